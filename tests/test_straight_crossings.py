"""A joint passing through straight is slowed to what a skipped clip frame cannot flip
(issue 28; synth_core.build.straight_crossings)."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.build.animals import build_builtin
from synth_core.build.straight_crossings import crossing_times
from synth_core.builtin.clips import build_clips
from tests.helpers.motion import clip_flips

FLIP_BEND_DEG = 15.0  # metrics.limb_flips: bent at least this much one frame, the other way the next


def bends_at(times: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """A hinge's signed bend (deg) at fractional frames, linear between frames."""
    return np.interp(times, np.arange(len(angles)), angles)


def test_a_fast_passage_is_slowed_and_no_skip_straddles_straight() -> None:
    """Shown frame by frame or skipping one clip frame (a stride rate up to 2), no two frames
    are bent 15 deg or more to either side of straight (metrics.limb_flips' flip)."""
    # A wrist from 50 deg one way to 50 the other at 30 deg a frame, about one axis.
    angles = np.clip(np.arange(30) * -30.0 + 400.0, -50.0, 50.0)
    vectors = angles[:, None] * np.array([0.0, 0.0, 1.0])
    times = crossing_times(vectors, cyclic=False)
    shown = bends_at(times, angles)
    crossing = shown[1:] * shown[:-1] < 0
    assert np.abs(np.diff(shown))[crossing].max() < 30.0  # was 30: now slower through straight
    for skip in (1, 2):  # a frame shown, the next or the one after
        a, b = shown[:-skip], shown[skip:]
        assert not np.any((a * b < 0) & (np.abs(a) >= FLIP_BEND_DEG) & (np.abs(b) >= FLIP_BEND_DEG))
    assert np.all(np.diff(times) > 0)  # the joint still moves forward in time
    far = np.abs(np.arange(30) - 400.0 / 30.0) > 5
    assert np.array_equal(times[far], np.arange(30)[far])  # only the passage's frames change


def test_a_slow_passage_is_left_alone() -> None:
    angles = np.linspace(30.0, -30.0, 20)  # 3.2 deg a frame
    times = crossing_times(angles[:, None] * np.array([1.0, 0.0, 0.0]), cyclic=False)
    assert np.array_equal(times, np.arange(20))


def test_a_passage_at_a_lift_off_is_slowed_on_its_swing_side() -> None:
    """A wrist passing through straight 0.7 frame after its flat stance ends (the real dog's
    lift-offs in its transitions: 17-24 deg a frame, left as they were while the window had to be
    symmetric) is slowed over the swing; the flat stance keeps its own timing (a foot flat in
    stance, issue 28)."""
    angles = np.clip(382.0 - 30.0 * np.arange(30), -50.0, 50.0)  # 22 deg at frame 12, -8 at 13
    flat = np.arange(30) <= 12
    times = crossing_times(angles[:, None] * np.array([0.0, 0.0, 1.0]), cyclic=False, flat=flat)
    assert np.array_equal(times[flat], np.arange(30)[flat])
    assert np.all(np.diff(times) > 0)
    shown = bends_at(times, angles)
    a, b = shown[:-1], shown[1:]  # frame by frame: no two frames 15 deg to either side
    assert not np.any((a * b < 0) & (np.abs(a) >= FLIP_BEND_DEG) & (np.abs(b) >= FLIP_BEND_DEG))
    crossing = shown[1:] * shown[:-1] < 0
    assert np.abs(np.diff(shown))[crossing].max() < 30.0 - 1.0  # slower through straight than it was


def test_a_passage_inside_a_stance_begun_in_the_swing_comes_to_the_touchdown_pose() -> None:
    """A fetlock bent 16 deg the frame before touchdown passes through straight over the stance's
    first two frames (the horse's gallop: 16.4, 0.9, -19.8): no window fits beside the flat
    stance, so frames shown either side of the touchdown straddle straight. Its swing side is
    eased toward the touchdown's pose; the stance keeps its timing."""
    angles = np.array([45.0, 40, 35, 30.4, 24.4, 21.0, 16.4, 0.9, -19.8, -36.8, -50.1, -55, -58, -60])
    flat = np.arange(len(angles)) >= 7
    times = crossing_times(angles[:, None] * np.array([1.0, 0.0, 0.0]), cyclic=False, flat=flat)
    assert np.array_equal(times[flat], np.arange(len(angles))[flat])
    assert np.all(np.diff(times) > 0)
    shown = bends_at(times, angles)
    for skip in (1, 2):
        a, b = shown[:-skip], shown[skip:]
        assert not np.any((a * b < 0) & (np.abs(a) >= FLIP_BEND_DEG) & (np.abs(b) >= FLIP_BEND_DEG)), skip
    assert np.array_equal(times[:2], [0.0, 1.0])  # eased over a few frames only


@pytest.mark.parametrize("animal", ["horse", "dog"])
def test_the_built_in_transitions_flip_no_joint_played_twice_as_fast(animal: str) -> None:
    """A transition is played by distance, at up to twice its clip's rate (a dog accelerating
    through walk -> trot in the low-latency mode: 1.85): shown skipping a clip frame, no joint
    flips (metrics.limb_flips). The built-in dog's toes passed through straight at 16-19 deg a
    clip frame at its transitions' lift-offs (6 flips; in the low-latency edge suite a toe flipped
    in 7 scenarios). Its stances stay as generated: its feet are not moved where planted."""
    library, generated = build_builtin(animal), build_clips(animal)
    flips = clip_flips(library, 2)
    assert not any(flips[name] for name in library.transitions), flips
    for name, motion in library.transitions.items():
        feet = np.asarray(motion.positions(), np.float64)[:, motion.skeleton.foot_joints]
        before = np.asarray(generated[name].positions(), np.float64)[:, motion.skeleton.foot_joints]
        assert np.abs(feet - before)[motion.contacts].max() < 1e-5, name


def test_the_built_in_horses_clips_flip_no_joint_played_twice_as_fast() -> None:
    """A small or too-fast horse plays its canter and gallop faster than their clips (a Froude
    tempo of 1 / sqrt(h), up to MAX_RATE 1.6): shown skipping a clip frame, no joint flips. The
    hind fetlock, bent 16 deg in the gallop's last swing frame and loaded through straight over
    the stance's first two, flipped once in every canter and gallop clip (120; the edge suite's
    too_fast: 2 flips). (The dog's fastest gallop clips still flip a fore toe loaded inside the
    stance, begun there: nothing in its swing to ease.)"""
    flips = clip_flips(build_builtin("horse"), 2)
    assert not any(flips.values()), flips
