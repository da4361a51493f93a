"""Schemathesis hooks (SCHEMATHESIS_HOOKS=tests/schemathesis_hooks.py): bodies in msgpack.

Requests: the generated body (JSON-shaped; blob ``data`` as base64 text, which the service takes
in msgpack too) packed as msgpack; integers beyond 64 bits travel as floats (msgpack has no
others). Responses: msgpack unpacked, ``bin`` turned into base64 text, as the JSON schema of the
same model describes it.
"""

from __future__ import annotations

import base64
from typing import Any

import msgpack
import schemathesis

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
def to_msgpack(ctx: schemathesis.SerializationContext, value: Any) -> dict[str, Any]:
    return {"data": msgpack.packb(_packable(value), use_bin_type=True)}


@schemathesis.deserializer(*MSGPACK_TYPES)
def from_msgpack(ctx: schemathesis.DeserializationContext, response: Any) -> Any:
    return _as_json(msgpack.unpackb(response.content))
