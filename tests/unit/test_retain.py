"""Retained state files: round trip, journal, kill-safety, and clear errors for damage."""

from __future__ import annotations

import shutil
import struct

import pytest

from softplc.blocks.counter import Counter
from softplc.blocks.timer import Timer
from softplc.modbus.image import ModbusImage
from softplc.persist import retain
from softplc.persist.retain import StateFileError, StateStore
from softplc.runtime.blocks import TimeSource
from softplc.runtime.memory import MemoryImage


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


APP = b"\x01" * 32


def started_store(path, mem: MemoryImage) -> StateStore:
    """A store on `path`, laid out for `mem` and holding it."""
    store = StateStore.open(path)
    store.start(retain.capture(mem))
    return store


def commit(store: StateStore, mem: MemoryImage) -> None:
    store.commit(retain.words_to_be(mem.mw.buf), bytes(mem.m))


def test_round_trip(tmp_path):
    path = tmp_path / "plc.state"
    src = image_with_data()
    retain.save(path, retain.capture(src, APP))
    assert [p.name for p in tmp_path.iterdir()] == ["plc.state"]  # no temp file left
    dst = image_with_data()
    dst.mw.buf[:] = bytes(len(dst.mw.buf))
    dst.m[:] = [0] * len(dst.m)
    dst.blocks["TM"][0].P = 0
    dst.blocks["C"][3].V = 0
    plc = FakePLC(dst)
    assert retain.restart(plc, retain.load(path), app=APP)[0] == "warm"
    assert plc.started == "warm"
    assert dst.mw.w[0] == -7 and dst.mw.get_f(40) == 2.5 and dst.mw.w[2999] == 1234
    assert dst.m[255] == 1
    assert dst.blocks["TM"][0].P == 321
    assert (dst.blocks["C"][3].V, dst.blocks["C"][3].P) == (42, 99)


def image_with_running_timer() -> MemoryImage:
    """%TM0 200 ms into its 321 ms TON, on a clock well past 0."""
    mem = image_with_data()
    clock = mem.blocks["TM"][0].clock
    clock.now_us = 1_000_000
    mem.blocks["TM"][0].run(1)
    clock.now_us = 1_200_000
    mem.blocks["TM"][0].run(1)
    assert mem.blocks["TM"][0].V == 200
    return mem


def assert_timer_goes_on_from_200ms(path) -> None:
    """Restored under another clock (at 3 s), %TM0 counts on from its 200 ms."""
    new = image_with_data()
    new.blocks["TM"][0].clock.now_us = 3_000_000
    retain.apply(new, retain.load(path))
    new.blocks["TM"][0].clock.now_us = 3_050_000
    new.blocks["TM"][0].run(1)
    assert new.blocks["TM"][0].V == 250 and new.blocks["TM"][0].Q == 0


def test_running_timer_keeps_its_elapsed_time(tmp_path):
    """A timer's start time is saved relative to the clock, which restarts from 0."""
    retain.save(tmp_path / "s", retain.capture(image_with_running_timer()))
    assert_timer_goes_on_from_200ms(tmp_path / "s")


def test_file_of_the_old_timer_format_still_restores(tmp_path):
    """Files saved before timers kept `_elapsed_us` hold `_t0` relative to the clock at
    saving (minus the elapsed time): a running timer goes on from where it was."""
    state = retain.capture(image_with_running_timer())
    old = dict(state.blocks["TM"][0])
    old["_t0"] = -old.pop("_elapsed_us")  # as the old writer stored it
    state.blocks["TM"][0] = old
    retain.save(tmp_path / "s", state)
    assert b'"_t0":-200000' in (tmp_path / "s").read_bytes()
    assert_timer_goes_on_from_200ms(tmp_path / "s")


def test_missing_or_empty_file_is_a_cold_start(tmp_path):
    plc = FakePLC(MemoryImage())
    assert retain.load(tmp_path / "absent.state") is None
    assert retain.restart(plc, None) == ("cold", "no retained state yet")
    (tmp_path / "empty.state").write_bytes(b"")  # a creation that never finished
    assert retain.load(tmp_path / "empty.state") is None


