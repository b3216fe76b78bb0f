"""Boolean accumulator instructions of Twido IL: loads, logic, stores, edges,
parentheses, the MPS/MRD/MPP stack, constants, comparisons, rung segmentation.

Semantics from docs/twido.md; tags [sure]/[m221]/[manual] as there.
"""

from __future__ import annotations

import itertools

import pytest

from softplc import PLC
from softplc.il.parser import parse


def run(plc: PLC, **bits: int) -> PLC:
    """Set %M bits (M0=1 -> %M0) and scan once."""
    for name, v in bits.items():
        plc["%" + name] = v
    plc.scan()
    return plc


BITS3 = list(itertools.product((0, 1), repeat=3))


# ---- loads and logic [sure] -----------------------------------------------------------------
def test_ld_ldn_st_stn(plc_from_source):
    plc = plc_from_source("""
LD    %M0
ST    %Q0.0
LDN   %M0
ST    %Q0.1
LD    %M0
STN   %Q0.2
""")
    for v in (0, 1, 0):
        run(plc, M0=v)
        assert plc["%Q0.0"] == bool(v)
        assert plc["%Q0.1"] == (not v)
        assert plc["%Q0.2"] == (not v)


@pytest.mark.parametrize("a,b,c", BITS3)
def test_and_or_xor_truth_tables(plc_from_source, a, b, c):
    plc = plc_from_source("""
LD   %M0
AND  %M1
ST   %M10
LD   %M0
ANDN %M1
ST   %M11
LD   %M0
OR   %M1
ST   %M12
LD   %M0
ORN  %M1
ST   %M13
LD   %M0
XOR  %M1
ST   %M14
LD   %M0
XORN %M1
ST   %M15
LD   %M0
AND  %M1
OR   %M2
ST   %M16
LD   %M0
OR   %M1
AND  %M2
ST   %M17
""")
    run(plc, M0=a, M1=b, M2=c)
    assert plc["%M10"] == bool(a and b)
    assert plc["%M11"] == bool(a and not b)
    assert plc["%M12"] == bool(a or b)
    assert plc["%M13"] == bool(a or not b)
    assert plc["%M14"] == bool(a != b)
    assert plc["%M15"] == bool(a == b)
    # IL evaluates left to right: ((a AND b) OR c), ((a OR b) AND c)
    assert plc["%M16"] == bool((a and b) or c)
    assert plc["%M17"] == bool((a or b) and c)


@pytest.mark.parametrize("a,b,c", BITS3)
def test_xor_after_compound_accumulator(plc_from_source, a, b, c):
    """The accumulator is one bit: XOR acts on (a AND b), not on b alone."""
    plc = plc_from_source("""
LD   %M0
AND  %M1
XOR  %M2
ST   %M10
LD   %M0
OR   %M1
XOR  %M2
ST   %M11
LD   %M0
AND  %M1
XORN %M2
ST   %M12
""")
    run(plc, M0=a, M1=b, M2=c)
    assert plc["%M10"] == bool((a and b) != c)
    assert plc["%M11"] == bool((a or b) != c)
    assert plc["%M12"] == bool((a and b) == c)


@pytest.mark.parametrize("a,b", list(itertools.product((0, 1), repeat=2)))
def test_n_and_stn_negate_the_whole_accumulator(plc_from_source, a, b):
    plc = plc_from_source("""
LD   %M0
AND  %M1
N
ST   %M10
LD   %M0
AND  %M1
STN  %M11
LD   %M0
OR   %M1
N
ST   %M12
LD   %M0
OR   %M1
STN  %M13
""")
    run(plc, M0=a, M1=b)
    assert plc["%M10"] == (not (a and b))
    assert plc["%M11"] == (not (a and b))
    assert plc["%M12"] == (not (a or b))
    assert plc["%M13"] == (not (a or b))


