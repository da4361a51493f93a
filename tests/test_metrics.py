"""Quality metrics on hand-made motions whose answers are known."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core import FOOT_NAMES
from synth_core.motion import quat
from synth_core.motion.skeleton import forward_kinematics
from synth_core.quality import metrics as M
from tests.helpers.motion import TEMPLATES, synthetic_gait, toy_skeleton


def test_a_foot_sliding_3mm_per_frame_measures_3mm() -> None:
    F = 50
    feet = np.zeros((F, 4, 3))
    feet[:, 0, 0] = np.arange(F) * 0.003  # LF slides 3 mm/frame along X
    feet[:, 1, 2] = np.arange(F) * -0.003  # RF slides 3 mm/frame along -Z
    feet[:, 2, 1] = np.arange(F) * 0.01  # LH moves only vertically: no horizontal skate
    contacts = np.zeros((F, 4), bool)
    contacts[:, :3] = True
    contacts[10:20, 3] = True  # RH planted and still
    stats = M.foot_skate(feet, contacts)
    expected_steps = 3 * (F - 1) + 9
    assert stats.steps == expected_steps
    assert stats.mean_mm == pytest.approx((2 * 3.0 * (F - 1)) / expected_steps)
    assert stats.p95_mm == pytest.approx(3.0)
    assert stats.ratio == pytest.approx(2 * (F - 1) / expected_steps)


def test_skate_ignores_swing_frames_and_batches_over_characters() -> None:
    rng = np.random.default_rng(0)
    feet = rng.normal(size=(3, 30, 4, 3))  # wild motion...
    contacts = np.zeros((3, 30, 4), bool)  # ...but never planted
    assert M.foot_skate(feet, contacts).steps == 0
    feet[1, :, 2] = 0.0
    feet[1, :, 2, 0] = np.arange(30) * 0.001
    contacts[1, :, 2] = True
    stats = M.foot_skate(feet, contacts)
    assert stats.mean_mm == pytest.approx(1.0) and stats.steps == 29
    with pytest.raises(ValueError, match="foot_pos"):
        M.foot_skate(feet[..., :2], contacts)


def test_path_error_is_horizontal_distance_in_cm() -> None:
    target = np.zeros((2, 10, 3))
    root = target.copy()
    root[0, :, 2] = 0.01  # 1 cm sideways
    root[1, 4, 0] = 0.05  # 5 cm once
    root[:, :, 1] = 3.0  # height is ignored
    err = M.path_error(root, target)
    assert err.max_cm == pytest.approx(5.0)
    assert err.mean_cm == pytest.approx((10 * 1.0 + 5.0) / 20)


@pytest.mark.parametrize(("gait", "template"), [
    ("walk", [["LH"], ["LF"], ["RH"], ["RF"]]),
    ("trot", [["LH", "RF"], ["RH", "LF"]]),
])
def test_footfall_order_matches_its_own_template_and_not_another(gait: str, template: list) -> None:
    phases, duty = TEMPLATES[gait]
    contacts = synthetic_gait(phases, duty, strides=5)
    assert M.footfall_order(contacts, template) == 1.0
    other = [["LH"], ["RF"], ["RH"], ["LF"]]  # diagonal-sequence walk
    assert M.footfall_order(contacts, other) == 0.0
    # One stride's LF lands late (frame 84, after RH at 80): that stride alone no longer matches.
    if gait == "walk":
        broken = contacts.copy()
        broken[70:84, 0] = False  # column 0 is LF
        assert M.footfall_order(broken, template) == pytest.approx(3 / 4)


def test_footfall_order_pools_characters() -> None:
    phases, duty = TEMPLATES["walk"]
    lateral = synthetic_gait(phases, duty, strides=3)  # two complete strides
    diagonal = synthetic_gait({"LH": 0.0, "RF": 0.25, "RH": 0.5, "LF": 0.75}, duty, strides=3)
    crowd = np.stack([lateral, diagonal])
    assert M.footfall_order(crowd, [["LH"], ["LF"], ["RH"], ["RF"]]) == pytest.approx(0.5)


def test_pop_ratio_flags_a_jump_in_rotation() -> None:
    F, J = 60, 3
    t = np.arange(F) / 60.0
    smooth = quat.from_axis_angle([0, 0, 1], np.sin(2 * np.pi * t))[:, None].repeat(J, 1)
    assert M.pop_ratio(smooth, [30], smooth, fps=60.0) <= 1.0 + 1e-9
    popped = smooth.copy()
    popped[30:, 1] = quat.mul(quat.from_axis_angle([1, 0, 0], 0.3), popped[30:, 1])
    assert M.pop_ratio(popped, [30], smooth, fps=60.0) > 5.0
    # Sign flips of quaternions are not pops.
    flipped = smooth.copy()
    flipped[30:] *= -1
    assert M.pop_ratio(flipped, [30], smooth, fps=60.0) <= 1.0 + 1e-9


def test_penetration_and_bone_length_change() -> None:
    feet = np.zeros((5, 4, 3))
    feet[3, 2, 1] = -0.004
    assert M.penetration_mm(feet) == pytest.approx(4.0)
    assert M.penetration_mm(np.abs(feet)) == 0.0
    skel = toy_skeleton()
    rot = quat.identity((2, skel.n_joints))
    pos, _ = forward_kinematics(skel, np.zeros((2, 3)), rot)
    assert M.bone_length_change(pos, skel).max_mm == pytest.approx(0.0, abs=1e-3)
    stretched = pos.astype(np.float64).copy()
    lower = skel.index("LeftUpLegLower")  # 0.2 m bone; move its child 1 cm further down
    child = skel.index("LeftFoot")
    stretched[1, [child] + [skel.index("LeftFoot_end")], 1] -= 0.01
    change = M.bone_length_change(stretched, skel)
    assert change.max_mm == pytest.approx(10.0, rel=1e-3)
    assert change.max_pct == pytest.approx(5.0, rel=1e-3)
    del lower


def test_a_stride_is_judged_in_phase_whatever_its_tempo() -> None:
    """A rotary gallop whose RH lands 3 frames before the next LH (over the 2-frame window of
    simultaneity): played 6% faster, the pair falls 2 or 3 frames apart by rounding, and
    grouping touchdowns by frames reads a changed order; in phase it is the same stride. A
    foot out of its place, or stepping twice, is still caught."""
    F = 25
    lands = {"LF": 7, "RF": 12, "LH": 3, "RH": 25 + 0}  # RH at frame 0 of the next stride
    clip = np.zeros((F, 4), bool)
    for k, foot in enumerate(FOOT_NAMES):
        f = lands[foot] % F
        clip[(f + np.arange(8)) % F, k] = True
    phases = M.footfall_phases(clip)
    assert phases == {"LF": 4 / 25, "RF": 9 / 25, "LH": 0.0, "RH": 22 / 25}
    t = np.arange(400)
    fast = clip[np.floor(t * 1.06).astype(int) % F]  # the clip played at tempo 1.06
    down = M.touchdowns(fast)
    lh = down[FOOT_NAMES.index("LH")]
    strides = list(zip(lh[:-1], lh[1:], strict=False))
    assert len(strides) > 10
    assert all(M.stride_in_order(down, int(a), int(b), phases, 3.0) for a, b in strides)
    grouped = [g for _, g in M.touchdown_groups(fast, 2)]  # what frame windows make of it
    assert len({frozenset(g) for g in grouped}) > 4  # some strides read [LH, RH] together
    late = fast.copy()
    late[:, FOOT_NAMES.index("RF")] = np.roll(fast[:, FOOT_NAMES.index("RF")], 6)  # RF 6 frames late
    down = M.touchdowns(late)
    assert not any(M.stride_in_order(down, int(a), int(b), phases, 3.0) for a, b in strides[1:-1])


# --- foot-height figures of the edge suite (issue 27) -------------------------------------------

def _sliding_foot(frames: int, step_m: float, height: float = 0.0) -> np.ndarray:
    """(F, 4, 3) feet: LF slides ``step_m`` a frame along X at ``height``; the others stay 1 m up."""
    feet = np.zeros((frames, 4, 3))
    feet[:, 1:, 1] = 1.0
    feet[:, 0, 0] = np.arange(frames) * step_m
    feet[:, 0, 1] = height
    return feet


def test_a_foot_sliding_5mm_per_frame_on_the_ground_skates_5mm_strictly() -> None:
    feet = _sliding_foot(40, 0.005)
    plants = M.strict_plants(M.foot_heights(feet))
    assert plants[:, 0].all() and not plants[:, 1:].any()
    skate = M.foot_skate(feet, plants)
    assert skate.mean_mm == pytest.approx(5.0) and skate.p95_mm == pytest.approx(5.0)


def test_strict_plants_need_three_frames_within_1cm() -> None:
    h = np.full((12, 4), 0.5)
    h[1:3, 0] = 0.0  # two frames: too short
    h[5:8, 0] = 0.009  # three frames within 1 cm: a plant
    h[9:12, 1] = 0.011  # three frames, 1.1 cm up: not within 1 cm
    plants = M.strict_plants(h)
    assert np.flatnonzero(plants[:, 0]).tolist() == [5, 6, 7]
    assert not plants[:, 1:].any()
    assert M.strict_plants(np.zeros((2, 4))).sum() == 0  # shorter than a plant
    crowd = np.stack([h, np.roll(h, 2, axis=0)])  # characters are apart: no run spans them
    assert np.array_equal(M.strict_plants(crowd)[1], np.roll(plants, 2, axis=0))


def test_a_run_cut_off_by_the_end_of_a_motion_is_a_plant_with_open_ends() -> None:
    """A synthesized run stops mid-stride: a foot set down on its second-last frame is not known
    to lift again (the real dog's uturn_walk read as a walk on one paw in its last two frames)."""
    h = np.full((12, 4), 0.5)
    h[0:2, 0] = 0.0  # at the first frame
    h[5:7, 0] = 0.0  # inside: too short either way
    h[10:12, 1] = 0.005  # at the last frame
    assert not M.strict_plants(h).any()
    plants = M.strict_plants(h, open_ends=True)
    assert np.flatnonzero(plants[:, 0]).tolist() == [0, 1]
    assert np.flatnonzero(plants[:, 1]).tolist() == [10, 11]
    assert not plants[:, 2:].any()


def test_a_foot_hangs_while_off_the_ground_on_a_straight_leg() -> None:
    """``longest_hang``: frames in a row a foot is over HANG_UP on a straight thigh and shin; a
    bent leg up high swings, and a straight one on the ground stands."""
    from synth_core.build.ik import limb_rigs
    skel = toy_skeleton()
    rigs = limb_rigs(skel)
    F = 12
    pos = np.zeros((1, F, len(skel.names), 3))
    heights = np.zeros((1, F, 4))
    for f, rig in enumerate(rigs):  # every leg bent at its hinge ...
        pos[0, :, rig.upper] = (f, 1.0, 0.0)
        pos[0, :, rig.hinge] = (f + 0.3, 0.5, 0.0)
        pos[0, :, rig.ankle] = (f, 0.0, 0.0)
    heights[0, :, 1] = 0.2  # ... one of them swinging high
    pos[0, :, rigs[0].hinge] = (0.0, 0.5, 0.0)  # the first straight ...
    heights[0, 3:8, 0] = 0.1  # ... and off the ground for 5 frames
    assert M.longest_hang(pos, skel, heights, np.ones(1)) == 5
    assert M.longest_hang(pos, skel, heights, np.full(1, 3.0)) == 0  # 0.1 m is on the ground at size 3
    heights[0, :, 0] = 0.0
    assert M.longest_hang(pos, skel, heights, np.ones(1)) == 0


def test_glide_weights_speed_by_height_and_divides_by_body_speed() -> None:
    body = np.zeros((40, 3))
    body[:, 2] = np.arange(40) * 0.010  # 10 mm/frame
    on_ground = _sliding_foot(40, 0.005)
    glide = M.near_ground_glide(on_ground, M.foot_heights(on_ground), body)
    assert glide.foot_mm == pytest.approx(5.0) and glide.ratio == pytest.approx(0.5)
    half = _sliding_foot(40, 0.005, height=M.GLIDE_HEIGHT_M / 2)  # weight 2 - 2^0.5
    assert M.near_ground_glide(half, M.foot_heights(half), body).foot_mm == pytest.approx(5 * (2 - 2**0.5))
    above = _sliding_foot(40, 0.005, height=M.GLIDE_HEIGHT_M * 1.01)
    assert M.near_ground_glide(above, M.foot_heights(above), body).frames == 0
    # Standing on the spot: the body's speed is floored, not zero.
    assert np.isfinite(M.near_ground_glide(on_ground, M.foot_heights(on_ground), body * 0).ratio)


def test_a_foot_jumping_10cm_in_one_frame_jumps_10cm_and_a_steady_one_0() -> None:
    feet = _sliding_foot(30, 0.0)
    feet[15:, 0, 2] += 0.10
    assert M.one_frame_jumps_mm(feet).max() == pytest.approx(100.0)
    fast = _sliding_foot(30, 0.20)  # 20 cm a frame, steadily
    assert M.one_frame_jumps_mm(fast).max() == pytest.approx(0.0, abs=1e-9)


def test_touchdown_is_the_step_before_a_strict_plant() -> None:
    feet = _sliding_foot(20, 0.0, height=0.3)
    feet[:10, 0, 1] = np.linspace(0.3, 0.04, 10)  # comes down 2.9 cm a frame...
    feet[10:, 0, 1] = 0.0  # ...then 4 cm in the last frame, and stands
    plants = M.strict_plants(M.foot_heights(feet))
    assert M.touchdown_steps_mm(feet, plants) == pytest.approx([40.0])


def _bent_legs(angles_deg: np.ndarray) -> tuple[np.ndarray, object]:
    """World positions of the toy skeleton with every knee (the joint below the limb root) bent
    by ``angles_deg`` per frame about Z."""
    from tests.helpers.motion import toy_skeleton

    toy = toy_skeleton()
    rot = quat.identity((len(angles_deg), toy.n_joints)).astype(np.float64)
    knees = [f.chain[1] for f in toy.feet]
    rot[:, knees] = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.radians(angles_deg))[:, None]
    pos, _ = forward_kinematics(toy, np.zeros((len(angles_deg), 3)), rot)
    return pos, toy


