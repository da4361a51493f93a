"""Synthesis results to wire dicts (the shape of :class:`api_schemas.SynthesizeResponse`); the
packing itself is the wire layer's (:mod:`api_schemas.packing`, :mod:`api_schemas.delta`)."""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np

from api_schemas.packing import contact_bits, pack_rotations
from api_schemas.wire import Encoding, blob, packed_dtype
from synth_core.motion.skeleton import Skeleton
from synth_core.runtime.synthesis import Result


def skeleton_id(animal: str, skeleton: Skeleton) -> str:
    """Changes whenever the joint layout a stream is played on does."""
    h = hashlib.sha256()
    h.update("|".join(skeleton.names).encode())
    h.update(np.ascontiguousarray(skeleton.parents, np.int64).tobytes())
    h.update(np.ascontiguousarray(skeleton.offsets, np.float32).tobytes())
    return f"{animal}-{h.hexdigest()[:12]}"


def characters_out(result: Result, ids: list[str], frames: list[int],
                   encoding: Encoding) -> list[dict[str, Any]]:
    """Per kept character, its wire dict; ``frames``: each one's own frame count (characters
    padded to a common length are cut back to it)."""
    packed = pack_rotations(result.rotations, encoding)
    bits = contact_bits(result.contacts)
    out = []
    for c, (cid, n) in enumerate(zip(ids, frames, strict=True)):
        rot = blob(packed[c, :n])
        rot["encoding"] = encoding
        rot["dtype"] = packed_dtype(encoding)
        out.append({"id": cid, "scale": float(result.scales[c]), "frames": n,
                    "root": blob(result.root_pos[c, :n]), "rotations": rot,
                    "gait": blob(result.gait[c, :n]), "contacts": blob(bits[c, :n])})
    return out
