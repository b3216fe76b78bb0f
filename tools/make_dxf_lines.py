"""A DXF drawing of N separate LINEs (0.7 mm each, on a 200 x 200 grid in the 240 mm work
area, $INSUNITS = mm): the large-file case of docs/reliability.md.

    .venv/bin/python tools/make_dxf_lines.py 200000 out/lines200000.dxf
    /usr/bin/time -f "%U s CPU, %M KB" .venv/bin/softplc cut out/lines200000.dxf --dry-run
"""

from __future__ import annotations

import argparse
from pathlib import Path

import ezdxf

GRID = 200  # lines a row, and rows
ORIGIN = 10.0  # mm from the homed corner
MM_UNITS = 4  # $INSUNITS code of millimetres


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("count", type=int, help="number of LINEs")
    ap.add_argument("out", type=Path, help="the DXF file to write")
    args = ap.parse_args()
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = MM_UNITS
    msp = doc.modelspace()
    for i in range(args.count):
        x, y = ORIGIN + i % GRID, ORIGIN + (i // GRID) % GRID
        msp.add_line((x, y), (x + 0.5, y + 0.5))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    doc.saveas(args.out)
    print(f"{args.out}: {args.count} LINEs")


if __name__ == "__main__":
    main()