def test_a_knee_reversing_in_one_frame_is_a_flip_and_a_slow_pass_is_not() -> None:
    flipped, toy = _bent_legs(np.where(np.arange(10) < 5, 30.0, -30.0))
    flips = M.limb_flips(flipped, toy)
    knees = [i for i, (_, j, _) in enumerate(M.hinge_joints(toy)) if j in [f.chain[1] for f in toy.feet]]
    assert flips.sum() == 4 and all(flips[k] == 1 for k in knees)  # one per leg, at its knee
    slow, _ = _bent_legs(np.linspace(30.0, -30.0, 30))  # 2 deg a frame through straight
    assert M.limb_flips(slow, toy).sum() == 0
    # The whole body turning half round in one frame, legs bent as ever: no flip in its frame.
    bent, _ = _bent_legs(np.full(4, 30.0))
    turn = quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), np.radians([0.0, 0.0, 170.0, 170.0]))
    spun = quat.rotate(turn[:, None], bent)
    assert M.limb_flips(spun, toy).sum() > 0  # in the world, every bent joint's axis turned
    assert M.limb_flips(spun, toy, turn).sum() == 0


def test_reach_single_support_floating_and_yaw_rate() -> None:
    pos, toy = _bent_legs(np.zeros(3))
    assert M.limb_reach(pos, toy)[0, 0] == pytest.approx(np.linalg.norm([0.03, -0.45, 0.0]))
    down = np.zeros((10, 4), bool)
    down[:, 1] = True
    down[2:7, 0] = True  # LF joins: RF is no longer alone
    assert M.single_support_frames(down).tolist() == [1, 2, 0, 0, 0, 0, 0, 1, 2, 3]
    heights = np.full((4, 4), 0.2)
    heights[:, 2] = [0.0, 0.03, 0.05, 0.0]
    assert M.floating_m(heights, np.array([0.0, 0.05, 2.0, 0.0])) == pytest.approx(0.03)
    turning = quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), np.radians(np.arange(20) * 1.5))
    assert M.yaw_rates_deg(turning, 60.0) == pytest.approx(np.full(19, 90.0))