def test_changed_application_is_a_cold_start_unless_keep_state(tmp_path):
    path = tmp_path / "plc.state"
    retain.save(path, retain.capture(image_with_data(), APP))
    state = retain.load(path)
    mem = MemoryImage()
    plc = FakePLC(mem)
    mode, why = retain.restart(plc, state, app=b"\x02" * 32)
    assert mode == "cold" and "changed" in why and "--keep-state" in why
    assert plc.started == "cold" and mem.mw.w[0] == 0
    mode, why = retain.restart(plc, state, app=b"\x02" * 32, keep_state=True)
    assert mode == "warm" and "--keep-state" in why and mem.mw.w[0] == -7
    assert retain.application_id(b"LD 1", {"timers": {"%TM0": {"preset": 50}}}) != \
        retain.application_id(b"LD 1", {"timers": {"%TM0": {"preset": 7}}})
    assert retain.application_id(b"LD 1", {"modbus": {"port": 1}}) == \
        retain.application_id(b"LD 1", {"modbus": {"port": 2}})


def _slot_offsets(path) -> list[int]:
    store = StateStore.open(path)
    try:
        store.load()
        lay = store._layout
        return [lay.slot_offset(i) for i in range(4)]
    finally:
        store.close()


def damaged_files(good: bytes, slots: list[int]) -> dict[str, bytes]:
    every_slot = bytearray(good)
    for off in slots:
        every_slot[off + 100] ^= 0x01
    bad_header = bytearray(good)
    bad_header[20] ^= 0x01
    return {
        "truncated": good[: len(good) // 2],
        "truncated header": good[:10],
        "every copy damaged": bytes(every_slot),
        "header damaged": bytes(bad_header),
        "padded": good + b"\0",
        "future version": good.replace(b"SOFTPLC-STATE 2", b"SOFTPLC-STATE 9", 1),
        "format 1": b"SOFTPLC-STATE 1 13 " + b"0" * 64 + b'\n{"format": 1}',
        "not a state file": b"hello world\n{}",
    }


CASES = {"truncated": "truncated", "truncated header": "not a softplc state file",
         "every copy damaged": "corrupt", "header damaged": "corrupt header",
         "padded": "padded", "future version": "version 9", "format 1": "version 1",
         "not a state file": "not a softplc state file"}


@pytest.mark.parametrize("case", list(CASES))
def test_damaged_file_is_an_error_unless_cold(tmp_path, case):
    path = tmp_path / "plc.state"
    retain.save(path, retain.capture(image_with_data()))
    path.write_bytes(damaged_files(path.read_bytes(), _slot_offsets(path))[case])
    with pytest.raises(StateFileError, match="--cold") as e:
        retain.load(path)
    assert CASES[case] in str(e.value)


def test_newest_copy_damaged_falls_back_to_the_previous(tmp_path):
    path = tmp_path / "plc.state"
    mem = image_with_data()
    store = started_store(path, mem)
    mem.mw.w[1] = 11
    commit(store, mem)
    mem.mw.w[1] = 22
    store.commit(retain.words_to_be(mem.mw.buf), bytes(mem.m))  # newest: slot seq 3
    newest = store._layout.slot_offset(store._slot)
    store.close()
    data = bytearray(path.read_bytes())
    data[newest + 100] ^= 1  # e.g. the kill came while this copy was being written
    path.write_bytes(bytes(data))
    assert struct.unpack_from("<h", retain.load(path).mw, 2)[0] == 11


def test_other_controller_is_an_error(tmp_path):
    path = tmp_path / "plc.state"
    state = retain.capture(image_with_data())
    state.mw = state.mw[:100]
    retain.save(path, state)
    with pytest.raises(StateFileError, match="50 %MW"):
        retain.restart(FakePLC(MemoryImage()), retain.load(path))


def test_checksummed_slot_with_bad_content(tmp_path):
    path = tmp_path / "plc.state"
    mem = image_with_data()
    store = started_store(path, mem)
    store.commit(retain.words_to_be(mem.mw.buf), bytes(mem.m), b"not json")
    store.close()
    with pytest.raises(StateFileError, match="unreadable content"):
        retain.load(path)


def test_second_store_on_one_file_is_refused(tmp_path):
    path = tmp_path / "plc.state"
    first = StateStore.open(path)
    first.start(retain.capture(image_with_data()))
    first.set_pid()
    try:
        with pytest.raises(StateFileError, match=r"in use by another softplc \(pid \d+\)"):
            StateStore.open(path)
    finally:
        first.close()
    StateStore.open(path).close()  # free again


def _kill_copy(path, tmp_path):
    """What a killed process leaves: the file as the page cache holds it, unclosed."""
    copy = tmp_path / "after-kill.state"
    shutil.copyfile(path, copy)
    return copy


def test_acknowledged_writes_survive_the_process_dying(tmp_path):
    """Writes are journaled before they are acknowledged; a new scan-boundary commit
    includes them. The file as left at any point holds every acknowledged write."""
    path = tmp_path / "plc.state"
    mem = image_with_data()
    store = started_store(path, mem)
    img = ModbusImage(mem, store=store, blocks=lambda: b"{}")
    img.write_words(100, [1, 2, 3])
    img.write_bits(7, [1])
    img.write_words(101, [20])
    st = retain.load(_kill_copy(path, tmp_path))  # killed before the next scan
    assert struct.unpack_from("<3h", st.mw, 200) == (1, 20, 3) and st.m[7] == 1
    img.apply_writes()
    mem.mw.w[102] = 30  # the program's work in the scan
    img.take_snapshot()  # scan boundary: committed
    img.write_words(100, [10])
    st = retain.load(_kill_copy(path, tmp_path))
    assert struct.unpack_from("<3h", st.mw, 200) == (10, 20, 30)
    for k in range(20_000):  # far more than the journal holds: it compacts into slots
        img.write_words(k % 3000, [k & 0x7FFF])
    st = retain.load(_kill_copy(path, tmp_path))
    expect = {k % 3000: k & 0x7FFF for k in range(20_000)}
    assert all(struct.unpack_from("<h", st.mw, 2 * a)[0] == v for a, v in expect.items())
    store.close()


def test_a_write_cut_off_mid_journal_entry_is_ignored(tmp_path):
    path = tmp_path / "plc.state"
    mem = image_with_data()
    store = started_store(path, mem)
    store.journal(retain.REGISTERS, 5, b"\x00\x05")
    pos = store._layout.journal_offset + store._jpos
    store.journal(retain.REGISTERS, 6, b"\x00\x06")
    store._mm[pos + 8] ^= 0xFF  # second entry torn
    store._mm.flush()
    st = retain.load(_kill_copy(path, tmp_path))
    assert struct.unpack_from("<2h", st.mw, 10) == (5, 0)
    store.close()


def test_persist_keeps_a_durable_copy(tmp_path):
    """Power loss: the durable slots are only written by persist (then msync'ed)."""
    path = tmp_path / "plc.state"
    mem = image_with_data()
    store = started_store(path, mem)
    mem.mw.w[9] = 99
    commit(store, mem)
    store.persist()
    mem.mw.w[9] = 100
    commit(store, mem)
    lay = store._layout
    data = bytearray(_kill_copy(path, tmp_path).read_bytes())
    store.close()
    for i in retain.VOLATILE:  # as if the volatile copies never reached the disk
        off = lay.slot_offset(i)
        data[off:off + lay.slot_size] = bytes(lay.slot_size)
    path.write_bytes(bytes(data))
    assert struct.unpack_from("<h", retain.load(path).mw, 18)[0] == 99


def test_persist_alternates_durable_copies(tmp_path):
    """A power cut during an msync tears at most the copy being written: the other
    durable copy holds the previous flush."""
    path = tmp_path / "plc.state"
    mem = image_with_data()
    store = started_store(path, mem)
    written = []
    for v in (1, 2, 3):
        mem.mw.w[9] = v
        commit(store, mem)
        store.persist()
        written.append(store._durable_seq.index(store.persisted_seq))
    assert written == [0, 1, 0]
    lay = store._layout
    data = bytearray(_kill_copy(path, tmp_path).read_bytes())
    store.close()
    for i in (*retain.VOLATILE, retain.DURABLE[0]):  # volatile lost, last flush torn
        off = lay.slot_offset(i)
        data[off + 200] ^= 0xFF
    path.write_bytes(bytes(data))
    assert struct.unpack_from("<h", retain.load(path).mw, 18)[0] == 2
