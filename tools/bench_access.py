"""The host access port's costs in the scan thread (softplc/access): what a web page's
read and a burst of queued changes take at the scan boundary.

    .venv/bin/python tools/bench_access.py [--objects 200] [--number 20000]

Reported: the typed reader of N/2 bits and N/2 words (the websocket pages' read, 10 times
a second per page), in us per read and ns per object; one `MemoryImage.read` per object
for comparison (what the reader avoids); the command queue's apply of MAX_PENDING writes
(one boundary, us per command); the status record (us).
"""

from __future__ import annotations

import argparse
import timeit
from typing import Any

from softplc.access import AccessPort
from softplc.access.commands import MAX_PENDING
from softplc.plc import PLC
from softplc.twido.address import parse_address

PROGRAM = "LD [%MW0 > 3]\nST %M5\nLD %I0.0\nST %Q0.0\n"


def run(objects: int = 200, number: int = 20000) -> dict[str, float]:
    plc = PLC.from_source(PROGRAM)
    port = AccessPort(plc, hooks=False)
    half = objects // 2
    refs = [parse_address(f"%M{i}") for i in range(half)] \
        + [parse_address(f"%MW{i}") for i in range(objects - half)]
    reader = port.reading.reader(refs)
    t_reader = min(timeit.repeat(reader, number=number, repeat=5)) / number
    slow = [port.reading.read_one] * len(refs)

    def one_by_one() -> list[Any]:
        return [f(r) for f, r in zip(slow, refs, strict=True)]

    n_slow = max(1, number // 20)
    t_slow = min(timeit.repeat(one_by_one, number=n_slow, repeat=3)) / n_slow
    t_apply = []
    for _ in range(5):
        for k in range(MAX_PENDING):
            port.write_many([("%MW10", k)])
        t_apply.append(timeit.timeit(port.apply_now, number=1))
    t_status = min(timeit.repeat(port.status, number=number // 10, repeat=3)) / (number // 10)
    return {"objects": objects, "reader_us": t_reader * 1e6,
            "reader_ns_per_object": t_reader * 1e9 / objects,
            "read_one_ns_per_object": t_slow * 1e9 / objects,
            "apply_us_per_command": min(t_apply) * 1e6 / MAX_PENDING,
            "status_us": t_status * 1e6}


def report(res: dict[str, float]) -> str:
    return "\n".join([
        f"typed reader, {res['objects']:.0f} objects (half bits, half words): "
        f"{res['reader_us']:.2f} us per read, {res['reader_ns_per_object']:.0f} ns/object",
        f"one MemoryImage.read per object: {res['read_one_ns_per_object']:.0f} ns/object",
        f"command queue, {MAX_PENDING} writes at one boundary: "
        f"{res['apply_us_per_command']:.2f} us per command",
        f"status record: {res['status_us']:.2f} us"])


def main() -> None:
    ap = argparse.ArgumentParser(description="Costs of the host access port in the scan "
                                             "thread (typed reads, queued commands).")
    ap.add_argument("--objects", type=int, default=200, help="objects read at once (200)")
    ap.add_argument("--number", type=int, default=20000, help="reads timed (20000)")
    a = ap.parse_args()
    print(report(run(a.objects, a.number)))


if __name__ == "__main__":
    main()
