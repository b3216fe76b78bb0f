"""The real-time clock: %SW49-%SW53 date and time, %S50 setting it from the program, and
the schedule blocks.

[manual, from memory of TWD USE 10AE, system words; not found in the search corpora]
  %SW49  day of the week, 1 = Monday .. 7 = Sunday
  %SW50  seconds (BCD, 16#00SS)
  %SW51  hour and minute (BCD, 16#HHMM)
  %SW52  month and day (BCD, 16#MMDD)
  %SW53  century and year (BCD, 16#CCYY)
  %S50   0: the words show the clock; 1: the program writes them, and the clock takes
         their value (we take it at the end of every scan while %S50 = 1)
  %S51   1: the clock is not set (we keep it at 0: the virtual clock always is)
Schedule blocks (TwidoSuite "Schedule blocks", up to 16): between a start and a stop time
of day, on the chosen days of the week and within a range of dates, an output bit is 1;
%SW114 bit i = 1 enables block i (all enabled at a cold start). We write the bit when the
block's state changes (entering or leaving its window, our choice), so the program may
also write it in between; blocks are evaluated once a second.

The calendar runs from a settable start (`[rtc] start`) plus the PLC clock's time, so a
program on the virtual clock sees a repeatable date.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import date, datetime, timedelta
from typing import Any

from softplc.twido.address import Ref
from softplc.twido.numeric import bcd_decode, bcd_encode

SW_DOW, SW_SEC, SW_HHMM, SW_MMDD, SW_CCYY = 49, 50, 51, 52, 53
S_RTC_WRITE, S_RTC_UNSET = 50, 51
SW_SCHEDULE_ENABLE = 114
SCHEDULE_BLOCKS = 16
DAYS = ("mon", "tue", "wed", "thu", "fri", "sat", "sun")
DEFAULT_START = datetime(2000, 1, 1)  # the virtual clock's calendar when none is given
_BCD_SECONDS = tuple(bcd_encode(s) for s in range(60))  # %SW50 is rewritten every second


@dataclass
class Schedule:
    """One schedule block: `output` is 1 from `start` to `stop` (minutes of the day; stop
    before start spans midnight) on `days` (0 = Monday), between the dates `first` and
    `last` ((month, day); last before first spans the new year)."""

    number: int
    output: Ref
    start: int
    stop: int
    days: frozenset[int]
    first: tuple[int, int] = (1, 1)
    last: tuple[int, int] = (12, 31)
    state: int = -1  # -1: not evaluated yet

    def active(self, t: datetime) -> bool:
        md = (t.month, t.day)
        in_dates = (self.first <= md <= self.last) if self.first <= self.last else \
            (md >= self.first or md <= self.last)
        minute = t.hour * 60 + t.minute
        if self.start <= self.stop:
            in_time, day = self.start <= minute < self.stop, t.weekday()
        else:  # over midnight: the part after midnight belongs to the day it started
            in_time = minute >= self.start or minute < self.stop
            day = t.weekday() if minute >= self.start else (t.weekday() - 1) % 7
        return in_dates and in_time and day in self.days


class RTC:
    """Date and time words, updated once a second from `start` + the PLC clock's time."""

    def __init__(self, mem: Any, start: datetime, schedules: list[Schedule]):
        self.mem = mem
        self.start = start
        self.offset = 0  # seconds added by %S50 settings
        self.schedules = schedules
        self._sec: int | None = None
        self._minute: int | None = None  # the minute the cached calendar below is of
        self._words: tuple[int, int, int, int] = (0, 0, 0, 0)  # DOW, HHMM, MMDD, CCYY
        self._active: list[bool] = []  # each schedule's window, for that minute
        self.cold_start()

    def cold_start(self) -> None:
        self.mem.sw.uw[SW_SCHEDULE_ENABLE] = 0xFFFF
        for sch in self.schedules:
            sch.state = -1
        self._sec = self._minute = None

    def now(self, now_us: int) -> datetime:
        return self.start + timedelta(seconds=now_us // 1_000_000 + self.offset)

    def tick(self, now_us: int) -> None:
        """Start of a scan: refresh the words when the second changed. The calendar (a
        datetime, the BCD words but the seconds, the schedules' windows) only changes with
        the minute: it is recomputed then, and the words rewritten from it every second."""
        sec = now_us // 1_000_000
        if sec == self._sec:
            return
        self._sec = sec
        minute, second = divmod(self.start.second + sec + self.offset, 60)
        if minute != self._minute:
            self._minute = minute
            t = self.now(now_us)
            self._words = (t.isoweekday(), bcd_encode(t.hour * 100 + t.minute),
                           bcd_encode(t.month * 100 + t.day), bcd_encode(t.year))
            self._active = [sch.active(t) for sch in self.schedules]
        s, sw = self.mem.s, self.mem.sw.w
        s[S_RTC_UNSET] = False
        if not s[S_RTC_WRITE]:
            sw[SW_DOW], sw[SW_HHMM], sw[SW_MMDD], sw[SW_CCYY] = self._words
            sw[SW_SEC] = _BCD_SECONDS[second]
        if self.schedules:
            enable = self.mem.sw.uw[SW_SCHEDULE_ENABLE]
            for sch, active in zip(self.schedules, self._active, strict=True):
                if not enable >> sch.number & 1:
                    continue
                on = 1 if active else 0
                if on != sch.state:
                    sch.state = on
                    self.mem.write(sch.output, on, field_inputs=False)

    def end_of_scan(self, now_us: int) -> None:
        """%S50 = 1: the clock takes the date and time the program wrote [manual]."""
        if not self.mem.s[S_RTC_WRITE]:
            return
        sw = self.mem.sw.w
        parts = [bcd_decode(sw[k]) for k in (SW_SEC, SW_HHMM, SW_MMDD, SW_CCYY)]
        if None in parts:
            return  # not BCD: ignored (the real controller's reaction is unknown)
        sec, hhmm, mmdd, year = parts
        try:
            wanted = datetime(year, mmdd // 100, mmdd % 100, hhmm // 100, hhmm % 100, sec)
        except ValueError:
            return
        base = self.start + timedelta(seconds=now_us // 1_000_000)
        self.offset = int((wanted - base).total_seconds())
        self._sec = self._minute = None
        sw[SW_DOW] = wanted.isoweekday()


def parse_time_of_day(text: str) -> int:
    """'08:30' -> minutes of the day."""
    h, m = text.split(":")
    v = int(h) * 60 + int(m)
    if not 0 <= int(h) <= 24 or not 0 <= int(m) < 60 or v > 24 * 60:
        raise ValueError(f"time of day {text!r}")
    return v


def parse_month_day(text: str) -> tuple[int, int]:
    """'12-24' -> (12, 24)."""
    m, d = (int(x) for x in text.split("-"))
    date(2000, m, d)  # raises ValueError on a bad date (2000 is a leap year)
    return m, d