def test_set_and_reset_are_latching(plc_from_source):
    plc = plc_from_source("""
LD   %M0
S    %Q0.0
LD   %M1
R    %Q0.0
""")
    run(plc, M0=1)
    assert plc["%Q0.0"]
    run(plc, M0=0)
    assert plc["%Q0.0"]  # stays set
    run(plc, M1=1)
    assert not plc["%Q0.0"]
    run(plc, M1=0)
    assert not plc["%Q0.0"]
    run(plc, M0=1, M1=1)  # the later rung wins
    assert not plc["%Q0.0"]


def test_constant_operands(plc_from_source):
    plc = plc_from_source("""
LD 1
ST %M0
LD 0
ST %M1
LDN 0
ST %M2
LD %M5
OR 1
ST %M3
LD 1
AND 0
ST %M4
""")
    plc.scan()
    assert plc["%M0"] and not plc["%M1"] and plc["%M2"] and plc["%M3"] and not plc["%M4"]


def test_multiple_outputs_and_conditions_after_a_store(plc_from_source):
    """A rung may store, then add conditions and store again (ladder branches)."""
    plc = plc_from_source("""
LD   %M0
ST   %Q0.0
ST   %Q0.1
AND  %M1
ST   %Q0.2
""")
    run(plc, M0=1, M1=0)
    assert plc["%Q0.0"] and plc["%Q0.1"] and not plc["%Q0.2"]
    run(plc, M0=1, M1=1)
    assert plc["%Q0.2"]
    run(plc, M0=0, M1=1)
    assert not plc["%Q0.0"] and not plc["%Q0.2"]


def test_word_bits_as_operands_and_targets(plc_from_source):
    """%MWi:Xk is readable and writable [sure]."""
    plc = plc_from_source("""
LD   %MW0:X3
ST   %M0
LD   %M1
ST   %MW1:X15
LDN  %MW0:X0
ST   %MW1:X0
""")
    plc["%MW0"] = 0b1000
    plc["%M1"] = 1
    plc.scan()
    assert plc["%M0"]
    assert plc["%MW1"] == -32768 + 1  # bit 15 and bit 0 set
    plc["%M1"] = 0
    plc["%MW0"] = 1
    plc.scan()
    assert not plc["%M0"]
    assert plc["%MW1"] == 0


def test_inputs_and_system_bits_as_operands(plc_from_source):
    plc = plc_from_source("""
LD   %I0.5
ANDN %I0.23
ST   %Q0.15
LD   %S13
ST   %M0
""")
    plc["%I0.5"] = 1
    plc.scan()
    assert plc["%Q0.15"] and plc["%M0"]
    plc["%I0.23"] = 1
    plc.scan()
    assert not plc["%Q0.15"] and not plc["%M0"]


# ---- edges [sure] ---------------------------------------------------------------------------
def test_rising_and_falling_edges_last_one_scan(plc_from_source):
    plc = plc_from_source("""
LDR  %M0
ST   %M10
LDF  %M0
ST   %M11
LD   1
ANDR %M0
ST   %M12
LD   1
ANDF %M0
ST   %M13
LD   0
ORR  %M0
ST   %M14
LD   0
ORF  %M0
ST   %M15
LD   0
XORR %M0
ST   %M16
LD   0
XORF %M0
ST   %M17
""")
    rising = ["%M10", "%M12", "%M14", "%M16"]
    falling = ["%M11", "%M13", "%M15", "%M17"]
    run(plc, M0=0)
    assert not any(plc[a] for a in rising + falling)
    run(plc, M0=1)
    assert all(plc[a] for a in rising) and not any(plc[a] for a in falling)
    run(plc, M0=1)
    assert not any(plc[a] for a in rising + falling)
    run(plc, M0=0)
    assert all(plc[a] for a in falling) and not any(plc[a] for a in rising)
    run(plc, M0=0)
    assert not any(plc[a] for a in rising + falling)


def test_rising_edge_counts_each_transition_once(plc_from_source):
    plc = plc_from_source("""
LDR  %I0.0
[ INC %MW0 ]
""")
    pattern = [0, 1, 1, 1, 0, 1, 0, 0, 1, 1, 0]
    for v in pattern:
        plc["%I0.0"] = v
        plc.scan()
    assert plc["%MW0"] == 3


