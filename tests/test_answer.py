"""The REST answer sent in pieces (service.answer) is byte for byte the answer built whole."""

from __future__ import annotations

import base64
import json
from typing import Any

import msgpack
import numpy as np
import pytest

from api_schemas.wire import blob
from service import answer, encode, jobs
from service.packing import characters_out
from service.settings import Settings
from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank
from synth_core.runtime.synthesis import synthesize


def body(encoding: str) -> dict[str, Any]:
    paths = crowd.simulate(7, 140, seed=3).astype(np.float32)
    characters: list[dict[str, Any]] = [{"id": f"h{c}", "points": blob(p)} for c, p in enumerate(paths)]
    characters[2]["points"] = blob(paths[2, :90])  # a shorter one: cut back to its own length
    bad = paths[4].copy()
    bad[70] = np.nan  # skipped (skip_invalid), the others kept
    characters[4]["points"] = blob(bad)
    characters[5]["scale"] = 1.3
    return {"seed": 4, "encoding": encoding, "skip_invalid": True, "characters": characters}


def _base64(value: Any) -> Any:
    if isinstance(value, bytes):
        return base64.b64encode(value).decode("ascii")
    if isinstance(value, dict):
        return {k: _base64(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_base64(v) for v in value]
    return value


def whole(job: jobs.Job, bank: Bank, meta: dict[str, Any], as_json: bool = False) -> bytes:
    """The answer built whole: synthesize, then every field packed at once (msgpack; or compact
    JSON, blobs' data as base64)."""
    req = job.request
    scales, seeds = jobs.character_scales_and_seeds(req)
    result = synthesize(bank, job.positions, req.fps, scales, jobs.options(req), ids=job.ids, seeds=seeds)
    frames = jobs.output_frames(job, result.root_pos.shape[1], result.kept)
    ids = [job.ids[c] for c in result.kept]
    reply = {**meta, "resample_rate": result.resample_rate,
             "characters": characters_out(result, ids, frames, req.encoding),
             "skipped": jobs.skipped(job, result), "warnings": jobs.warned(job, result)}
    if as_json:
        return json.dumps(_base64(reply), separators=(",", ":")).encode()
    return msgpack.packb(reply, use_bin_type=True)  # type: ignore[no-any-return]


@pytest.mark.parametrize(("encoding", "as_json"), [("s48", False), ("i16", False), ("f32", False),
                                                   ("s48", True), ("f32", True)])
def test_the_answer_in_pieces_is_the_whole_answer_byte_for_byte(bank: Bank, encoding: str, as_json: bool,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(answer, "PIECE_BYTES", 3 * 140 * bank.skeleton.n_joints * 16)  # 3 a chunk
    job = jobs.parse(body(encoding), Settings(), {"horse": bank})
    meta = {"animal": "horse", "skeleton_id": "horse-x", "fps": bank.fps, "encoding": encoding}
    emitted: list[Any] = []
    sent = answer.produce(job, bank, meta, emitted.append, as_json)
    length, pieces = emitted[0], emitted[1:]
    assert len(pieces) == 1 + 2  # the head, then 6 kept characters 3 at a time
    expected = whole(job, bank, meta, as_json)
    assert b"".join(pieces) == expected and length == len(expected)
    decoded = json.loads(expected) if as_json else msgpack.unpackb(expected)
    assert [c["id"] for c in decoded["characters"]] == ["h0", "h1", "h2", "h3", "h5", "h6"]
    assert decoded["skipped"][0]["index"] == 4 and sent == sum(c["frames"] for c in decoded["characters"])
    # The render threads' scratch pages are reused by the next answer, and it is the same again.
    emitted.clear()
    answer.produce(job, bank, meta, emitted.append, as_json)
    assert b"".join(emitted[1:]) == expected


def whole_delta(job: jobs.Job, bank: Bank, meta: dict[str, Any]) -> dict[str, Any]:
    """A delta answer built whole: synthesize, then each character's rotations encoded alone."""
    req = job.request
    scales, seeds = jobs.character_scales_and_seeds(req)
    result = synthesize(bank, job.positions, req.fps, scales, jobs.options(req), ids=job.ids, seeds=seeds)
    frames = jobs.output_frames(job, result.root_pos.shape[1], result.kept)
    p = encode.packing("delta", 1, "full", [None] * len(frames), bank.skeleton, result.scales)
    characters = characters_out(result, [job.ids[c] for c in result.kept], frames, "f32")
    for c, (one, n) in enumerate(zip(characters, frames, strict=True)):
        packed, rot = encode.rotations_each(result.rotations[c:c + 1, :n], p, np.array([c]), None)[0]
        one["rotations"] = rot | {"data": packed.tobytes()}
        for key in ("root", "gait", "contacts"):
            one[key]["data"] = bytes(one[key]["data"])
    return {**meta, "frame_step": 1, "joints": bank.skeleton.n_joints,
            "resample_rate": result.resample_rate, "characters": characters,
            "skipped": jobs.skipped(job, result), "warnings": jobs.warned(job, result)}


@pytest.mark.parametrize("as_json", [False, True])
def test_a_delta_answer_goes_out_chunk_by_chunk_as_the_whole_answer(
        bank: Bank, as_json: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """Its length is known only once packed: no length first, each chunk's characters as soon as
    they are made, then the tail and the end."""
    monkeypatch.setattr(answer, "PIECE_BYTES", 3 * 140 * bank.skeleton.n_joints * 16)  # 3 a chunk
    job = jobs.parse(body("delta"), Settings(), {"horse": bank})
    meta = {"animal": "horse", "skeleton_id": "horse-x", "fps": bank.fps, "encoding": "delta"}
    emitted: list[Any] = []
    sent = answer.produce(job, bank, meta, emitted.append, as_json)
    assert emitted[0] is None and emitted[-1] is answer.END
    pieces = emitted[1:-1]
    assert len(pieces) == 1 + 2 + 1  # the head, 6 kept characters 3 at a time, the tail
    got = json.loads(b"".join(pieces)) if as_json else msgpack.unpackb(b"".join(pieces))
    expected = whole_delta(job, bank, meta)
    assert got == (json.loads(json.dumps(_base64(expected))) if as_json else expected)
    assert sent == sum(c["frames"] for c in got["characters"])


def test_a_cancelled_answer_stops_between_chunks(bank: Bank, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(answer, "PIECE_BYTES", 140 * bank.skeleton.n_joints * 16)  # one a chunk
    job = jobs.parse(body("s48"), Settings(), {"horse": bank})
    emitted: list[Any] = []

    def emit(item: Any) -> None:
        emitted.append(item)
        if len(emitted) == 3:  # length, head, first character
            job.cancel.set()

    with pytest.raises(jobs.Cancelled):
        answer.produce(job, bank, {"animal": "horse"}, emit)
    assert len(emitted) == 3


def test_msgpack_bin_headers_are_msgpacks_own() -> None:
    for n in (0, 1, 255, 256, 65535, 65536, 1 << 20):
        assert answer.bin_header(n) == msgpack.packb(b"\0" * n, use_bin_type=True)[:-n or None]
