"""Issue 11 B: the real-time clock (%SW49-%SW53, %S50), the settable calendar start of
the virtual clock, schedule blocks, and the example ladder_programs/rtc_schedule.il.

Source: TWD USE 10AE system words %SW49 (day of the week, 1 = Monday), %SW50 seconds,
%SW51 HHMM, %SW52 MMDD, %SW53 CCYY, all BCD, %S50 (update the clock from %SW50-53),
%SW114 (schedule blocks enabled); schedule blocks configured in TwidoSuite [manual, from
memory: see docs/twido.md#real-time-clock].
"""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.errors import ConfigError

WORDS = "LD 1\n[ %MW0 := %SW49 ]\n[ %MW1 := %SW50 ]\n[ %MW2 := %SW51 ]\n" \
        "[ %MW3 := %SW52 ]\n[ %MW4 := %SW53 ]\n"
EXAMPLE = ("ladder_programs/rtc_schedule.il", "ladder_programs/rtc_schedule.toml")


def words(plc: PLC) -> tuple[int, ...]:
    return tuple(plc[f"%MW{k}"] & 0xFFFF for k in range(5))


def test_date_and_time_words_in_bcd_from_the_calendar_start():
    plc = PLC.from_source(WORDS, {"scan_period": "1s",
                                  "rtc": {"start": "2026-12-31T23:59:58"}})
    plc.scan()
    assert words(plc) == (4, 0x58, 0x2359, 0x1231, 0x2026)   # a Thursday
    plc.scan(2)
    assert words(plc) == (5, 0x00, 0x0000, 0x0101, 0x2027)   # new year, Friday


def test_virtual_clock_default_start_is_repeatable():
    plc = PLC.from_source(WORDS, {"scan_period": "1s"})
    plc.scan()
    assert words(plc) == (6, 0, 0, 0x0101, 0x2000)           # 2000-01-01 was a Saturday


def test_s50_sets_the_clock_from_the_words():
    src = WORDS + "LD %M0\nST %S50\n[ %SW50 := 16#0030 ]\n[ %SW51 := 16#1015 ]\n" \
                  "[ %SW52 := 16#0704 ]\n[ %SW53 := 16#2025 ]\n"
    plc = PLC.from_source(src, {"scan_period": "1s"})
    plc.scan()
    plc["%M0"] = 1
    plc.scan()
    plc["%M0"] = 0
    plc.scan(2)
    # set to 10:15:30 at the end of the scan at t = 1 s; the scan at t = 3 s reads :32
    assert words(plc) == (5, 0x32, 0x1015, 0x0704, 0x2025)   # 2025-07-04, a Friday


def test_the_clock_costs_nothing_when_unused():
    assert PLC.from_source("LD %I0.0\nST %Q0.0\n").engine.rtc is None
    assert PLC.from_source("LD 1\n[ %MW0 := %SW5 ]\n").engine.rtc is None
    assert PLC.from_source("LD 1\n[ %MW0 := %SW49 ]\n").engine.rtc is not None
    assert PLC.from_source("LD %S51\nST %Q0.0\n").engine.rtc is not None


def test_schedule_block_days_and_edges():
    cfg = {"scan_period": "60s", "rtc": {"start": "2026-01-02T07:00:00"},   # a Friday
           "schedule": {"0": {"output": "%Q0.0", "start": "07:30", "stop": "18:00",
                              "days": ["mon", "tue", "wed", "thu", "fri"]}}}
    plc = PLC.from_source("LD %M0\nR %Q0.0\n", cfg)
    plc.scan(30)
    assert not plc["%Q0.0"]
    plc.scan()                                    # 07:30
    assert plc["%Q0.0"]
    plc["%M0"] = 1
    plc.scan()
    plc["%M0"] = 0
    plc.scan(5)                                   # scans so far: 37, the last at 07:36
    assert not plc["%Q0.0"], "the program's reset stands until the block's next change"
    plc.scan(24 * 60)                             # Saturday 07:36: off
    assert not plc["%Q0.0"]
    plc.scan(4349 - 37 - 24 * 60 + 1)             # Monday 07:29 (minute 4349)
    assert not plc["%Q0.0"]
    plc.scan()                                    # 07:30
    assert plc["%Q0.0"]


