"""A stream's chunk message packed in place (service.chunk) is byte for byte msgpack's packing of
the message as a dict -- from one window, or from a live session's shards' windows; a Shelf lends
a session's scratch to the next."""

from __future__ import annotations

import msgpack
import numpy as np
import pytest

from service.chunk import chunk_message, packed_chunk
from synth_core.compiled.scratch import Scratch, Shelf
from synth_core.runtime.streaming import Window, joined


def window(C: int, n: int, J: int, start: int, seed: int) -> Window:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(C, n, J, 4)).astype(np.float32)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return Window(start, rng.normal(size=(C, n, 3)).astype(np.float32), q,
                  rng.integers(-1, 5, (C, n)).astype(np.int8), rng.random((C, n, 4)) < 0.5)


@pytest.mark.parametrize("encoding", ["s48", "i16", "f32"])
def test_a_chunk_is_msgpacks_bytes_of_its_message(encoding: str) -> None:
    shards = [window(c, 7, 5, 42, seed) for seed, c in enumerate((3, 1, 4))]
    whole = joined(shards)
    want = msgpack.packb(chunk_message(2, 9, whole, encoding), use_bin_type=True)
    for parts in (shards, [whole]):
        frames, got = packed_chunk(2, 9, parts, encoding)
        assert frames == 7 and bytes(got) == want
    message = msgpack.unpackb(got)
    assert message["rotations"]["shape"][:3] == [8, 7, 5] and message["start"] == 42


def test_a_big_chunks_rotations_are_packed_in_place_aligned() -> None:
    """Over 64 KiB of rotations (msgpack's bin 32 header), each of several packings aligned
    wherever its buffer landed: the same bytes every time."""
    w = window(40, 30, 20, 0, 1)
    want = msgpack.packb(chunk_message(0, 0, w, "s48"), use_bin_type=True)
    for _ in range(4):
        assert bytes(packed_chunk(0, 0, [w], "s48")[1]) == want


def test_chunks_packed_on_a_scratch_reuse_its_buffer() -> None:
    """On a Scratch buffer (a live session's: one sent while the next is packed), a chunk is
    the same bytes, and a later one of no more bytes is packed over it."""
    scratch = Scratch()
    big, small = window(6, 9, 5, 0, 1), window(6, 4, 5, 9, 2)
    first = packed_chunk(0, 0, [big], "s48", scratch, "a")[1]
    assert bytes(first) == msgpack.packb(chunk_message(0, 0, big, "s48"), use_bin_type=True)
    other = packed_chunk(0, 1, [small], "s48", scratch, "b")[1]
    again = packed_chunk(0, 2, [small], "s48", scratch, "a")[1]
    assert bytes(again) == msgpack.packb(chunk_message(0, 2, small, "s48"), use_bin_type=True)
    assert np.shares_memory(np.frombuffer(first, np.uint8), np.frombuffer(again, np.uint8))
    assert not np.shares_memory(np.frombuffer(other, np.uint8), np.frombuffer(again, np.uint8))


def test_a_shelf_lends_what_was_given_back_and_keeps_few() -> None:
    shelf = Shelf(keep=2)
    first = shelf.take()
    pages = packed_chunk(0, 0, [window(6, 9, 5, 0, 1)], "s48", first, "chunk0")[1]
    shelf.give(first)
    again = shelf.take()
    assert again is first  # the next session packs over the pages the last one touched
    small = window(2, 3, 5, 0, 2)
    reused = packed_chunk(0, 0, [small], "s48", again, "chunk0")[1]
    assert np.shares_memory(np.frombuffer(pages, np.uint8), np.frombuffer(reused, np.uint8))
    assert bytes(reused) == msgpack.packb(chunk_message(0, 0, small, "s48"), use_bin_type=True)
    assert shelf.take() is not first  # lent: never to two at once
    for s in [again, again, Scratch(), Scratch()]:  # the same twice counts once; at most two kept
        shelf.give(s)
    kept = [shelf.take() for _ in range(3)]
    assert kept[0] is not kept[1] and again in kept[:2] and all(k not in kept[:2] for k in kept[2:])
