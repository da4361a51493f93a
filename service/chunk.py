"""A stream's ``chunk`` message (docs/streaming.md): frames ``[start, start + n)`` of every
character, packed into one buffer.

A live tick of 4,000 horses is ~30 MB of rotations. Packed as a dict (:func:`chunk_message`,
the reference) they were copied three times on the way -- into the packed array, into bytes,
into msgpack's buffer -- a sixth of the tick's time. Here the message's bytes are laid out
first (:func:`service.answer.template`: its length and where each array goes are known from
the shapes), then every array is written once, straight into its place: the rotations packed
there by the compiled packer. A live session's shards give one window each (consecutive
characters, the same frames), which fill each array's rows in turn: no joined window is made.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import msgpack
import numpy as np
from numpy.typing import NDArray

from api_schemas.packing import contact_bits, pack_rotations
from api_schemas.wire import BYTES_PER_JOINT_FRAME, Encoding, blob, packed_dtype
from service import encode
from service.answer import Hole, hole_blob, template
from synth_core.compiled import render_pool
from synth_core.compiled.scratch import Scratch
from synth_core.runtime.streaming import Window

_ALIGN = 8  # the rotations' place in the buffer: the compiled packer writes uint16 words there


def chunk_message(batch: int, index: int, window: Window, encoding: Encoding) -> dict[str, Any]:
    """The chunk message as a dict (the reference :func:`packed_chunk` is held to, byte for byte)."""
    rotations = blob(pack_rotations(window.rotations, encoding))
    rotations["encoding"] = encoding
    rotations["dtype"] = packed_dtype(encoding)
    return {"type": "chunk", "batch": batch, "chunk": index, "start": window.start,
            "frames": window.stop - window.start, "root": blob(window.root_pos), "rotations": rotations,
            "gait": blob(window.gait), "contacts": blob(contact_bits(window.contacts))}


def detailed_chunk(batch: int, index: int, windows: Sequence[Window],
                   p: encode.Packing) -> tuple[int, memoryview]:
    """:func:`packed_chunk` of a chunk whose size is known only once packed (delta) or that
    leaves out frames (``frame_step``: ``start`` and ``frames`` count the frames sent) or
    characters' rotations (a level of detail: ``rotations.characters`` lists the rows sent,
    ``rotations.joints`` the joints, when not all)."""
    first = windows[0]
    n = first.stop - first.start
    sent, start = encode.sent_frames(first.start, n, p.frame_step)
    root = np.concatenate([w.root_pos[:, sent] for w in windows])
    gait = np.concatenate([w.gait[:, sent] for w in windows])
    bits = contact_bits(np.concatenate([w.contacts[:, sent] for w in windows]))
    rows, joints = encode.chunk_rows(p)
    everyone = len(rows) == len(p.details)
    packed, rot = _rotations(windows, rows, joints, sent, p)
    if not everyone:
        rot["characters"] = rows.tolist()
    rot["data"] = packed.tobytes()
    message = {"type": "chunk", "batch": batch, "chunk": index, "start": start, "frames": root.shape[1],
               "root": blob(root), "rotations": rot, "gait": blob(gait), "contacts": blob(bits)}
    return n, memoryview(msgpack.packb(message, use_bin_type=True))


def _rotations(windows: Sequence[Window], rows: NDArray[np.int64], joints: NDArray[np.int64] | None,
               sent: slice, p: encode.Packing) -> tuple[NDArray[Any], dict[str, Any]]:
    """The chunk's rotations of characters ``rows`` (of the request) packed, and their map: each
    window's rows (only those sent are copied out: a far character's rotations never are)
    packed on its own, side by side on the render pool's one-kernel-thread threads (as
    :func:`packed_chunk` fills a live session's shards' windows), joined -- the same bytes as one
    call on them all (:func:`service.encode.rotations_joined`). One call's kernels fanned out to
    both cores cost a tenth more CPU, and on a busy machine more wall time, than one thread."""
    edges = np.cumsum([0, *(w.root_pos.shape[0] for w in windows)]).tolist()

    def one(w: Window, at: NDArray[np.int64], a: int) -> tuple[NDArray[Any], dict[str, Any]]:
        return encode.rotations(w.rotations[at - a][:, sent], p, at, joints)

    jobs = [functools.partial(one, w, at, a) for w, a, b in zip(windows, edges[:-1], edges[1:], strict=True)
            if len(at := rows[(rows >= a) & (rows < b)])] or [functools.partial(one, windows[0], rows, 0)]
    if len(jobs) == 1:
        with render_pool.one_thread():
            return jobs[0]()
    return encode.rotations_joined(render_pool.side_by_side(jobs), p.encoding)


def packed_chunk(batch: int, index: int, windows: Sequence[Window], encoding: Encoding,
                 scratch: Scratch | None = None, name: str = "chunk",
                 p: encode.Packing | None = None) -> tuple[int, memoryview]:
    """The frame count and the packed chunk message of ``windows`` (the same frames of
    consecutive characters; one window: all of them): ``msgpack.packb`` of
    :func:`chunk_message` of them joined, made in the pool (CPU work the event loop must not do).
    ``scratch``: packed on its buffer ``name`` (the message then holds until that is used again);
    ``p``: the request's encoding and level of detail, where they are not the plain case."""
    if p is not None and not p.plain:
        return detailed_chunk(batch, index, windows, p)
    first = windows[0]
    n = first.stop - first.start
    C = sum(w.root_pos.shape[0] for w in windows)
    J = first.rotations.shape[2]
    components = 6 if encoding == "s48" else 4
    rotations = hole_blob(packed_dtype(encoding), [C, n, J, components],
                          BYTES_PER_JOINT_FRAME[encoding] // components)
    rotations["encoding"] = encoding
    parts = template({"type": "chunk", "batch": batch, "chunk": index, "start": first.start, "frames": n,
                      "root": hole_blob("<f4", [C, n, 3], 4), "rotations": rotations,
                      "gait": hole_blob("|i1", [C, n], 1), "contacts": hole_blob("|u1", [C, n], 1)})
    sizes = [p.nbytes if isinstance(p, Hole) else len(p) for p in parts]
    starts = np.cumsum([0, *sizes]).tolist()
    holes = [i for i, p in enumerate(parts) if isinstance(p, Hole)]  # root, rotations, gait, contacts
    # Shifted in a slightly larger buffer so that the rotations start on an aligned address.
    size = starts[-1] + _ALIGN
    raw = np.empty(size, np.uint8) if scratch is None else scratch.array(name, (size,), np.uint8)
    shift = -(raw.ctypes.data + starts[holes[1]]) % _ALIGN
    buf = raw[shift:shift + starts[-1]]
    for i, part in enumerate(parts):
        if not isinstance(part, Hole):
            buf[starts[i]:starts[i + 1]] = np.frombuffer(part, np.uint8)
    places = [buf[starts[i]:starts[i + 1]] for i in holes]
    per_character = (n * 12, n * J * BYTES_PER_JOINT_FRAME[encoding], n, n)  # bytes in each array

    def fill(w: Window, row: int) -> None:
        """Window ``w``'s characters into their rows, from ``row`` on."""
        c = w.root_pos.shape[0]
        root, rot, gait, bits = (place[row * k:(row + c) * k] for place, k in zip(places, per_character,
                                                                                  strict=True))
        root[...] = np.ascontiguousarray(w.root_pos, "<f4").reshape(-1).view(np.uint8)
        if encoding == "f32":
            rot[...] = np.ascontiguousarray(pack_rotations(w.rotations, encoding)).reshape(-1).view(np.uint8)
        else:  # packed in place
            pack_rotations(w.rotations, encoding, out=rot.view(np.uint8 if encoding == "s48" else np.int16)
                           .reshape(c, n, J, components))
        gait[...] = np.ascontiguousarray(w.gait, np.int8).reshape(-1).view(np.uint8)
        bits[...] = contact_bits(w.contacts).reshape(-1)

    rows = np.cumsum([0, *(w.root_pos.shape[0] for w in windows)]).tolist()
    if len(windows) == 1:
        fill(first, 0)
    else:
        # A live session's shards' windows, each filled on a render-pool thread (one-thread
        # packer): faster in a whole session than the compiled packer's own two threads, though
        # either packs a chunk alone as fast (why is not pinned down; not the thread team spinning).
        render_pool.side_by_side([functools.partial(fill, w, row)
                                  for w, row in zip(windows, rows[:-1], strict=True)])
    return n, memoryview(buf)  # type: ignore[arg-type]

