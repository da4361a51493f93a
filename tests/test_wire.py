"""The wire format: blobs round-trip, each rotation encoding within its documented error, the
compiled packers byte-equal to the numpy reference, and the body decoder refuses garbage with a 422."""

from __future__ import annotations

import msgpack
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from api_schemas.packing import contact_bits, pack_rotations
from api_schemas.wire import (
    BYTES_PER_JOINT_FRAME,
    ENCODING_ERROR,
    FIXED_ENCODINGS,
    WireError,
    blob,
    decode_rotations,
    encode_rotations,
    rotation_angle,
    unblob,
    worst_error,
)
from service.body import decode
from service.errors import ApiError
from service.jobs import parse
from service.settings import Settings


def random_rotations(n: int, seed: int = 0) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4)).astype(np.float32)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


@pytest.mark.parametrize("encoding", FIXED_ENCODINGS)
def test_each_encoding_is_within_its_documented_error(encoding: str) -> None:
    degrees, mm = worst_error(encoding, n=200_000, seed=1)  # type: ignore[arg-type]
    assert degrees <= ENCODING_ERROR[encoding][0] and mm <= ENCODING_ERROR[encoding][1]
    packed = encode_rotations(random_rotations(10), encoding)  # type: ignore[arg-type]
    assert packed.nbytes == 10 * BYTES_PER_JOINT_FRAME[encoding]


def test_s48_is_six_bytes_and_keeps_edge_cases() -> None:
    edge = np.array([[1, 0, 0, 0], [0, 0, 0, -1], [0.5, -0.5, 0.5, -0.5], [0, 0.70710677, 0.70710677, 0],
                     [0, 0, 0, 1], [-0.70710677, 0, 0, 0.70710677]], np.float32)
    packed = encode_rotations(edge, "s48")
    assert packed.shape == (6, 6) and packed.dtype == np.uint8
    assert np.degrees(rotation_angle(edge, decode_rotations(packed, "s48"))).max() < ENCODING_ERROR["s48"][0]
    assert not (packed[:, 5] & 0x80).any()  # bit 47 stays 0


@pytest.mark.parametrize("encoding", ["s48", "i16"])
def test_compiled_packers_give_the_reference_bytes(encoding: str) -> None:
    q = random_rotations(50_000, seed=2)
    # Ties and edges too: components equal in size, on an axis, at +-1/sqrt 2, both signs.
    rng = np.random.default_rng(3)
    axes = np.eye(4, dtype=np.float32)[rng.integers(0, 4, 500)] * rng.choice([-1, 1], (500, 1))
    steps = np.round(q[1000:3000] * 2) / 2
    steps /= np.maximum(np.linalg.norm(steps, axis=1, keepdims=True), 1e-6)
    q = np.concatenate([q[:1000], axes, steps, q[3000:]]).astype(np.float32)[:49_994].reshape(-1, 7, 4)  # not a whole number of blocks
    packed = pack_rotations(q, encoding)  # type: ignore[arg-type]
    assert np.array_equal(packed, encode_rotations(q, encoding))  # type: ignore[arg-type]
    into = np.full_like(packed, 7)
    assert pack_rotations(q, encoding, out=into) is into and np.array_equal(into, packed)  # type: ignore[arg-type]


def test_blobs_round_trip_and_refuse_what_does_not_add_up() -> None:
    a = np.arange(12, dtype=np.float32).reshape(4, 3)
    b = blob(a)
    assert b["dtype"] == "<f4" and b["shape"] == [4, 3]
    assert np.array_equal(unblob(b["dtype"], b["shape"], b["data"]), a)
    with pytest.raises(WireError, match=r"points.data: 8 bytes do not hold <f4 of shape \[4, 3\]"):
        unblob("<f4", [4, 3], b"\0" * 8, "points")
    with pytest.raises(WireError, match="dtype must be one of"):
        unblob(">f8", [1], b"\0" * 8, "points")


def test_contact_bits_follow_the_foot_order() -> None:
    contacts = np.array([[True, False, False, False], [False, True, False, True]])
    assert contact_bits(contacts).tolist() == [1, 10]


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200))
def test_any_bytes_decode_or_are_refused_with_422(raw: bytes) -> None:
    for kind in ("application/vnd.msgpack", "application/json"):
        refused: ApiError | None = None
        try:
            decode(raw, kind)
        except ApiError as exc:
            refused = exc
        assert refused is None or (refused.status == 422 and refused.field == "body"), refused


values = st.recursive(st.none() | st.booleans() | st.integers(-2**63, 2**64 - 1) | st.floats() | st.text(max_size=8)
                      | st.binary(max_size=24),
                      lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner,
                                                                                   max_size=4),
                      max_leaves=20)
requests = st.fixed_dictionaries({"characters": st.lists(st.fixed_dictionaries(
    {"id": values, "points": st.one_of(values, st.fixed_dictionaries(
        {"dtype": st.sampled_from(["<f4", "<f8", "<i2", "x"]), "shape": st.lists(st.integers(-2, 5), max_size=3),
         "data": st.binary(max_size=48)}))}), max_size=3)}, optional={"animal": values, "fps": values,
                                                                       "encoding": values, "seed": values})


@settings(max_examples=300, deadline=None)
@given(requests)
def test_any_msgpack_structure_is_parsed_or_refused_with_422(body: dict) -> None:
    raw = msgpack.packb(body, use_bin_type=True)
    refused: ApiError | None = None
    try:
        parse(decode(raw, "application/vnd.msgpack"), Settings(), {"horse": None})  # type: ignore[dict-item]
    except ApiError as exc:
        refused = exc
    except (TypeError, AttributeError) as exc:  # pragma: no cover - would be a 500
        pytest.fail(f"parse crashed: {exc!r}")
    assert refused is None or (refused.status == 422 and refused.message), refused


def test_a_refusal_names_what_a_blob_is_and_the_next_problems_by_field() -> None:
    """A client that sends points as a list of numbers is told what a blob is; problems after the
    first are named by field (up to errors.NAMED), the rest counted."""
    body = {"characters": [{"id": "a", "points": [[0, 0, 0], [1, 0, 0]]}]}
    with pytest.raises(ApiError) as exc:
        parse(body, Settings(), {"horse": None})  # type: ignore[dict-item]
    assert exc.value.status == 422 and exc.value.field == "characters[0].points"
    assert "expected a blob" in exc.value.message and "got a list" in exc.value.message
    points = blob(np.zeros((3, 3), np.float32))
    many = {"characters": [{"id": f"c{i}", "points": points, "colour": i} for i in range(6)]}
    with pytest.raises(ApiError) as exc:
        parse(many, Settings(), {"horse": None})  # type: ignore[dict-item]
    assert exc.value.field == "characters[0].colour"
    for i in (1, 2, 3):
        assert f"characters[{i}].colour: Extra inputs are not permitted" in exc.value.message
    assert "characters[4]" not in exc.value.message and "2 more" in exc.value.message
