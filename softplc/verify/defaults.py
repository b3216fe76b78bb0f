"""`softplc verify`'s defaults, in one light module (no z3): the command line's options
read them without loading the solver, and the engines use the same values."""

DEPTH = 30  # scans BMC searches for a counterexample
MAX_K = 10  # the largest k k-induction tries
TIMEOUT_S = 60.0  # s per requirement, all of it (model and engines)
LOOP_BOUND = 32  # passes of a loop (backward jump) unrolled per scan
MARGIN_S = 2.0  # s past a requirement's time before its process is killed (verify.guard)
