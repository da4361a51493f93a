"""Limb IK (paper Fig. 5): reach, no hinge flip, ground, stretch only when needed, batching."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core import bvh, ik, quat
from synth_core.library.clips import build_clips
from synth_core.motion import Motion
from synth_core.skeleton import forward_kinematics
from tests.conftest import mann_path

_X = np.array([1.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def trot() -> Motion:
    return build_clips("horse")["trot"]


def toes(motion: Motion, rotations: np.ndarray, offsets: np.ndarray | None = None) -> np.ndarray:
    pos, _ = forward_kinematics(motion.skeleton, motion.root_pos, rotations, offsets)
    return np.asarray(pos[..., motion.skeleton.foot_joints, :], dtype=np.float64)


def test_reachable_targets_are_reached_within_a_tenth_of_a_millimetre(trot: Motion) -> None:
    rng = np.random.default_rng(0)
    source = trot.foot_positions().astype(np.float64)
    targets = source + rng.uniform(-0.06, 0.06, source.shape) * [1.0, 0.0, 1.0]
    result = ik.solve(trot.skeleton, trot.root_pos, trot.rotations, targets)
    assert np.all(result.stretch == 1.0) and np.all(result.miss == 0.0)
    error_mm = np.linalg.norm(toes(trot, result.rotations) - targets, axis=-1).max() * 1000
    assert error_mm < 0.1


def test_only_upper_hinge_and_ankle_turn_distal_angles_are_kept(trot: Motion) -> None:
    targets = trot.foot_positions() + np.array([0.0, 0.0, 0.05])
    result = ik.solve(trot.skeleton, trot.root_pos, trot.rotations, targets)
    rigs = ik.limb_rigs(trot.skeleton)
    changed = {j for r in rigs for j in (r.upper, r.hinge, r.ankle)}
    kept = [j for j in range(trot.skeleton.n_joints) if j not in changed]
    same = np.abs(quat.dot(result.rotations[:, kept], trot.rotations[:, kept]))
    assert np.all(same > 1 - 1e-6)  # girdle, carpus, hock, fetlock: source angles


def test_unreachable_targets_stretch_by_the_reported_factor_and_only_then(trot: Motion) -> None:
    skeleton = trot.skeleton
    targets = trot.foot_positions().astype(np.float64)
    far = targets.copy()
    far[:, 0, 2] += 1.5  # the left fore hoof 1.5 m ahead: beyond any horse leg
    result = ik.solve(skeleton, trot.root_pos, trot.rotations, far)
    assert np.all(result.stretch[:, 0] > 1.05) and np.all(result.miss[:, 0] > 0.05)
    assert np.all(result.stretch[:, 1:] == 1.0)  # the others reach: no stretch
    offsets = ik.stretched_offsets(skeleton, ik.limb_rigs(skeleton), result.stretch)
    error_mm = np.linalg.norm(toes(trot, result.rotations, offsets) - far, axis=-1).max() * 1000
    assert error_mm < 0.1


def leg_bend(motion: Motion, rotations: np.ndarray, rig: ik.LimbRig) -> np.ndarray:
    """Signed bend (deg) of the hinge about the body's lateral (+X) axis, per frame."""
    pos, _ = forward_kinematics(motion.skeleton, motion.root_pos, rotations)
    thigh = pos[:, rig.hinge] - pos[:, rig.upper]
    shin = pos[:, rig.ankle] - pos[:, rig.hinge]
    return np.degrees(np.arctan2(np.cross(thigh, shin) @ _X, np.sum(thigh * shin, axis=-1)))


def test_no_hinge_flip_when_the_source_leg_is_nearly_straight(trot: Motion) -> None:
    """A fast gait's nearly straight leg wobbles through straight in the source; thigh x shin then
    flips sign frame to frame. The solved bend must keep one side and change smoothly."""
    skeleton = trot.skeleton
    rig = ik.limb_rigs(skeleton)[2]  # left hind: femur, tibia (stifle bends forward)
    F = 60
    pose = np.repeat(trot.rotations[:1], F, axis=0).astype(np.float64)
    root = np.repeat(trot.root_pos[:1], F, axis=0)
    # Straighten the stifle (shin in line with the thigh), then wobble it +-2 deg about straight.
    pos, rot = forward_kinematics(skeleton, root, pose)
    straighten = quat.between(pos[:, rig.ankle] - pos[:, rig.hinge], pos[:, rig.hinge] - pos[:, rig.upper])
    wobble = quat.from_axis_angle(_X, np.radians(2.0 * np.sin(np.linspace(0, 6 * np.pi, F))))
    hinge_world = quat.mul(wobble, quat.mul(straighten, rot[:, rig.hinge]))
    pose[:, rig.hinge] = quat.mul(quat.inv(rot[:, rig.upper]), hinge_world)
    source = Motion(skeleton, root, pose, 60.0)
    source_bend = leg_bend(source, pose, rig)
    assert source_bend.min() < -1.0 and source_bend.max() > 1.0  # the source does flip
    # Targets 8 cm closer to the hip than the straight leg reaches: the leg must bend 20-odd deg.
    feet = source.foot_positions().astype(np.float64)
    targets = feet.copy()
    targets[:, 2, 1] += 0.08
    result = ik.solve(skeleton, root, pose, targets, ground=None)
    bend = leg_bend(source, result.rotations, rig)
    assert np.all(np.abs(bend) > 10.0)
    assert np.all(np.sign(bend) == np.sign(bend[0])), "the hinge flipped side"
    assert np.abs(np.diff(bend)).max() < 1.0  # no pop
    assert np.linalg.norm(toes(source, result.rotations) - targets, axis=-1).max() < 1e-4


