"""Generated IL programs for benchmarks (shared by tools/bench.py and the peer comparison)."""

from __future__ import annotations

import random


def boolean_program(n_instructions: int = 1000, seed: int = 1) -> str:
    """Rungs of `LD a AND( b OR c ) ST q` style logic: exactly n_instructions boolean
    instructions (LD, AND, ANDN, OR, ORN, ST; a closing ')' counts as an instruction too)."""
    rnd = random.Random(seed)
    lines: list[str] = []
    count = 0
    while count < n_instructions:
        a, b, c = (rnd.randrange(200) for _ in range(3))
        q = 200 + rnd.randrange(56)
        form = rnd.randrange(3)
        if form == 0 and count + 4 <= n_instructions:  # LD a AND b OR c ST q
            lines += [f"LD %M{a}", f"AND %M{b}", f"OR %M{c}", f"ST %M{q}"]
            count += 4
        elif form == 1 and count + 5 <= n_instructions:  # LD a AND( b OR c ) ST q
            lines += [f"LD %M{a}", f"AND( %M{b}", f"ORN %M{c}", ")", f"ST %M{q}"]
            count += 5
        elif count + 3 <= n_instructions:  # LD a ANDN b ST q
            lines += [f"LDN %M{a}", f"ANDN %M{b}", f"ST %M{q}"]
            count += 3
        else:
            lines += ["LD %M0", f"ST %M{q}"][: n_instructions - count]
            count = n_instructions
    return "\n".join(lines) + "\n"