def test_each_edge_instruction_has_its_own_memory(plc_from_source):
    plc = plc_from_source("""
LDR  %M0
ST   %M10
LDR  %M0
ST   %M11
""")
    run(plc, M0=1)
    assert plc["%M10"] and plc["%M11"]


# ---- parentheses [sure; nesting depth manual] -----------------------------------------------
@pytest.mark.parametrize("a,b,c", BITS3)
def test_parentheses(plc_from_source, a, b, c):
    plc = plc_from_source("""
LD   %M0
AND( %M1
OR   %M2
)
ST   %M10
LD   %M0
OR(  %M1
AND  %M2
)
ST   %M11
LD   %M0
XOR( %M1
AND  %M2
)
ST   %M12
LD   %M0
AND(N %M1
OR   %M2
)
ST   %M13
LD   %M0
AND( [ %MW0 > 5 ]
OR   %M2
)
ST   %M14
""")
    plc["%MW0"] = 10 if b else 0
    run(plc, M0=a, M1=b, M2=c)
    assert plc["%M10"] == bool(a and (b or c))
    assert plc["%M11"] == bool(a or (b and c))
    assert plc["%M12"] == bool(a != (b and c))
    # AND(N: the modifier applies to the first operand inside the parenthesis [manual]
    assert plc["%M13"] == bool(a and ((not b) or c))
    assert plc["%M14"] == bool(a and (b or c))


def test_parenthesis_with_edge_modifier(plc_from_source):
    plc = plc_from_source("""
LD    1
AND(R %M0
OR    %M1
)
ST    %M10
""")
    run(plc, M0=1)
    assert plc["%M10"]
    run(plc, M0=1)
    assert not plc["%M10"]
    run(plc, M0=1, M1=1)
    assert plc["%M10"]


def test_nested_parentheses_eight_deep(plc_from_source):
    # a AND (b OR (c AND (d OR ...))) nested 8 levels [manual: 8 levels]
    lines = ["LD %M0"]
    for k in range(1, 9):
        lines.append(("AND( " if k % 2 else "OR( ") + f"%M{k}")
    lines += [")"] * 8 + ["ST %M20"]
    plc = plc_from_source("\n".join(lines) + "\n")

    def model(v):
        # close the levels from the innermost: level k combines %M(k-1) with level k+1
        inner = v[8]
        for k in range(8, 0, -1):
            inner = (v[k - 1] and inner) if k % 2 else (v[k - 1] or inner)
        return bool(inner)

    for bits in ([1] * 9, [1, 0] * 4 + [1], [1, 1, 0, 0, 1, 1, 0, 0, 1], [0] + [1] * 8,
                 [1, 0, 0, 0, 0, 0, 0, 0, 1], [1, 0, 1, 0, 1, 0, 1, 0, 0]):
        for k, v in enumerate(bits):
            plc[f"%M{k}"] = v
        plc.scan()
        assert plc["%M20"] == model(bits), bits


# ---- MPS / MRD / MPP [m221] -----------------------------------------------------------------
@pytest.mark.parametrize("a,b,c", BITS3)
def test_stack_instructions(plc_from_source, a, b, c):
    plc = plc_from_source("""
LD   %M0
MPS
AND  %M1
ST   %Q0.0
MRD
AND  %M2
ST   %Q0.1
MPP
ANDN %M1
ST   %Q0.2
""")
    run(plc, M0=a, M1=b, M2=c)
    assert plc["%Q0.0"] == bool(a and b)
    assert plc["%Q0.1"] == bool(a and c)
    assert plc["%Q0.2"] == bool(a and not b)


def test_nested_stack(plc_from_source):
    plc = plc_from_source("""
LD   %M0
MPS
AND  %M1
MPS
AND  %M2
ST   %M10
MPP
ST   %M11
MPP
ST   %M12
""")
    run(plc, M0=1, M1=1, M2=0)
    assert not plc["%M10"] and plc["%M11"] and plc["%M12"]
    run(plc, M0=1, M1=0, M2=1)
    assert not plc["%M10"] and not plc["%M11"] and plc["%M12"]


