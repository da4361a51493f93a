"""Skeleton validation, feet, and batched forward kinematics."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from synth_core import FOOT_NAMES
from synth_core.motion import quat
from synth_core.motion.skeleton import Skeleton, forward_kinematics, guess_feet
from tests.helpers.motion import random_motion, toy_skeleton


def test_fk_of_a_bent_chain_is_known() -> None:
    skel = Skeleton(("a", "b", "c"), np.array([-1, 0, 1]), np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0]]))
    rot = quat.identity((3,), np.float64)
    rot[1] = quat.from_axis_angle([0, 0, 1], np.pi / 2)  # bend at b: c goes up
    pos, grot = forward_kinematics(skel, np.array([0.0, 2.0, 0.0]), rot)
    np.testing.assert_allclose(pos, [[0, 2, 0], [1, 2, 0], [1, 3, 0]], atol=1e-12)
    np.testing.assert_allclose(quat.angle(grot[2]), np.pi / 2)


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**31))
def test_batched_fk_equals_looped_single_calls(seed: int) -> None:
    rng = np.random.default_rng(seed)
    skel = toy_skeleton()
    crowd = [random_motion(rng, frames=7, skeleton=skel) for _ in range(5)]
    root = np.stack([m.root_pos for m in crowd])  # (C, F, 3)
    rot = np.stack([m.rotations for m in crowd])  # (C, F, J, 4)
    batched, _ = forward_kinematics(skel, root, rot)
    for c, m in enumerate(crowd):
        for f in range(m.n_frames):
            single, _ = forward_kinematics(skel, m.root_pos[f], m.rotations[f])
            np.testing.assert_allclose(batched[c, f], single, atol=1e-6)


def test_fk_with_per_character_offsets_scales_the_body() -> None:
    rng = np.random.default_rng(0)
    m = random_motion(rng, frames=5)
    scales = np.array([0.5, 1.0, 2.0])[:, None, None]
    offsets = m.skeleton.offsets[None] * scales  # (C, J, 3)
    pos, _ = forward_kinematics(m.skeleton, np.zeros((1, m.n_frames, 3)), m.rotations[None],
                                offsets=offsets[:, None])
    base, _ = forward_kinematics(m.skeleton, np.zeros(3), m.rotations)
    np.testing.assert_allclose(pos, base[None] * scales[:, None], atol=1e-5)


def test_invalid_skeletons_are_rejected_with_clear_errors() -> None:
    with pytest.raises(ValueError, match="topological"):
        Skeleton(("a", "b"), np.array([-1, 1]), np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"Expected `offsets` to have shape \(2, 3\)"):
        Skeleton(("a", "b"), np.array([-1, 0]), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="unique"):
        Skeleton(("a", "a"), np.array([-1, 0]), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="finite"):
        Skeleton(("a", "b"), np.array([-1, 0]), np.array([[0, 0, 0], [np.nan, 0, 0]]))
    with pytest.raises(KeyError, match="nope"):
        toy_skeleton().index("nope")
    with pytest.raises(ValueError, match="missing"):
        toy_skeleton().with_feet({"LF": "LeftHand_end"})


def test_feet_chains_and_leg_length(toy: Skeleton) -> None:
    assert [f.name for f in toy.feet] == list(FOOT_NAMES)
    lf = toy.feet[0]
    assert [toy.names[j] for j in lf.chain] == ["LeftArm", "LeftArmLower", "LeftHand", "LeftHand_end"]
    rh = toy.feet[3]
    assert [toy.names[j] for j in rh.chain] == ["RightUpLeg", "RightUpLegLower", "RightFoot",
                                                "RightFoot_end"]
    # Each leg: 0.2 + 0.2 + |(0.03, -0.05, 0)|.
    assert toy.leg_length() == pytest.approx(0.4 + np.hypot(0.03, 0.05), rel=1e-6)


def test_guess_feet_reads_common_names(toy: Skeleton) -> None:
    assert guess_feet(toy) == {"LF": "LeftHand_end", "RF": "RightHand_end",
                               "LH": "LeftFoot_end", "RH": "RightFoot_end"}
    bare = Skeleton(("root", "a", "b"), np.array([-1, 0, 0]), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="pass the four end-effector joint names"):
        guess_feet(bare)