def test_path_distance_maps_time_and_ignores_running_ahead_along_the_path() -> None:
    F = 61
    target = np.zeros((F, 3))
    target[:, 2] = np.linspace(0.0, 6.0, F)  # 10 cm a frame along Z
    T = 2 * F - 1  # a clock resampled 2x
    root = np.zeros((T, 3))
    # A stride's surge: up to 5 cm ahead of or behind its time (never past the path's ends)...
    root[:, 2] = np.clip(np.linspace(0.0, 6.0, T) + 0.05 * np.sin(np.arange(T) / 3), 0.0, 6.0)
    root[:, 0] = 0.02  # ...and 2 cm to the side
    root[:, 1] = 1.5  # height does not count
    assert M.path_distance_cm(root, target) == pytest.approx(np.full(T, 2.0), abs=1e-6)
    cut = root.copy()
    cut[60, 0] = 0.07  # 7 cm off the path once
    assert M.path_distance_cm(cut, target).max() == pytest.approx(7.0)
    assert M.mapped_frames(T, F)[[0, 2, -1]] == pytest.approx([0.0, 1.0, F - 1.0])


def test_path_distance_takes_a_surge_past_a_moving_end_as_along_the_path_but_not_past_a_stop() -> None:
    """The target goes on past its ends as it went: a root 3 cm ahead at the last frame of a path
    still moving is on it (the same lead as mid-path), 3 cm past a path that stopped is off it."""
    F = 61
    target = np.zeros((F, 3))
    target[:, 2] = np.linspace(0.0, 6.0, F)
    root = target.copy()
    root[-1, 2] += 0.03
    assert M.path_distance_cm(root, target).max() == pytest.approx(0.0, abs=1e-9)
    stopped = target.copy()
    stopped[-10:, 2] = stopped[-10, 2]  # stands for its last 10 frames
    root = stopped.copy()
    root[-1, 2] += 0.03
    assert M.path_distance_cm(root, stopped).max() == pytest.approx(3.0)