def test_schedule_over_midnight_dates_and_enable_word():
    cfg = {"scan_period": "60s", "rtc": {"start": "2026-12-30T21:00:00"},
           "schedule": {"3": {"output": "%M7", "start": "22:00", "stop": "02:00",
                              "first": "12-31", "last": "01-01", "days": ["thu"]}}}
    plc = PLC.from_source("LD %M7\nST %Q0.0\n", cfg)
    plc.scan(25 * 60 + 1)                         # minute 1500: Thursday 2026-12-31 22:00
    assert plc["%M7"]
    plc.scan(3 * 60)                              # 01:00 Friday: still Thursday's night
    assert plc["%M7"]
    plc.scan(60)                                  # 02:00
    assert not plc["%M7"]
    plc = PLC.from_source("LD %M7\nST %Q0.0\n", cfg)
    plc.scan()
    plc["%SW114"] = 0xFFFF & ~(1 << 3)            # block 3 disabled
    plc.scan(25 * 60)
    assert not plc["%M7"]


@pytest.mark.parametrize("cfg, message", [
    ({"rtc": {"start": "yesterday"}}, "rtc.start"),
    ({"rtc": {"begin": "2026-01-01"}}, "rtc.begin: unknown key; known: start"),
    ({"schedule": {"0": {"output": "%Q0.0", "start": "25:00", "stop": "08:00"}}},
     "schedule.0.start"),
    ({"schedule": {"0": {"output": "%Q0.0", "start": "07:00", "stop": "08:00",
                         "days": ["monday"]}}}, "schedule.0.days"),
    ({"schedule": {"0": {"output": "%MW0", "start": "07:00", "stop": "08:00"}}},
     "schedule.0.output: '%MW0' is not a %Q/%M bit"),
    ({"schedule": {"16": {"output": "%Q0.0", "start": "07:00", "stop": "08:00"}}},
     "schedule blocks are 0 .. 15"),
    ({"schedule": {"0": {"output": "%Q0.0", "start": "07:00", "stop": "08:00",
                         "last": "02-30"}}}, "schedule.0.last"),
])
def test_config_errors(cfg, message):
    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD 1\nST %M0\n", cfg)
    assert message in str(e.value)


# ---- the example program ------------------------------------------------------------------

@pytest.mark.plc_program(EXAMPLE[0], config=EXAMPLE[1])
def test_example_lights_heating_and_time_stamp(plc):
    plc.run(1800)                                  # Friday 07:29:59
    assert not plc["%Q0.0"]
    plc.run(2)
    assert plc["%Q0.0"], "weekday lights from 07:30"
    plc["%I0.0"] = 1                               # the door opens at 07:30:02
    plc.scan()
    assert plc["%MW10"] == 0x0730 and plc["%MW11"] == 0x0102
    plc.run(24 * 3600)                             # Saturday 07:30
    assert not plc["%Q0.0"] and not plc["%Q0.1"]
    plc.run(2 * 3600)                              # Saturday 09:30
    assert plc["%Q0.1"], "Saturday-morning heating"
    plc.run(3 * 3600)
    assert not plc["%Q0.1"]


def test_example_sets_the_clock():
    plc = PLC.from_file(*EXAMPLE)
    plc["%MW20"], plc["%MW21"], plc["%MW22"], plc["%MW23"] = 0x00, 0x0930, 0x0103, 0x2026
    plc["%I0.1"] = plc["%I0.2"] = 1
    plc.scan()
    plc["%I0.1"] = 0
    plc.scan(2)
    assert plc["%Q0.1"], "Saturday 2026-01-03 09:30 after the setting"
