"""The delta rotation encoding (api_schemas.delta) and the levels of detail (synth_core.motion.lod),
without a service: round trips, the compiled encoder against the same code run as Python, the
world error after FK within the 0.1 mm budget and the size within 2 bytes per joint-frame on
motion the synthesis makes (horse and dog, a herd and edge scenarios), refusals of bad streams."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from api_schemas import delta
from api_schemas.wire import WireError, decode_rotations, rotation_angle, rotations_of
from bench.bench_wire import errors
from synth_core.build.library_store import builtin_library
from synth_core.build.motion_graph import HUBS
from synth_core.motion.lod import detail_joints
from synth_core.motion.skeleton import forward_kinematics
from synth_core.quality import edge, evaluate
from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.synthesis import Options, Result, synthesize


def unit(q: np.ndarray) -> np.ndarray:
    return np.asarray(q / np.linalg.norm(q, axis=-1, keepdims=True), np.float32)


@pytest.fixture(scope="module", params=["horse", "dog"])
def animal(request: pytest.FixtureRequest) -> tuple[Bank, list[Result]]:
    """A library, a small herd's motion and two edge scenarios' (a stop-and-go and a zig-zag)."""
    bank = build_bank(builtin_library(request.param))
    paths = crowd.simulate(12, 300, seed=7, top=evaluate.crowd_top_speed(bank))
    motions = [synthesize(bank, paths, options=Options(seed=7))]
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    for sc in edge.scenarios(gaits, bank.fps, 3, ["stop_go", "zigzag"]):
        motions.append(synthesize(bank, sc.positions, bank.fps, scales=sc.scales, options=Options(seed=3)))
    return bank, motions


def test_synthesized_motion_is_within_a_tenth_of_a_mm_at_two_bytes(animal: tuple[Bank, list[Result]]) -> None:
    bank, motions = animal
    sk = bank.skeleton
    size = count = 0
    for result in motions:
        codes = delta.joint_steps(sk.parents, sk.offsets, result.scales)
        for step in (1, 2):  # 60 fps, and every other frame (a 30 fps stream) in 28-frame chunks
            q = result.rotations[:, ::step]
            cut = q.shape[1] if step == 1 else 28
            for a in range(0, q.shape[1], cut):
                buf, starts = delta.encode(q[:, a:a + cut], codes)
                back = np.stack(delta.decode(buf))
                root = result.root_pos[:, ::step][:, a:a + cut]
                err = errors(sk, root, q[:, a:a + cut], back, result.scales)
                assert err.max() <= 0.1, err.max()  # every joint, hooves included: the budget
                assert len(starts) == len(q) + 1 and starts[-1] == len(buf)
                size += len(buf)
                count += q[:, a:a + cut, :, 0].size
    assert size / count <= 2.0, size / count


def test_compiled_encoder_gives_the_python_encoders_bytes(animal: tuple[Bank, list[Result]]) -> None:
    bank, motions = animal
    q = motions[1].rotations[:3, :50]
    codes = delta.joint_steps(bank.skeleton.parents, bank.skeleton.offsets, motions[1].scales[:3])
    compiled, starts = delta.encode(q, codes)
    reference, ref_starts = delta.encode(q, codes, compiled=False)
    assert np.array_equal(compiled, reference) and np.array_equal(starts, ref_starts)


@settings(max_examples=40, deadline=None)
@given(frames=st.integers(0, 40), joints=st.integers(1, 5), smooth=st.booleans(), code=st.integers(40, 216),
       seed=st.integers(0, 2**32 - 1))
def test_any_rotations_round_trip_within_the_step(frames: int, joints: int, smooth: bool, code: int,
                                                  seed: int) -> None:
    """Random tracks -- smooth, or jumping anywhere each frame (escaped residuals) -- at any step,
    q and -q alike: the rotation comes back within step * sqrt(3) / 2."""
    rng = np.random.default_rng(seed)
    if smooth:
        walk = np.cumsum(rng.normal(0, 0.05, (2, frames, joints, 4)), 1)
        q = unit(rng.normal(size=(2, 1, joints, 4)) + walk)
    else:
        q = unit(rng.normal(size=(2, frames, joints, 4)))
    q *= rng.choice([-1, 1], (2, frames, joints, 1)).astype(np.float32)
    codes = np.full(joints, code, np.uint8)
    buf, _ = delta.encode(q, codes)
    back = decode_rotations(buf, "delta")
    assert back.shape == (2, frames, joints, 4) or frames == 0
    if frames:
        step = 2.0 ** (-code / 8)
        # the float32 of the rebuilt quaternion adds ~1e-7 rad
        assert rotation_angle(q, back).max() <= step * np.sqrt(3) / 2 + 2e-6


def test_a_cut_or_altered_stream_is_refused_not_misread(animal: tuple[Bank, list[Result]]) -> None:
    bank, motions = animal
    q = motions[0].rotations[:2, :30]
    buf, starts = delta.encode(q, delta.joint_steps(bank.skeleton.parents, bank.skeleton.offsets))
    with pytest.raises(WireError, match="rotations"):
        decode_rotations(buf[:-5], "delta")
    bad = buf.copy()
    bad[0] = 9  # another version
    with pytest.raises(WireError, match="version 9"):
        decode_rotations(bad, "delta")
    rot = {"encoding": "delta", "dtype": "|u1", "shape": [len(buf)], "data": buf.tobytes(),
           "decoded_shape": [3, 30, 4]}
    with pytest.raises(WireError, match="decoded_shape"):
        rotations_of(rot)


def test_leaf_joints_get_coarser_steps_than_the_shoulder(animal: tuple[Bank, list[Result]]) -> None:
    bank, _ = animal
    sk = bank.skeleton
    codes = delta.joint_steps(sk.parents, sk.offsets)
    foot = int(sk.foot_joints[0])
    chain = sk.feet[0].chain
    assert codes[chain[0]] > codes[foot]  # finer (a larger code) at the limb's root
    assert (delta.joint_steps(sk.parents, sk.offsets, 2.0) >= codes).all()  # a bigger animal: finer


def test_legs_and_spine_place_the_feet_as_the_full_motion(animal: tuple[Bank, list[Result]]) -> None:
    """What legs_spine leaves out (head, neck, tail) moves no foot: FK at the feet is the same."""
    bank, motions = animal
    sk, result = bank.skeleton, motions[0]
    joints = detail_joints(sk, "legs_spine")
    assert len(joints) < sk.n_joints and set(sk.foot_joints.tolist()) <= set(joints.tolist())
    reduced = np.zeros_like(result.rotations)
    reduced[..., 3] = 1.0
    reduced[:, :, joints] = result.rotations[:, :, joints]
    full, _ = forward_kinematics(sk, result.root_pos, result.rotations)
    lod, _ = forward_kinematics(sk, result.root_pos, reduced)
    np.testing.assert_allclose(lod[:, :, sk.foot_joints], full[:, :, sk.foot_joints], atol=1e-6)
    assert np.abs(lod - full).max() > 1e-3  # and it does leave something out
    assert len(detail_joints(sk, "root_gait")) == 0 and len(detail_joints(sk, "full")) == sk.n_joints
