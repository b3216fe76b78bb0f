"""Write ladder_programs/pieces/plate.dxf, the DXF sample of `softplc cut` (docs/machines/
cutting-table.md): E3's rounded rectangle as one closed LWPOLYLINE with bulges, a round hole
(CIRCLE R 6) and a slot of two LINEs and two ARCs, in mm, made with ezdxf.

    python tools/make_plate_dxf.py [OUT.dxf]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import ezdxf

ROOT = Path(__file__).resolve().parent.parent


def make(out: Path) -> Path:
    doc = ezdxf.new("R2000")  # the oldest version with LWPOLYLINE
    doc.header["$INSUNITS"] = 4  # mm
    msp = doc.modelspace()
    b = math.tan(math.pi / 8)  # bulge of a 90 degree corner: tan(θ/4)
    msp.add_lwpolyline([(20, 10, 0), (40, 10, b), (50, 20, 0), (50, 40, b), (40, 50, 0),
                        (20, 50, b), (10, 40, 0), (10, 20, b)], format="xyb", close=True)
    msp.add_circle((30, 30), 6)
    msp.add_line((60, 20), (80, 20))
    msp.add_arc((80, 25), 5, -90, 90)
    msp.add_line((80, 30), (60, 30))
    msp.add_arc((60, 25), 5, 90, 270)
    doc.saveas(out)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", nargs="?", type=Path,
                    default=ROOT / "ladder_programs" / "pieces" / "plate.dxf",
                    help="output file (default: %(default)s)")
    print(f"wrote {make(ap.parse_args().out)}")


if __name__ == "__main__":
    main()