# ---- comparisons as operands [sure] ---------------------------------------------------------
@pytest.mark.parametrize("op,expected", [(">", [0, 0, 1]), (">=", [0, 1, 1]),
                                         ("<", [1, 0, 0]), ("<=", [1, 1, 0]),
                                         ("=", [0, 1, 0]), ("<>", [1, 0, 1])])
def test_comparison_operators(plc_from_source, op, expected):
    plc = plc_from_source(f"LD [ %MW0 {op} 100 ]\nST %M0\nLD 1\nAND [ %MF2 {op} 1.5 ]\n"
                          f"ST %M1\n")
    for w, f, exp in zip((99, 100, 101), (1.25, 1.5, 1.75), expected, strict=True):
        plc["%MW0"] = w
        plc["%MF2"] = f
        plc.scan()
        assert plc["%M0"] == bool(exp), (w, op)
        assert plc["%M1"] == bool(exp), (f, op)


def test_comparison_of_expressions_and_negative_values(plc_from_source):
    plc = plc_from_source("""
LD  [ %MW0 + %MW1 > -5 ]
ST  %M0
LDN [ %MD10 = 100000 ]
ST  %M1
""")
    plc["%MW0"], plc["%MW1"] = -3, -1
    plc["%MD10"] = 100000
    plc.scan()
    assert plc["%M0"] and not plc["%M1"]
    plc["%MW1"] = -3
    plc["%MD10"] = 99999
    plc.scan()
    assert not plc["%M0"] and plc["%M1"]


# ---- syntax details [sure] ------------------------------------------------------------------
def test_case_insensitive_comments_and_blank_lines(plc_from_source):
    plc = plc_from_source("""
(* a comment on its own line *)

ld    %m0          (* load *)
andn  %m1
st    %q0.0

Ld %M0 (* mixed case *)
St %Q0.1
""")
    run(plc, M0=1)
    assert plc["%Q0.0"] and plc["%Q0.1"]


def test_operation_block_leaves_accumulator_unchanged(plc_from_source):
    plc = plc_from_source("""
LD   %M0
[ %MW0 := 7 ]
ST   %Q0.0
""")
    run(plc, M0=0)
    assert plc["%MW0"] == 0 and not plc["%Q0.0"]
    run(plc, M0=1)
    assert plc["%MW0"] == 7 and plc["%Q0.0"]


def test_rungs_are_derived_from_loads_after_outputs():
    prog = parse("""
LD   %M0
AND  %M1
ST   %Q0.0
ST   %Q0.1
LD   %M2
OR(  %M3
AND  %M4
)
ST   %Q0.2
LD   1
[ %MW0 := 1 ]
LD   %M5
ST   %Q0.3
""")
    assert [len(r.instructions) for r in prog.rungs] == [4, 5, 2, 2]


def test_expansion_module_outputs(plc_from_source):
    plc = plc_from_source("LD %M0\nST %Q1.7\n", {"modules": {"1": "TM2DDO8TT"}})
    run(plc, M0=1)
    assert plc["%Q1.7"]


@pytest.mark.parametrize("a,b,c", BITS3)
def test_negated_operands_anded_are_one_negation(plc_from_source, a, b, c):
    """`LDN a ANDN b ANDN c` (and negations by N or inside parentheses) are compiled as
    `not (a or b or c)` (De Morgan): the same truth table as the instruction list says."""
    plc = plc_from_source("""
LDN  %M0
ANDN %M1
ANDN %M2
ST   %M10
LD   %M0
OR   %M1
N
ANDN %M2
ST   %M11
LDN  %M0
AND( %M1
N
)
ANDN %M2
ST   %M12
LDN  %M0
ANDN %M1
AND  %M2
ST   %M13
""")
    run(plc, M0=a, M1=b, M2=c)
    assert plc["%M10"] == ((not a) and (not b) and (not c))
    assert plc["%M11"] == ((not (a or b)) and (not c))
    assert plc["%M12"] == ((not a) and (not b) and (not c))
    assert plc["%M13"] == ((not a) and (not b) and bool(c))
    assert "(not (_M[0] or _M[1] or _M[2]))" in plc.program.source
