"""Progress lines: redrawn in place on a terminal; off a terminal (a pipe, a file, CI's log)
a plain line now and then, the first and the last always, and no carriage return."""

from __future__ import annotations

import io

from softplc.machines.drawing.host import ProgressBar
from softplc.modbus.host import ProgressLine


def test_off_a_terminal_a_line_every_few_seconds_and_the_last_one():
    now = [0.0]
    out = io.StringIO()  # not a terminal
    bar = ProgressBar(186, out, clock=lambda: now[0])
    for done in range(186):  # one update a segment, 0.1 s apart: 18.6 s in all
        now[0] = done * 0.1
        bar.update(done)
    bar.close()
    text = out.getvalue()
    assert "\r" not in text and "\x1b" not in text
    lines = text.splitlines()
    # the first, one every LINE_INTERVAL_S of the 18.5 s, and the last state at close()
    assert len(lines) == 1 + int(18.5 // ProgressLine.LINE_INTERVAL_S) + 1
    assert lines[0].startswith("[---") and "0/186" in lines[0]
    assert "185/186" in lines[-1]


def test_the_end_is_written_at_once_off_a_terminal():
    out = io.StringIO()
    line = ProgressLine(out, width=10, clock=lambda: 0.0)
    line.show(0.0, "start")
    line.show(0.5, "half")  # within the interval: held back
    line.show(1.0, "done")  # the end: written at once
    line.close()
    assert out.getvalue() == "[----------] start\n[##########] done\n"


def test_on_a_terminal_the_line_is_redrawn_in_place():
    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    out = Terminal()
    line = ProgressLine(out, width=4)
    line.show(0.5, "a")
    line.show(1.0, "b")
    line.close()
    assert out.getvalue() == "\r[##--] a\x1b[K\r[####] b\x1b[K\n"
