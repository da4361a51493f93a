"""Limb IK (paper Fig. 5): reach, no hinge flip, ground, stretch only when needed, batching."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.build import ik
from synth_core.builtin.clips import build_clips
from synth_core.motion import bvh, quat
from synth_core.motion.clip import Motion
from synth_core.motion.skeleton import forward_kinematics
from tests.helpers.mocap import mann_path

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


def twisted_leg(frames: int = 80, peak_deg: float = 150.0) -> tuple[Motion, np.ndarray]:
    """The toy's left hind leg bent 60 deg, its bend plane turned about the thigh for a stretch
    of frames (a paw lifted out to the side while turning) up to ``peak_deg`` from the body's
    side and back; the rest of the clip it bends straight to the side. Returns the motion and
    the twist per frame (deg)."""
    from tests.helpers.motion import toy_skeleton

    skeleton = toy_skeleton()
    rig = ik.limb_rigs(skeleton)[2]
    t = np.arange(frames)
    stretch = (t >= 20) & (t < 50)
    twist = np.where(stretch, peak_deg * np.sin(np.pi * (t - 20) / 30), 0.0)
    rotations = np.tile(quat.identity(), (frames, skeleton.n_joints, 1))
    rotations[:, rig.upper] = quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), np.radians(twist))
    rotations[:, rig.hinge] = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.radians(60.0))
    root = np.tile([0.0, 0.5, 0.0], (frames, 1))
    return Motion(skeleton, root, rotations, 60.0), twist


def hinge_axes_world(motion: Motion, rotations: np.ndarray, rig: ik.LimbRig) -> np.ndarray:
    pos, _ = forward_kinematics(motion.skeleton, motion.root_pos, rotations)
    return np.cross(pos[:, rig.hinge] - pos[:, rig.upper], pos[:, rig.ankle] - pos[:, rig.hinge])


def test_a_bend_plane_turned_past_the_side_keeps_its_hinge_side_over_time() -> None:
    """Signing each frame's hinge axis by the limb's dominant bend alone bends the knee the other
    way wherever the plane has turned more than 90 deg from it: a flip in and a flip out (the real
    dog's foreleg knotted at shoulder height). The axes kept continuous over time do not flip,
    and the leg stays as the source posed it (its toe targets 2 cm above the source's)."""
    motion, twist = twisted_leg()
    rig = ik.limb_rigs(motion.skeleton)[2]
    targets = motion.foot_positions().astype(np.float64) + [0.0, 0.02, 0.0]

    def flips(rotations: np.ndarray) -> int:
        axis = hinge_axes_world(motion, rotations, rig)
        return int(np.sum(np.sum(axis[1:] * axis[:-1], axis=-1) < 0))

    assert flips(motion.rotations) == 0  # the source turns smoothly
    today = ik.solve(motion.skeleton, motion.root_pos, motion.rotations, targets, ground=None)
    assert flips(today.rotations) >= 2  # the per-frame rule flips in and out of the stretch

    axes = ik.hinge_axes_over_time(motion.skeleton, motion.rotations)
    result = ik.solve(motion.skeleton, motion.root_pos, motion.rotations, targets, ground=None, axes=axes)
    assert flips(result.rotations) == 0 and not result.wrong_side.any()
    assert np.linalg.norm(toes(motion, result.rotations) - targets, axis=-1).max() < 1e-4
    pos, _ = forward_kinematics(motion.skeleton, motion.root_pos, result.rotations)
    source, _ = forward_kinematics(motion.skeleton, motion.root_pos, motion.rotations)
    assert np.linalg.norm(pos[:, rig.hinge] - source[:, rig.hinge], axis=-1).max() < 0.03
    assert np.linalg.norm(np.diff(pos[:, rig.hinge], axis=0), axis=-1).max() < 0.03  # no jump
    assert twist.max() > 140  # the stretch does turn past the side


def test_a_one_frame_reversal_in_the_source_is_turned_back() -> None:
    """A mocap glitch: the knee bent the wrong way for one frame. The axis of that frame is
    turned back to its neighbours' side (the IK then bends the knee their way)."""
    motion, _ = twisted_leg(peak_deg=0.0)
    rig = ik.limb_rigs(motion.skeleton)[2]
    rotations = motion.rotations.copy()
    rotations[30, rig.hinge] = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.radians(-40.0))
    axes = ik.hinge_axes_over_time(motion.skeleton, rotations)[:, 2]
    assert np.all(axes[:, 2] > 0.99)  # every frame bends about +Z, the glitch's included


def test_a_looped_sequence_is_continuous_across_its_seam() -> None:
    motion, _ = twisted_leg()
    plain = ik.hinge_axes_over_time(motion.skeleton, motion.rotations, cyclic=True)
    for shift in (35, 45):  # the turned stretch runs over the loop's end
        rolled = np.roll(motion.rotations, -shift, axis=0)
        looped = ik.hinge_axes_over_time(motion.skeleton, rolled, cyclic=True)
        assert np.allclose(looped, np.roll(plain, -shift, axis=0), atol=1e-9)


def test_mend_flips_blends_flipped_frames_from_their_good_neighbours() -> None:
    motion, _ = twisted_leg(frames=10, peak_deg=0.0)
    rigs = ik.limb_rigs(motion.skeleton)
    rig = rigs[2]
    angles = np.radians(np.arange(10) * 10.0)
    rotations = motion.rotations.copy()
    rotations[:, rig.hinge] = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), angles)
    wrong = np.zeros((10, 4), bool)
    wrong[[4, 5], 2] = True
    rotations[[4, 5], rig.hinge] = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.radians(-70.0))
    mended = ik.mend_flips(rotations, wrong, rigs)
    got = np.degrees(2 * np.arctan2(mended[:, rig.hinge, 2], mended[:, rig.hinge, 3]))
    assert np.allclose(got, np.arange(10) * 10.0, atol=0.5)  # 30 .. 60 deg: nlerp of 30 and 60
    untouched = [j for j in range(motion.skeleton.n_joints) if j not in (rig.upper, rig.hinge, rig.ankle)]
    assert np.array_equal(mended[:, untouched], rotations[:, untouched])
    wrong[:, 2] = False
    wrong[[0, 9], 2] = True  # looped: frame 0 and 9 sit between frames 8 and 1
    looped = ik.mend_flips(rotations, wrong, rigs, cyclic=True)
    got = np.degrees(2 * np.arctan2(looped[[9, 0], rig.hinge, 2], looped[[9, 0], rig.hinge, 3]))
    assert np.allclose(got, [80 - 70 / 3, 80 - 2 * 70 / 3], atol=3.0)  # from frame 8 on to frame 1