def test_same_pattern_share_is_one_in_lock_step_and_chance_level_out_of_it() -> None:
    rng = np.random.default_rng(0)
    stride = rng.random((40, 4)) < 0.5  # a 40-frame pattern cycle
    lock = np.broadcast_to(stride, (6, 40, 4))
    assert M.same_pattern_share(lock) == pytest.approx(1.0)
    shifted = np.stack([np.roll(stride, 7 * c, axis=0) for c in range(6)])
    pairs = [(a, b) for a in range(6) for b in range(a + 1, 6)]
    looped = np.mean([(shifted[a] == shifted[b]).all(axis=-1).mean() for a, b in pairs])
    assert M.same_pattern_share(shifted) == pytest.approx(looped)
    with pytest.raises(ValueError, match="2 characters"):
        M.same_pattern_share(lock[:1])


def test_a_body_sliding_over_four_planted_feet_drifts_and_one_carrying_them_does_not() -> None:
    F = 30
    feet = np.zeros((F, 4, 3))
    feet[:, :, 0] = [0.5, 0.5, -0.5, -0.5]
    root = np.zeros((F, 3))
    root[:, 2] = np.linspace(0.0, 0.29, F)  # 1 cm a frame over feet that stay
    down = np.ones((F, 4), bool)
    slow = np.ones(F, bool)
    np.testing.assert_allclose(M.stand_drift_m(root, feet, down, slow)[-1], 0.29)
    carried = feet + root[:, None, :]  # the feet go along (a glide, measured apart): no drift
    assert M.stand_drift_m(root, carried, down, slow).max() < 1e-12
    slow[:10] = False  # the run starts where the body is first slow
    np.testing.assert_allclose(M.stand_drift_m(root, feet, down, slow)[-1], 0.29 - 0.1)
    assert M.stand_drift_m(root, feet, down & (np.arange(F) % 2 == 0)[:, None], slow).max() == 0.0


