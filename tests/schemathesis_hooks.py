"""Schemathesis hooks (SCHEMATHESIS_HOOKS=tests/schemathesis_hooks.py): bodies in msgpack, and
synthesize bodies that reach the synthesis.

Synthesize bodies: the OpenAPI document cannot say that a blob's ``data`` holds prod(shape)
items of its dtype, so schemathesis alone never made a body the service could synthesize (0 of
927, issue 34). Nine in ten generated bodies get consistent characters here -- 1 to 3 paths of
2 to 80 points, float32 or float64, at a speed and heading drawn, with the generated ``scale``
and ``seed`` kept -- and a loaded animal, a frame rate and resampling within the limits; every
other field stays as generated. The tenth is sent as generated. ``QUADSYNTH_FUZZ_LOG``: a file
each answer's method, path and status are appended to (the test counts the synthesize 200s).

Requests: the generated body (JSON-shaped; blob ``data`` as base64 text, which the service takes
in msgpack too) packed as msgpack; integers beyond 64 bits travel as floats (msgpack has no
others). Responses: msgpack unpacked, ``bin`` turned into base64 text, as the JSON schema of the
same model describes it.
"""

from __future__ import annotations

import base64
import math
import os
from typing import Any

import msgpack
import numpy as np
import schemathesis
from hypothesis import strategies as st

MSGPACK_TYPES = ("application/vnd.msgpack", "application/x-msgpack", "application/msgpack")


def _packable(value: Any) -> Any:
    """msgpack has no integers beyond 64 bits: such a generated number travels as a float."""
    if isinstance(value, int) and not isinstance(value, bool) and not -2**63 <= value < 2**64:
        return float(value)
    if isinstance(value, dict):
        return {k: _packable(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_packable(v) for v in value]
    return value


def _as_json(value: Any) -> Any:
    if isinstance(value, bytes):
        return base64.b64encode(value).decode("ascii")
    if isinstance(value, dict):
        return {k: _as_json(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_as_json(v) for v in value]
    return value


@schemathesis.serializer(*MSGPACK_TYPES)
def to_msgpack(ctx: schemathesis.SerializationContext, value: Any) -> bytes:
    # The body's bytes (schemathesis 4; a {"data": ...} dict, as 3.x took, went out form-encoded
    # and every msgpack case was refused as "not valid msgpack").
    return bytes(msgpack.packb(_packable(value), use_bin_type=True))


@schemathesis.deserializer(*MSGPACK_TYPES)
def from_msgpack(ctx: schemathesis.DeserializationContext, response: Any) -> Any:
    return _as_json(msgpack.unpackb(response.content))


@st.composite
def _path(draw: st.DrawFn, fps: float) -> dict[str, Any]:
    """A blob of a path that holds what its shape says: a walk along a heading (metres, Y up)."""
    frames = draw(st.integers(2, 80))
    speed = draw(st.floats(0.0, 6.0))  # m/s: standing to a horse's canter
    heading = draw(st.floats(0.0, 2 * math.pi))
    t = np.arange(frames) / fps
    start = draw(st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)))
    points = np.stack([start[0] + speed * t * math.sin(heading), np.zeros(frames),
                       start[1] + speed * t * math.cos(heading)], axis=1)
    dtype = draw(st.sampled_from(["<f4", "<f8"]))
    data = points.astype(dtype).tobytes()
    return {"dtype": dtype, "shape": [frames, 3], "data": base64.b64encode(data).decode("ascii")}


@st.composite
def _consistent(draw: st.DrawFn, body: dict[str, Any]) -> dict[str, Any]:
    if draw(st.integers(0, 9)) == 0:
        return body  # one in ten as generated
    body = dict(body)
    body["animal"] = draw(st.sampled_from(["horse", "dog"]))
    body["fps"] = fps = draw(st.floats(15.0, 120.0))
    body["min_resample_rate"] = draw(st.floats(1.0, 1.5))
    body["scale_min"], body["scale_max"] = sorted(draw(st.tuples(st.floats(0.5, 1.5), st.floats(0.5, 1.5))))
    given: list[Any] = body["characters"] if isinstance(body.get("characters"), list) else []
    characters = []
    for c in range(draw(st.integers(1, 3))):
        old = given[c] if c < len(given) and isinstance(given[c], dict) else {}
        kept = {k: v for k, v in old.items() if k in ("scale", "seed")}
        characters.append({"id": f"c{c}", "points": draw(_path(fps)), **kept})
    body["characters"] = characters
    return body


@schemathesis.hook
def flatmap_body(ctx: schemathesis.HookContext, body: Any) -> Any:
    operation = ctx.operation
    if operation is None or operation.path != "/v1/synthesize" or not isinstance(body, dict):
        return st.just(body)
    return _consistent(body)


@schemathesis.hook
def after_call(ctx: schemathesis.HookContext, case: Any, response: Any) -> None:
    log = os.environ.get("QUADSYNTH_FUZZ_LOG")
    if log:
        with open(log, "a") as out:
            error = response.content[:150] if response.status_code >= 400 else b""
            out.write(f"{case.method} {case.operation.path} {response.status_code} {error!r}\n")
