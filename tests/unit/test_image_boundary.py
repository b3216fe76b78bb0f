"""The Modbus image's scan boundary (softplc/modbus/image.py): the snapshot is redone only
where the memory changed, and what hosts read and the store keeps stay those of the
boundary, host writes laid over as before.

The model: after every boundary a reader sees the memory's image with the writes
acknowledged since the last apply laid over it; between boundaries, each accepted write
at once. The property test runs random scans (program writes, host writes at any point,
boundaries) against that model."""

from __future__ import annotations

import struct

import pytest
from fuzz_budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from softplc.modbus.image import ModbusImage
from softplc.persist import retain
from softplc.runtime.memory import MemoryImage

N_WORDS = 8  # the registers and coils the tests touch (the image holds more)


def regs(img: ModbusImage, n: int = N_WORDS) -> list[int]:
    return list(struct.unpack(f">{n}H", img.read_registers_wire(0, n)))


def coils(img: ModbusImage, n: int = N_WORDS) -> list[int]:
    return list(img.coils[:n])


def test_a_changed_word_or_bit_is_seen_after_the_boundary_only():
    mem = MemoryImage()
    img = ModbusImage(mem)
    mem.mw.w[3] = 1234
    mem.m[5] = True
    assert regs(img)[3] == 0 and coils(img)[5] == 0  # the scan has not ended
    img.take_snapshot()
    assert regs(img)[3] == 1234 and coils(img)[5] == 1
    img.take_snapshot()  # nothing changed: the same image
    assert regs(img)[3] == 1234 and coils(img)[5] == 1
    mem.mw.w[3] = 7
    img.take_snapshot()
    assert regs(img)[3] == 7 and coils(img)[5] == 1
    mem.m[5] = False
    img.take_snapshot()
    assert regs(img)[3] == 7 and coils(img)[5] == 0


@pytest.mark.parametrize("kind", ["register", "coil"])
def test_the_program_putting_back_what_a_host_wrote_is_seen(kind):
    """A host writes a register (or a coil); the next scan applies it and the program puts
    it back to its value at the boundary before: the memory equals that boundary's, yet
    readers must now see the program's value, not the write."""
    mem = MemoryImage()
    img = ModbusImage(mem)
    mem.mw.w[1], mem.m[2] = 5, True
    img.take_snapshot()
    if kind == "register":
        img.write_words(1, [9])
        assert regs(img)[1] == 9  # read back at once
    else:
        img.write_bits(2, [0])
        assert coils(img)[2] == 0
    img.apply_writes()
    assert (mem.mw.w[1], mem.m[2]) == ((9, True) if kind == "register" else (5, False))
    mem.mw.w[1], mem.m[2] = 5, True  # the program's work in the scan
    img.take_snapshot()
    assert regs(img)[1] == 5 and coils(img)[2] == 1


@pytest.mark.parametrize("kind", ["register", "coil"])
def test_a_write_pending_at_a_boundary_is_laid_over_the_next_one_too(kind):
    """A write acknowledged during a scan (after that scan's apply) is laid over the
    boundary's image; the next scan applies it, and if the program then puts the old value
    back the boundary after shows the program's value."""
    mem = MemoryImage()
    img = ModbusImage(mem)
    img.take_snapshot()
    img.apply_writes()
    if kind == "register":  # arrives mid-scan
        img.write_words(4, [77])
    else:
        img.write_bits(4, [1])
    img.take_snapshot()
    assert (regs(img)[4], coils(img)[4]) == ((77, 0) if kind == "register" else (0, 1))
    assert (mem.mw.w[4], mem.m[4]) == (0, False)
    img.apply_writes()
    assert (mem.mw.w[4], mem.m[4]) == ((77, False) if kind == "register" else (0, True))
    mem.mw.w[4], mem.m[4] = 0, False  # the program resets it: the last boundary's memory
    img.take_snapshot()
    assert (regs(img)[4], coils(img)[4]) == (0, 0)


