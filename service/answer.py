"""The msgpack answer of ``POST /v1/synthesize``, sent while the characters are synthesized.

msgpack is a concatenation (a map is its header, then its keys and values), so the answer can
go out in pieces -- the head, then each chunk of characters as soon as it is rendered and
packed, then the tail -- with the same bytes as ``msgpack.packb`` of the whole answer (tested),
and its length is known before the first rotation is made (ids, scales and frame counts are
known once the batch is prepared): it goes out with a Content-Length, and the network carries
one chunk while the next are synthesized. No batch-sized float32 rotations are made at all: the
chunks are rendered and packed side by side, each in its render thread's own :class:`Scratch`
pages (:func:`produce`).
"""

from __future__ import annotations

import base64
import functools
import json
import math
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import msgpack
import numpy as np

from api_schemas.packing import contact_bits, pack_rotations
from api_schemas.wire import BYTES_PER_JOINT_FRAME, Encoding, packed_dtype
from service import encode, jobs
from synth_core.compiled.scratch import Scratch
from synth_core.motion.lod import DETAILS
from synth_core.runtime.bank import Bank
from synth_core.runtime.parallel_render import render_in_order
from synth_core.runtime.synthesis import Rendered, prepare_batch
from synth_core.runtime.trajectory import TrajectoryError

PIECE_BYTES = 8 * 1024 * 1024  # float32 rotations per chunk: the chunks stay small enough to stream