def test_a_foot_is_judged_over_the_standing_heights_of_the_pieces_its_pose_blends() -> None:
    """A paw planted at its trot's standing height (3 cm) stays put as a piece labelled the walk's
    starts (standing 1.5 cm): for the fade's frames after the start the pose is mostly the trot's,
    and the paw reads 0 over it; after them, over the walk's only (1.5 cm). A label changing with
    no piece starting (halfway through a transition) fades nothing."""
    standing = np.array([[[0.0] * 4, [0.015] * 4, [0.03] * 4]])  # (1, labels, 4): static, walk, trot
    labels = np.array([[2, 2, 2, 1, 1, 1, 1, 1]])
    started = np.zeros((1, 8), bool)
    started[0, 3] = True
    heights = np.full((1, 8, 4), 0.03)
    over = M.over_standing(heights, standing, labels, started, fade=3)
    assert np.allclose(over[0, :6], 0.0)  # the trot's frames, then the three after the start
    assert np.allclose(over[0, 6:], 0.015)
    # A foot nearer the walk's height reads over that (the nearest of the pieces blended).
    near = M.over_standing(np.full((1, 8, 4), 0.016), standing, labels, started, fade=3)
    assert near[0, 4, 0] == pytest.approx(0.001)
    unstarted = M.over_standing(heights, standing, labels, np.zeros((1, 8), bool), fade=3)
    assert np.allclose(unstarted[0, 3:], 0.015)