def test_a_held_image_keeps_its_snapshot_and_the_boundary_call_takes_it_anyway():
    mem = MemoryImage()
    img = ModbusImage(mem)
    img.hold = True  # a scan cut short: its memory is neither shown nor kept
    mem.mw.w[0] = 3
    img.take_snapshot()
    assert regs(img)[0] == 0
    img.snapshot_boundary()  # an online change's swap, between two scans
    assert regs(img)[0] == 3


def test_every_boundary_is_committed_to_the_store_even_with_the_memory_unchanged(tmp_path):
    """The blocks' state moves with time while the words and bits stand still: each
    boundary makes a new slot, and the file holds the last boundary's blocks."""
    path = tmp_path / "plc.state"
    mem = MemoryImage()
    store = retain.StateStore.open(path)
    store.load()
    store.start(retain.capture(mem))
    state = {"n": 0}
    img = ModbusImage(mem, store=store,
                      blocks=lambda: retain.encode_blocks({"TM": {0: {"V": state["n"]}}}))
    mem.mw.w[2] = 42
    for n in range(1, 4):
        state["n"] = n
        before = store.commits
        img.take_snapshot()
        assert store.commits == before + 1
    store.close()
    kept = retain.load(path)
    assert kept is not None
    assert kept.blocks["TM"][0]["V"] == 3
    assert struct.unpack_from("<H", kept.mw, 4)[0] == 42


# ---- the property: random scans against the model ----------------------------------------
# one step of a scan: ("prog", kind, addr, value) the program writes the memory,
# ("host", kind, addr, value) a host writes through the image (at any point of the scan)
step = st.one_of(
    st.tuples(st.just("prog"), st.sampled_from(["w", "m"]), st.integers(0, N_WORDS - 1),
              st.integers(0, 3)),
    st.tuples(st.just("host"), st.sampled_from(["w", "m"]), st.integers(0, N_WORDS - 1),
              st.integers(0, 3)),
)
scan = st.tuples(st.lists(step, max_size=4), st.lists(step, max_size=2))  # before/after apply


@settings(max_examples=examples(200), deadline=None)
@given(st.lists(scan, min_size=1, max_size=12))
def test_readers_see_the_boundary_image_with_the_pending_writes_over_it(scans):
    mem = MemoryImage()
    img = ModbusImage(mem)
    pending_w: dict[int, int] = {}
    pending_m: dict[int, int] = {}

    def do(s: tuple[str, str, int, int]) -> None:
        who, kind, addr, value = s
        if who == "prog":
            if kind == "w":
                mem.mw.w[addr] = value
            else:
                mem.m[addr] = bool(value & 1)
        elif kind == "w":
            img.write_words(addr, [value])
            pending_w[addr] = value
        else:
            img.write_bits(addr, [value & 1])
            pending_m[addr] = value & 1

    def model() -> tuple[list[int], list[int]]:
        w = [mem.mw.w[i] for i in range(N_WORDS)]
        m = [int(mem.m[i]) for i in range(N_WORDS)]
        for a, v in pending_w.items():
            w[a] = v
        for a, v in pending_m.items():
            m[a] = v
        return w, m

    for early, late in scans:
        for s in early:  # host writes before the scan: applied at its start
            if s[0] == "host":
                do(s)
        img.apply_writes()
        pending_w.clear()
        pending_m.clear()
        for s in early:  # the program's work
            if s[0] == "prog":
                do(s)
        for s in late:  # anything during the scan, after the apply
            do(s)
        img.take_snapshot()
        assert (regs(img), coils(img)) == model()
        # and the whole image, not only the part written: the rest is the memory's
        assert img.regs_wire[2 * N_WORDS:] == retain.words_to_be(mem.mw.buf)[2 * N_WORDS:]
        assert img.coils[N_WORDS:] == bytes(mem.m[N_WORDS:])