def test_target_passing_through_full_extension_keeps_the_bend_side(trot: Motion) -> None:
    skeleton = trot.skeleton
    rig = ik.limb_rigs(skeleton)[0]  # left fore
    F = 80
    pose = np.repeat(trot.rotations[:1], F, axis=0)
    root = np.repeat(trot.root_pos[:1], F, axis=0)
    source = Motion(skeleton, root, pose, 60.0)
    feet = source.foot_positions().astype(np.float64)
    targets = feet.copy()
    targets[:, 0, 1] -= 0.25 * np.sin(np.linspace(0, np.pi, F))  # down 25 cm (past full reach) and back
    result = ik.solve(skeleton, root, pose, targets, ground=None)
    bend = leg_bend(source, result.rotations, rig)
    assert np.all(np.sign(bend[np.abs(bend) > 0.5]) == np.sign(bend[0]))
    beyond = result.stretch[:, 0] > 1.0
    assert beyond.any() and not beyond.all()  # stretched only while out of reach
    assert np.all(result.miss[~beyond, 0] == 0.0)


def test_ankle_and_toe_stay_above_the_ground(trot: Motion) -> None:
    skeleton = trot.skeleton
    rigs = ik.limb_rigs(skeleton)
    targets = trot.foot_positions().astype(np.float64)
    targets[..., 1] = -0.05  # asked to go 5 cm under the ground
    # Tip every hoof toe-up by 100 deg: kept as is, the ankle would end up under the toe.
    pose = trot.rotations.astype(np.float64).copy()
    for rig in rigs:
        pose[:, rig.ankle] = quat.mul(pose[:, rig.ankle], quat.from_axis_angle(_X, np.radians(-100.0)))
    result = ik.solve(skeleton, trot.root_pos, pose, targets)
    pos, _ = forward_kinematics(skeleton, trot.root_pos, result.rotations)
    for rig in rigs:
        assert pos[:, rig.effector, 1].min() > -1e-4
        assert pos[:, rig.ankle, 1].min() > -1e-4


def test_batched_over_clips_equals_one_clip_at_a_time(trot: Motion) -> None:
    rng = np.random.default_rng(1)
    feet = trot.foot_positions().astype(np.float64)
    targets = np.stack([feet + rng.uniform(-0.05, 0.05, feet.shape) * [1, 0, 1] for _ in range(3)])
    roots = np.stack([trot.root_pos] * 3)
    rots = np.stack([trot.rotations] * 3)
    batched = ik.solve(trot.skeleton, roots, rots, targets)
    for c in range(3):
        one = ik.solve(trot.skeleton, trot.root_pos, trot.rotations, targets[c])
        assert np.allclose(batched.rotations[c], one.rotations, atol=1e-6)
        assert np.allclose(batched.stretch[c], one.stretch)


def test_rigs_of_the_built_in_horse_and_the_real_dog() -> None:
    horse = build_clips("horse")["walk"].skeleton
    names = {r.foot: (horse.names[r.upper], horse.names[r.hinge]) for r in ik.limb_rigs(horse)}
    assert names["LF"] == ("L_Humerus", "L_Radius") and names["RH"] == ("R_Femur", "R_Tibia")
    dog = bvh.read(mann_path("D1_009_KAN01_002"))
    names = {r.foot: (dog.skeleton.names[r.upper], dog.skeleton.names[r.hinge])
             for r in ik.limb_rigs(dog.skeleton)}
    assert names["LF"] == ("LeftArm", "LeftForeArm") and names["LH"] == ("LeftUpLeg", "LeftLeg")
    with pytest.raises(ValueError, match=r"ik\.LF: 'Head' is not on the leg"):
        ik.limb_rigs(dog.skeleton, {"LF": "Head"})


def test_sinking_the_root_by_the_reported_amount_brings_far_targets_into_reach(trot: Motion) -> None:
    targets = trot.foot_positions().astype(np.float64) + np.array([0.0, 0.0, 0.25])  # far ahead
    assert ik.solve(trot.skeleton, trot.root_pos, trot.rotations, targets).stretch.max() > 1.0
    limit = np.full(4, 0.99)
    sink = ik.sink_to_reach(trot.skeleton, trot.root_pos, trot.rotations, targets, limit)
    assert sink.shape == (trot.n_frames,) and sink.max() > 0.0 and sink.min() >= 0.0
    lowered = trot.root_pos - sink[:, None] * np.array([0.0, 1.0, 0.0])
    result = ik.solve(trot.skeleton, lowered, trot.rotations, targets)
    assert np.all(result.stretch == 1.0)
    assert np.all(ik.extension(trot.skeleton, lowered, result.rotations) <= limit + 1e-6)
    # Sinking further than needed is never asked for: 2 mm less and some leg is short again.
    higher = lowered + np.array([0.0, 0.002, 0.0]) * (sink > 0)[:, None]
    over = ik.extension(trot.skeleton, higher, ik.solve(trot.skeleton, higher, trot.rotations,
                                                        targets).rotations)
    assert np.any(over > limit + 1e-6)
