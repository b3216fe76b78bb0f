"""The program kept beside a state file (softplc.persist.kept): round trip, the two
records a swap cut off between its writes needs, and a damaged or hostile file."""

from __future__ import annotations

import logging
from datetime import date, datetime

from softplc.persist.kept import KeptProgram, ProgramKeeper, path_of

A, B, C = b"\x01" * 32, b"\x02" * 32, b"\x03" * 32


def record(app: bytes, origin: bytes = A, source: str = "LD 1\nEND\n") -> KeptProgram:
    return KeptProgram(app, origin, "new.il", source,
                       {"rtc": {"start": datetime(2026, 1, 2, 3, 4, 5)}, "d": date(2026, 1, 1),
                        "timers": {"%TM0": {"preset": 5}}},
                       {"s.csv": b"%MW0,X,\xe9\n"}, 3, 1234.5)


def test_a_record_reads_back_as_written(tmp_path):
    state = tmp_path / "S"
    keeper = ProgramKeeper(state)
    assert keeper.records == [] and keeper.find(A) is None
    keeper.keep(record(B))
    again = ProgramKeeper(state)
    assert again.find(B) == record(B)
    assert path_of(state).stat().st_mode & 0o777 == 0o600


def test_the_running_record_stays_until_the_swap_is_made(tmp_path):
    """Written before the swap: the state file names the old application until the scan
    thread makes it, and a kill in between must still find the old program."""
    keeper = ProgramKeeper(tmp_path / "S")
    keeper.keep(record(A))
    keeper.running = record(A)
    keeper.keep(record(B))
    again = ProgramKeeper(tmp_path / "S")
    assert again.find(A) == record(A) and again.find(B) == record(B)
    keeper.running = record(B)
    keeper.keep(record(C))  # at most two: the one to run and the one running
    assert [r.app for r in ProgramKeeper(tmp_path / "S").records] == [C, B]


def test_a_damaged_or_linked_file_keeps_nothing_and_says_so(tmp_path, caplog):
    state = tmp_path / "S"
    with caplog.at_level(logging.WARNING, "softplc.retain"):
        path_of(state).write_bytes(b"\x00garbage")
        assert ProgramKeeper(state).records == []
        path_of(state).unlink()
        path_of(state).symlink_to("/dev/zero")
        assert ProgramKeeper(state).records == []
    assert "unreadable" in caplog.text and "symbolic link" in caplog.text
