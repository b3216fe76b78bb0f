"""Retained state files: round trip, atomic save, and clear errors for damaged files."""

from __future__ import annotations

import pytest

from softplc.runtime import retain
from softplc.runtime.blocks import Counter, Timer, TimeSource
from softplc.runtime.memory import MemoryImage
from softplc.runtime.retain import StateFileError


def image_with_data() -> MemoryImage:
    mem = MemoryImage()
    clock = TimeSource()
    mem.blocks["TM"][0] = Timer(clock, "TON", "1ms", 500)
    mem.blocks["C"][3] = Counter()
    mem.mw.w[0] = -7
    mem.mw.set_f(40, 2.5)
    mem.mw.w[2999] = 1234
    mem.m[255] = 1
    mem.blocks["TM"][0].P = 321
    mem.blocks["C"][3].V = 42
    mem.blocks["C"][3].P = 99
    return mem


class FakePLC:
    def __init__(self, mem: MemoryImage):
        self.mem = mem
        self.started = ""

    def warm_start(self) -> None:
        self.started = "warm"

    def cold_start(self) -> None:
        self.started = "cold"


def test_round_trip(tmp_path):
    path = tmp_path / "plc.state"
    src = image_with_data()
    retain.save(path, retain.capture(src, "prog.il"))
    assert [p.name for p in tmp_path.iterdir()] == ["plc.state"]  # no temp file left
    dst = image_with_data()
    dst.mw.buf[:] = bytes(len(dst.mw.buf))
    dst.m[:] = bytes(len(dst.m))
    dst.blocks["TM"][0].P = 0
    dst.blocks["C"][3].V = 0
    plc = FakePLC(dst)
    assert retain.restart(plc, path) == "warm" and plc.started == "warm"
    assert dst.mw.w[0] == -7 and dst.mw.get_f(40) == 2.5 and dst.mw.w[2999] == 1234
    assert dst.m[255] == 1
    assert dst.blocks["TM"][0].P == 321
    assert (dst.blocks["C"][3].V, dst.blocks["C"][3].P) == (42, 99)


def test_running_timer_keeps_its_elapsed_time(tmp_path):
    """A timer's start time is saved relative to the clock, which restarts from 0."""
    mem = image_with_data()
    clock = mem.blocks["TM"][0].clock
    clock.now_us = 1_000_000
    mem.blocks["TM"][0].run(1)
    clock.now_us = 1_200_000  # 200 ms into a 321 ms TON
    mem.blocks["TM"][0].run(1)
    assert mem.blocks["TM"][0].V == 200
    retain.save(tmp_path / "s", retain.capture(mem))
    new = image_with_data()
    new.blocks["TM"][0].clock.now_us = 0
    retain.apply(new, retain.load(tmp_path / "s"))
    new.blocks["TM"][0].clock.now_us = 50_000
    new.blocks["TM"][0].run(1)
    assert new.blocks["TM"][0].V == 250 and new.blocks["TM"][0].Q == 0


def test_missing_file_is_a_cold_start(tmp_path):
    plc = FakePLC(MemoryImage())
    assert retain.restart(plc, tmp_path / "absent.state") == "cold" and plc.started == "cold"
    assert retain.restart(plc, None) == "cold"


def damaged_files(good: bytes) -> dict[str, bytes]:
    head, _, body = good.partition(b"\n")
    flipped = bytearray(good)
    flipped[len(head) + 20] ^= 0x01
    return {
        "empty": b"",
        "truncated": good[: len(good) // 2],
        "truncated header": good[:10],
        "one bit flipped": bytes(flipped),
        "padded": good + b"\0",
        "future version": good.replace(b"SOFTPLC-STATE 1 ", b"SOFTPLC-STATE 9 ", 1),
        "not a state file": b"hello world\n{}",
        "bad length": head.replace(head.split()[2], b"x") + b"\n" + body,
    }


@pytest.mark.parametrize("case", ["empty", "truncated", "truncated header", "one bit flipped",
                                  "padded", "future version", "not a state file",
                                  "bad length"])
def test_damaged_file_is_an_error_unless_cold(tmp_path, case):
    path = tmp_path / "plc.state"
    retain.save(path, retain.capture(image_with_data()))
    path.write_bytes(damaged_files(path.read_bytes())[case])
    mem = MemoryImage()
    plc = FakePLC(mem)
    with pytest.raises(StateFileError, match="--cold"):
        retain.restart(plc, path)
    assert plc.started == "" and mem.mw.w[0] == 0  # nothing touched
    assert retain.restart(plc, path, cold=True) == "cold" and plc.started == "cold"


def test_other_controller_is_an_error(tmp_path):
    path = tmp_path / "plc.state"
    state = retain.capture(image_with_data())
    state.mw = state.mw[:100]
    retain.save(path, state)
    with pytest.raises(StateFileError, match="50 %MW"):
        retain.restart(FakePLC(MemoryImage()), path)


def test_checksummed_json_with_valid_sum_but_bad_content(tmp_path):
    import hashlib
    body = b'{"format": 1}'
    data = f"SOFTPLC-STATE 1 {len(body)} {hashlib.sha256(body).hexdigest()}\n".encode() + body
    with pytest.raises(StateFileError, match="unreadable content"):
        retain.decode(data)


def test_writer_thread_saves_latest_and_reports_errors(tmp_path):
    path = tmp_path / "w.state"
    mem = image_with_data()
    w = retain.RetainWriter(path)
    for k in range(5):
        mem.mw.w[7] = k
        w.submit(retain.capture(mem))
    mem.mw.w[7] = 99
    w.close(retain.capture(mem))
    assert retain.load(path).mw == bytes(mem.mw.buf)
    bad = retain.RetainWriter(tmp_path / "no" / "such" / "dir" / "s")
    with pytest.raises(StateFileError, match="cannot save"):
        bad.close(retain.capture(mem))