def characters_per_piece(frames: int, joints: int) -> int:
    """Characters rendered into one piece: ``PIECE_BYTES`` of float32 rotations (at least one)."""
    return max(1, PIECE_BYTES // max(1, frames * joints * 16))


@dataclass(frozen=True)
class Hole:
    """Binary data that comes later; its length is known now. ``text``: it goes out as base64
    (a JSON answer's blobs), ``size`` bytes."""

    nbytes: int
    text: bool = False

    @property
    def size(self) -> int:
        return 4 * -(-self.nbytes // 3) if self.text else self.nbytes


Template = list[bytes | Hole]


def bin_header(n: int) -> bytes:
    """msgpack's header of ``bin`` data of ``n`` bytes (as ``packb`` writes it for ``bytes``)."""
    if n < 1 << 8:
        return struct.pack(">BB", 0xC4, n)
    if n < 1 << 16:
        return struct.pack(">BH", 0xC5, n)
    return struct.pack(">BI", 0xC6, n)


@dataclass(frozen=True)
class Spliced:
    """A value whose template is made already (:func:`character`)."""

    parts: Template


@dataclass(frozen=True)
class Items:
    """A list of ``n`` items that are not known yet: its template holds the list's own bytes
    (msgpack's array header, JSON's brackets) around ``ITEMS``, where they go."""

    n: int


ITEMS = Hole(-1)  # where an Items' items go in a template
END = object()  # the end of an answer whose length was not known when it started (None)


def json_template(value: Any) -> Template:
    """``value``'s JSON text as :func:`service.body.encode` writes it (compact, blobs' data as
    base64) with a text :class:`Hole` inside the quotes where each :class:`Hole` leaf's data goes."""
    parts: Template = []

    def walk(v: Any) -> None:
        if isinstance(v, Hole):
            parts.extend((b'"', Hole(v.nbytes, text=True), b'"'))
        elif isinstance(v, Spliced):
            parts.extend(v.parts)
        elif isinstance(v, Items):
            parts.extend((b"[", ITEMS, b"]"))
        elif isinstance(v, dict):
            parts.append(b"{")
            for i, (key, item) in enumerate(v.items()):
                parts.append((b"," if i else b"") + json.dumps(key).encode() + b":")
                walk(item)
            parts.append(b"}")
        elif isinstance(v, list):
            parts.append(b"[")
            for i, item in enumerate(v):
                if i:
                    parts.append(b",")
                walk(item)
            parts.append(b"]")
        else:
            parts.append(json.dumps(v, separators=(",", ":")).encode())

    walk(value)
    return _joined(parts)


def _joined(parts: Template) -> Template:
    """Neighbouring bytes joined."""
    joined: Template = []
    for part in parts:
        if joined and isinstance(part, bytes) and isinstance(joined[-1], bytes):
            joined[-1] += part
        else:
            joined.append(part)
    return joined


def template(value: Any, header: bool = True) -> Template:
    """``value``'s msgpack bytes with a :class:`Hole` where each :class:`Hole` leaf's data goes;
    neighbouring bytes are joined. ``header=False``: a map's entries without its header."""
    packer = msgpack.Packer(use_bin_type=True)
    parts: Template = []

    def walk(v: Any, header: bool = True) -> None:
        if isinstance(v, Hole):
            parts.extend((bin_header(v.nbytes), v))
        elif isinstance(v, Spliced):
            parts.extend(v.parts)
        elif isinstance(v, Items):
            parts.extend((packer.pack_array_header(v.n), ITEMS))
        elif isinstance(v, dict):
            if header:
                parts.append(packer.pack_map_header(len(v)))
            for key, item in v.items():
                walk(key)
                walk(item)
        elif isinstance(v, list):
            parts.append(packer.pack_array_header(len(v)))
            for item in v:
                walk(item)
        else:
            parts.append(packer.pack(v))

    walk(value, header)
    return _joined(parts)


def hole_blob(dtype: str, shape: list[int], itemsize: int) -> dict[str, Any]:
    """A wire blob (:func:`api_schemas.wire.blob`) whose data comes later."""
    return {"dtype": dtype, "shape": shape, "data": Hole(math.prod(shape) * itemsize)}


@functools.lru_cache(maxsize=256)
def _arrays(frames: int, joints: int, encoding: Encoding) -> tuple[bytes | Hole, ...]:
    """A character's entries after its id and scale: frame count and the four arrays (as holes:
    root, rotations, gait, contacts), the same for every character of that length."""
    components = 6 if encoding == "s48" else 4
    rotations = hole_blob(packed_dtype(encoding), [frames, joints, components],
                          BYTES_PER_JOINT_FRAME[encoding] // components)
    rotations["encoding"] = encoding
    return tuple(template({"frames": frames, "root": hole_blob("<f4", [frames, 3], 4),
                           "rotations": rotations, "gait": hole_blob("|i1", [frames], 1),
                           "contacts": hole_blob("|u1", [frames], 1)}, header=False))


def character(packer: msgpack.Packer | None, cid: str, scale: float, frames: int, joints: int,
              encoding: Encoding) -> Spliced:
    """One character of the answer (:func:`service.packing.characters_out`'s dict); msgpack, or
    JSON where there is no ``packer``."""
    if packer is None:
        components = 6 if encoding == "s48" else 4
        rotations = hole_blob(packed_dtype(encoding), [frames, joints, components],
                              BYTES_PER_JOINT_FRAME[encoding] // components)
        rotations["encoding"] = encoding
        return Spliced(json_template({"id": cid, "scale": scale, "frames": frames,
                                      "root": hole_blob("<f4", [frames, 3], 4), "rotations": rotations,
                                      "gait": hole_blob("|i1", [frames], 1),
                                      "contacts": hole_blob("|u1", [frames], 1)}))
    first = packer.pack_map_header(7) + packer.pack("id") + packer.pack(cid) + packer.pack("scale")
    rest = _arrays(frames, joints, encoding)
    return Spliced([first + packer.pack(scale) + rest[0], *rest[1:]])


def filled(parts: Template, arrays: list[np.ndarray]) -> list[bytes | memoryview]:
    """The template's bytes with the arrays' bytes in its holes, in order."""
    data = iter(arrays)
    out: list[bytes | memoryview] = []
    for part in parts:
        if isinstance(part, Hole):
            a = next(data)
            assert a.nbytes == part.nbytes and a.flags.c_contiguous
            view = memoryview(a.reshape(-1)).cast("B")  # type: ignore[arg-type]
            out.append(base64.b64encode(view) if part.text else view)
        else:
            out.append(part)
    return out


def produce(job: jobs.Job, bank: Bank, meta: dict[str, Any], emit: Callable[[Any], None],
            as_json: bool = False, prepared: Callable[[int, int], None] | None = None) -> int:
    """The answer to ``job`` (msgpack; ``as_json``: JSON text, blobs' data in base64):
    ``emit(length)``, the answer's whole length in bytes, once the batch is prepared; then
    ``emit(piece)`` for each piece of it, in order. ``meta``: the answer's fields before
    ``resample_rate`` (animal, skeleton_id, fps, encoding). ``prepared(characters, frames)``
    is told the size of what will be made before it is (it may refuse by raising). Returns the
    character-frames sent; 422 (:class:`ApiError`) for a bad trajectory or too many frames
    after resampling, before anything is emitted; :class:`jobs.Cancelled` between chunks once
    ``job.cancel`` is set.

    The chunks are made side by side (:func:`synth_core.runtime.parallel_render.render_in_order`),
    each planned, rendered (one thread), packed and joined in its thread's own :class:`Scratch` pages: the
    numpy around the render runs on every core too (a 500 x 500 answer in-process: 0.26-0.28
    -> 0.18-0.20 s; over HTTP, interleaved: best 0.226 -> 0.204 s, median 0.273 -> 0.230)."""
    req = job.request
    batch = _prepare(job, bank, prepared)
    prep, h, keys, options, frames = batch
    C, T = prep.positions.shape[:2]
    J = bank.skeleton.n_joints
    encoding: Encoding = req.encoding
    p = encode.packing(encoding, req.lod.frame_step, req.lod.detail,
                       [req.characters[c].detail for c in prep.kept], bank.skeleton, h)
    if not p.plain:
        return produce_detailed(job, bank, meta, emit, as_json, batch, p)
    packer = None if as_json else msgpack.Packer(use_bin_type=True)
    characters = [character(packer, job.ids[c], float(h[i]), n, J, encoding)
                  for i, (c, n) in enumerate(zip(prep.kept, frames, strict=True))]
    whole = {**meta, "resample_rate": prep.resample_rate, "characters": characters,
             "skipped": jobs.skipped(job, prep), "warnings": jobs.warned(job, prep)}
    parts = json_template(whole) if as_json else template(whole)
    emit(sum(p.size if isinstance(p, Hole) else len(p) for p in parts))
    holes = [i for i, p in enumerate(parts) if isinstance(p, Hole)]  # four per character, in order
    emit(b"".join(parts[:holes[0]] if holes else parts))  # type: ignore[arg-type]
    per_chunk = characters_per_piece(T, J)

    def piece(chunk: Rendered, scratch: Scratch) -> bytes:
        """The chunk's characters packed: from their first hole up to the next chunk's (the
        last: to the end)."""
        sl, p = chunk.characters, chunk.plan
        n = sl.stop - sl.start
        packed = pack_rotations(chunk.rotations, encoding,
                                out=None if encoding == "f32" else scratch.array(
                                    "packed", (n, T, J, 6 if encoding == "s48" else 4),
                                    np.uint8 if encoding == "s48" else np.int16))
        bits = contact_bits(chunk.contacts)
        arrays = []
        for i in range(n):
            k = frames[sl.start + i]
            arrays += [chunk.root[i, :k], packed[i, :k], p.gait[i, :k], bits[i, :k]]
        end = holes[4 * sl.stop] if 4 * sl.stop < len(holes) else len(parts)
        return b"".join(filled(parts[holes[4 * sl.start]:end], arrays))

    for made in render_in_order(bank, prep, h, keys, options, per_chunk, piece, job.cancel):
        emit(made)
    return sum(frames)


class _Batch(NamedTuple):
    """A prepared batch (:func:`prepare_batch`) and its characters' output frames."""
    prep: Any
    h: Any
    keys: Any
    options: Any
    frames: list[int]


def _prepare(job: jobs.Job, bank: Bank, prepared: Callable[[int, int], None] | None) -> _Batch:
    """The job's batch prepared (422 for a bad trajectory), its size told to ``prepared``."""
    req = job.request
    scales, seeds = jobs.character_scales_and_seeds(req)
    options = jobs.options(req, job.max_character_frames, job.ground)
    try:
        prep, h, keys = prepare_batch(bank, job.positions, req.fps, scales, options, job.ids, seeds)
    except TrajectoryError as exc:
        raise jobs.trajectory_error(exc, job) from None
    C, T = prep.positions.shape[:2]
    if prepared is not None:
        prepared(C, T)
    return _Batch(prep, h, keys, options, jobs.output_frames(job, T, prep.kept))


def _packed_rotations(chunk: Rendered, frames: list[int], p: encode.Packing
                      ) -> list[tuple[np.ndarray, dict[str, Any]]]:
    """Each character's packed rotations (its frames sent) and their map, packed a group at a
    time -- the characters of one frame count and one detail: usually the whole chunk -- not
    one encoder call per character."""
    sl = chunk.characters
    cs = np.arange(sl.start, sl.stop)
    group = np.asarray(frames)[cs] * len(DETAILS) + p.levels[cs]  # (frames, detail)
    out: list[tuple[np.ndarray, dict[str, Any]]] = [(np.empty(0), {})] * len(cs)
    for g in np.unique(group).tolist():
        members = np.flatnonzero(group == g)
        n, level = divmod(g, len(DETAILS))
        joints = None if DETAILS[level] == "full" else p.joints(DETAILS[level])
        a, b = int(members[0]), int(members[-1]) + 1
        # A run of rows is a view; scattered ones (mixed frame counts or details) a copy.
        rows = slice(a, b) if b - a == len(members) else members
        q = chunk.rotations[rows, 0:n:p.frame_step]
        for i, one in zip(members.tolist(), encode.rotations_each(q, p, cs[members], joints), strict=True):
            out[i] = one
    return out


def produce_detailed(job: jobs.Job, bank: Bank, meta: dict[str, Any], emit: Callable[[Any], None],
                     as_json: bool, batch: _Batch, p: encode.Packing) -> int:
    """:func:`produce` of an answer whose size is known only once it is packed (delta) or that
    leaves frames or joints out (a level of detail): ``emit(None)`` (no length: the answer goes
    out chunked), then the answer's head, each chunk's characters as soon as they are rendered
    and packed (the same bytes as the whole answer packed at once), its tail, and ``END``."""
    prep, h, keys, options, frames = batch
    C, T = prep.positions.shape[:2]
    J = bank.skeleton.n_joints
    k = p.frame_step
    head = {**meta, "fps": meta["fps"] / k, "frame_step": k, "joints": J}
    whole = {**head, "resample_rate": prep.resample_rate, "characters": Items(C),
             "skipped": jobs.skipped(job, prep), "warnings": jobs.warned(job, prep)}
    parts = json_template(whole) if as_json else template(whole)
    at = parts.index(ITEMS)
    comma = b"," if as_json else b""

    def piece(chunk: Rendered, scratch: Scratch) -> bytes:
        sl = chunk.characters
        bits = contact_bits(chunk.contacts)
        out: list[bytes | memoryview] = []
        for i, (packed, rot) in enumerate(_packed_rotations(chunk, frames, p)):
            c = sl.start + i
            sent = slice(0, frames[c], k)
            n = len(range(*sent.indices(T)))
            arrays = [np.ascontiguousarray(a) for a in (chunk.root[i, sent], packed,
                                                        chunk.plan.gait[i, sent], bits[i, sent])]
            rot["data"] = Hole(arrays[1].nbytes)
            one = {"id": job.ids[prep.kept[c]], "scale": float(h[c]), "frames": n,
                   "root": hole_blob("<f4", [n, 3], 4), "rotations": rot,
                   "gait": hole_blob("|i1", [n], 1), "contacts": hole_blob("|u1", [n], 1)}
            out += [comma] if c else []
            out += filled(json_template(one) if as_json else template(one), arrays)
        return b"".join(out)  # a copy: the chunk lives in this thread's scratch pages, reused next

    emit(None)
    emit(b"".join(parts[:at]))  # type: ignore[arg-type]
    for made in render_in_order(bank, prep, h, keys, options, characters_per_piece(T, J), piece, job.cancel):
        emit(made)
    if job.cancel.is_set():
        raise jobs.Cancelled
    emit(b"".join(parts[at + 1:]))  # type: ignore[arg-type]
    emit(END)
    return sum(frames)
