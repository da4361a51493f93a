"""Quality metrics on hand-made motions whose answers are known."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core import FOOT_NAMES, quat
from synth_core import metrics as M
from synth_core.skeleton import forward_kinematics
from tests.conftest import toy_skeleton
from tests.test_contacts import TEMPLATES, synthetic_gait


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


@pytest.mark.parametrize("gait, template", [
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
