"""Quaternion helpers against scipy.spatial.transform.Rotation on random inputs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from synth_core.motion import quat

seeds = st.integers(min_value=0, max_value=2**31)  # room for seed + k


def rand_quats(seed: int, n: int = 64) -> np.ndarray:
    return Rotation.random(n, random_state=seed).as_quat()


def same_rotation(a: np.ndarray, b: np.ndarray, atol: float = 1e-9) -> bool:
    """q and -q are the same rotation."""
    return bool(np.all(np.abs(np.abs(np.sum(a * b, axis=-1)) - 1.0) < atol))


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_mul_inv_rotate_match_scipy(seed: int) -> None:
    a, b = rand_quats(seed), rand_quats(seed + 1)
    v = np.random.default_rng(seed).normal(size=(64, 3))
    ra, rb = Rotation.from_quat(a), Rotation.from_quat(b)
    assert same_rotation(quat.mul(a, b), (ra * rb).as_quat())
    assert same_rotation(quat.inv(a), ra.inv().as_quat())
    np.testing.assert_allclose(quat.rotate(a, v), ra.apply(v), atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_matrix_round_trip_and_scipy(seed: int) -> None:
    q = rand_quats(seed)
    m = quat.to_matrix(q)
    np.testing.assert_allclose(m, Rotation.from_quat(q).as_matrix(), atol=1e-12)
    assert same_rotation(quat.from_matrix(m), q)
    assert np.all(quat.from_matrix(m)[..., 3] >= 0)


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_axis_angle_and_rotvec_match_scipy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=(64, 3))
    angle = rng.uniform(-np.pi, np.pi, size=64)
    unit = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    expected = Rotation.from_rotvec(unit * angle[:, None]).as_quat()
    assert same_rotation(quat.from_axis_angle(axis, angle), expected)
    assert same_rotation(quat.from_rotvec(unit * angle[:, None]), expected)
    q = rand_quats(seed)
    np.testing.assert_allclose(quat.to_rotvec(q), Rotation.from_quat(q).as_rotvec(), atol=1e-9)
    np.testing.assert_allclose(quat.angle(q), Rotation.from_quat(q).magnitude(), atol=1e-9)


def test_tiny_rotations_keep_precision() -> None:
    rv = np.array([[1e-9, 0, 0], [0, 0, 0], [0, 3e-7, 0]])
    np.testing.assert_allclose(quat.to_rotvec(quat.from_rotvec(rv)), rv, atol=1e-15)


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_slerp_matches_scipy_and_nlerp_endpoints(seed: int) -> None:
    a, b = rand_quats(seed, 32), rand_quats(seed + 7, 32)
    t = np.random.default_rng(seed).uniform(size=32)
    expected = np.stack([Slerp([0, 1], Rotation.from_quat([a[i], b[i]]))(t[i]).as_quat()
                         for i in range(32)])
    assert same_rotation(quat.slerp(a, b, t), expected, atol=1e-9)
    assert same_rotation(quat.nlerp(a, b, np.zeros(32)), a)
    assert same_rotation(quat.nlerp(a, b, np.ones(32)), b)


def test_slerp_of_identical_quaternions_is_finite() -> None:
    q = rand_quats(3, 4)
    out = quat.slerp(q, q, np.full(4, 0.3))
    assert np.all(np.isfinite(out)) and same_rotation(out, q)


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_between_takes_u_onto_v(seed: int) -> None:
    rng = np.random.default_rng(seed)
    u, v = rng.normal(size=(64, 3)), rng.normal(size=(64, 3))
    v[0] = -u[0] * 2.0  # opposite directions take the half-turn branch
    q = quat.between(u, v)
    got = quat.rotate(q, u / np.linalg.norm(u, axis=-1, keepdims=True))
    np.testing.assert_allclose(got, v / np.linalg.norm(v, axis=-1, keepdims=True), atol=1e-9)
    # Smallest rotation: its angle equals the angle between u and v.
    cos = np.sum(u * v, -1) / np.linalg.norm(u, axis=-1) / np.linalg.norm(v, axis=-1)
    np.testing.assert_allclose(quat.angle(q), np.arccos(np.clip(cos, -1, 1)), atol=1e-6)


def test_make_continuous_removes_sign_flips() -> None:
    q = rand_quats(5, 1)[0]
    track = np.stack([q, -q, -q, q, -q])[:, None, :]  # (F, 1, 4)
    out = quat.make_continuous(track, axis=0)
    assert np.all(np.sum(out[1:] * out[:-1], axis=-1) > 0)
    assert same_rotation(out[:, 0], track[:, 0])


def test_normalize_zero_gives_identity_and_shape_errors_name_the_argument() -> None:
    np.testing.assert_allclose(quat.normalize(np.zeros((2, 4))), quat.identity((2,)))
    with pytest.raises(ValueError, match=r"Expected `q` to have shape \(\.\.\., 4\), got \(5, 3\)"):
        quat.inv(np.zeros((5, 3)))
    with pytest.raises(ValueError, match="`v`"):
        quat.rotate(quat.identity(), np.zeros((2,)))


def test_float32_in_float32_out() -> None:
    q = rand_quats(1, 8).astype(np.float32)
    assert quat.mul(q, q).dtype == np.float32
    assert quat.rotate(q, np.ones((8, 3), np.float32)).dtype == np.float32
