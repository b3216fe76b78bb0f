"""State files bound what they read (issue 31 item 3, state files): a checksummed slot with
a 5,000-digit number, NaN, deep nesting or a block state of the wrong shape, and a header
claiming a huge layout, are StateFileErrors naming --cold, never a traceback."""

from __future__ import annotations

import struct
import zlib

import pytest
from test_retain import FakePLC, commit, image_with_data, started_store

from softplc.persist import retain
from softplc.persist.retain import _HEADER, MAX_STATE_OBJECTS, StateFileError


@pytest.mark.parametrize("blocks, words", [
    (b'{"TM": {"0": {"P": ' + b"9" * 5000 + b"}}}", "a number of 5000 characters"),
    (b'{"TM": {"0": {"P": NaN}}}', "NaN in a block's state"),
    (b'{"TM": {"0": {"P": -Infinity}}}', "-Infinity in a block's state"),
    (b'{"TM": {"0": ' + b"[" * 30_000 + b"]" * 30_000 + b"}}", "unreadable content"),
    (b'{"TM": {"' + b"9" * 5000 + b'": {}}}', "a number of 5000 characters"),
    (b'{"TM": [1, 2]}', "unreadable content"),
    (b'{"TM": {"0": 5}}', "unreadable content"),
])
def test_checksummed_blocks_with_bad_content_are_refused(tmp_path, blocks, words):
    path = tmp_path / "plc.state"
    mem = image_with_data()
    store = started_store(path, mem)
    store.commit(retain.words_to_be(mem.mw.buf), bytes(mem.m), blocks)
    store.close()
    with pytest.raises(StateFileError, match="--cold") as e:
        retain.load(path)
    assert words in str(e.value)


def test_a_block_state_of_the_wrong_type_is_refused_at_restart(tmp_path):
    path = tmp_path / "plc.state"
    mem = image_with_data()
    store = started_store(path, mem)
    store.commit(retain.words_to_be(mem.mw.buf), bytes(mem.m),
                 b'{"TM": {"0": {"P": "three", "_elapsed_us": [1]}}}')
    store.close()
    with pytest.raises(StateFileError, match=r"%TM0 cannot be restored.*--cold"):
        retain.restart(FakePLC(image_with_data()), retain.load(path))


def test_a_header_claiming_a_huge_layout_is_refused_before_mapping(tmp_path):
    path = tmp_path / "plc.state"
    mem = image_with_data()
    store = started_store(path, mem)
    commit(store, mem)
    store.close()
    data = bytearray(path.read_bytes())
    fields = list(_HEADER.unpack_from(data))
    fields[2] = MAX_STATE_OBJECTS + 1  # n_regs
    head = _HEADER.pack(*fields[:-1], 0)
    data[:_HEADER.size] = head[:-4] + struct.pack("<I", zlib.crc32(head[:-4]))
    path.write_bytes(bytes(data))
    with pytest.raises(StateFileError, match=f"claims {MAX_STATE_OBJECTS + 1} registers"):
        retain.load(path)
