"""No hoof jumps more than issue 27's 6 cm in one frame after FK (metrics.one_frame_jumps_mm: a
step longer than the mean of the steps before and after it), in horse edge scenarios whose
stitches jumped it: a held transition fading out, a frame skipped at a contact change, settling
pinning a raised hoof (docs/stitch_jumps.md). The foot lock eases a target's one-frame jump into
a ramp over the swing frames around it (jump_kernels.ease_jumps).

Before it (main at 8b8a386) these read 8.31 (cruise_straight), 9.99 (uturn_canter), 12.16
(uturn_gallop) and 12.98 cm (mixed_sizes, scales 0.5-2.0); too_fast (a gallop past its clips'
rate: a touchdown slowing faster than a ramp eases) 7.08 cm before the retime after a ramp
(main at f553fef)."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.build.library_store import builtin_library
from synth_core.quality import evaluate
from synth_core.runtime.bank import Bank, build_bank

JUMP_TARGET_CM = 6.0  # issue 27: one-frame jump, after FK
SKATE_TARGET_MM = 3.0  # issue 27: strict plant skate p95 (planted frames are never moved)


@pytest.fixture(scope="module")
def horse() -> Bank:
    return build_bank(builtin_library("horse"))


@pytest.mark.parametrize("name", ["cruise_straight", "uturn_canter", "uturn_gallop", "mixed_sizes",
                                  "too_fast"])
def test_no_hoof_jumps_past_the_target_in_one_frame(horse: Bank, name: str) -> None:
    out = evaluate.edge_suite(horse, names=[name])["scenarios"][name]["figures"]
    assert out["jump_cm_max"] <= JUMP_TARGET_CM
    assert out["strict_skate_mm_p95"] <= SKATE_TARGET_MM


LL_SKATE_LIMIT_MM = 5.0  # issue 31: the low-latency mode's strict plant skate p95
LL_LATENCY_MS = 100.0  # the low-latency edge suite's budget (quadsynth eval --live low_latency)


@pytest.mark.parametrize(("animal", "name"), [("dog", "jitter_10hz"), ("horse", "moving_start"),
                                             ("horse", "uturn_canter"), ("horse", "cruise_straight")])
def test_no_foot_jumps_past_the_target_in_the_low_latency_mode(horse: Bank, animal: str, name: str) -> None:
    """The low-latency live mode eases the jumps of its frames not sent yet from the targets sent
    (jump_kernels.ease_unsent), and a ramp lowers no swing frame still moving over the ground
    to near its plants' height (jump_kernels._ramp): the dog's jitter_10hz, whose last swing
    frames before a touchdown it lowered under the strict-plant height, skated 6.6 mm (p95).
    On main at e2f3035 these read 10.07 cm (dog jitter_10hz) and 7.49 cm (horse moving_start);
    the horse's uturn_canter 6.2 cm on f553fef, before a swing a ramp leaves jumping is retimed;
    its cruise_straight 6.58 cm on 6574919, before a window carried the offset of the frame sent
    into its first frames (jump_kernels._carry: each window began again from its own targets)."""
    bank = horse if animal == "horse" else build_bank(builtin_library(animal))
    out = evaluate.edge_suite(bank, names=[name], live=True, latency_ms=LL_LATENCY_MS)["scenarios"][name]
    assert out["figures"]["jump_cm_max"] <= JUMP_TARGET_CM
    assert out["figures"]["strict_skate_mm_p95"] <= LL_SKATE_LIMIT_MM


def test_a_swing_too_short_for_its_distance_is_retimed_not_left_jumping() -> None:
    """A start from a stand played fast (the low-latency horse's every gait start, main c089b29:
    7.02 cm after FK) is a swing of 3 frames over 53 cm stepping 10 20 19 4 cm: two long steps
    side by side, so no ramp of one step's excess makes room (each leaves the other as long).
    The swing's progress along its own path is reshaped instead (jump_kernels._retime): no step
    then jumps past the ease bound (JUMP_EASE: half issue 27's 6 cm, the rest for after the
    targets), the plants are not moved, the foot stays on its path and never steps back; a
    frame at either end still skimming the ground is not sped up (it would read as a plant
    skating: issue 27's strict skate)."""

    from synth_core.compiled.jump_kernels import ease_jumps
    from synth_core.quality.metrics import one_frame_jumps_mm
    from synth_core.runtime.footlock import JUMP_EASE

    steps = np.array([0, 0, 0, 0, 0, 0, 0, 9.9, 19.7, 19.4, 4.3, 0, 0, 0, 0, 0]) / 100
    out = np.zeros((steps.size, 4, 3))
    out[:, 1, 2] = np.cumsum(steps)
    out[7:10, 1, 1] = [0.055, 0.059, 0.032]  # lifted over the swing
    down = np.ones(steps.size, np.bool_)
    down[7:10] = False
    skimming = out.copy()
    skimming[7, 1, 1] = 0.005  # a lift-off skimming the ground: keeps its own step (read as planted)
    for before, first in ((out, 0), (out, 7), (out, 8), (skimming, 0)):  # batch; low-latency windows
        eased = before.copy()
        ease_jumps(eased, down, 1, 1.0, np.empty((steps.size + 4, 3)), first, np.empty(steps.size))
        # 1 mm: the rule spaces the frames along the path, a step's chord cuts its corners; with a
        # frame kept the rest cannot all come within the bound: issue 27's target then (6.7 before)
        limit = JUMP_TARGET_CM * 10 if before is skimming else JUMP_EASE * 1000 + 1.0
        assert one_frame_jumps_mm(eased[None, :, 1:2]).max() <= limit
        if before is skimming:
            assert np.array_equal(eased[7], before[7])
        assert_swing_kept(eased, before, down, first)


def test_a_touchdown_slowing_too_fast_for_a_ramp_is_retimed() -> None:
    """A gallop played past its clips' rate (the horse's too_fast, 13.8 m/s: 7.08 cm after FK)
    brings a hoof from 41 cm a frame to its plant in three frames, 35 32 26 3 cm: a ramp of the
    26 cm step's excess only moves it a frame back (35 then read 7.1 cm past its neighbours'
    mean). Where a ramp leaves a step past the bound and the next plant is known, the swing's
    progress is reshaped too (jump_kernels._clear_retime, kept only if it helps): every step
    within the ease bound, the plants and the frames sent not moved, the hoof never stepping back."""

    from synth_core.compiled.jump_kernels import ease_jumps
    from synth_core.quality.metrics import one_frame_jumps_mm
    from synth_core.runtime.footlock import JUMP_EASE

    steps = np.array([0, 0, 0, 6, 18, 32, 42, 46, 47, 41, 41.5, 35, 32.4, 26, 2.9, 0, 0, 0]) / 100
    out = np.zeros((steps.size, 4, 3))
    out[:, 1, 2] = np.cumsum(steps)
    out[3:14, 1, 1] = [0.02, 0.06, 0.11, 0.16, 0.2, 0.22, 0.22, 0.19, 0.14, 0.069, 0.029]
    down = np.ones(steps.size, np.bool_)
    down[3:14] = False
    for first in (0, 6, 9):  # a batch; low-latency windows with frames sent
        eased = out.copy()
        ease_jumps(eased, down, 1, 1.0, np.empty((steps.size + 4, 3)), first, np.empty(steps.size))
        assert one_frame_jumps_mm(eased[None, max(first - 2, 0):, 1:2]).max() <= JUMP_EASE * 1000 + 1.0, first
        assert_swing_kept(eased, out, down, first)


def assert_swing_kept(eased: np.ndarray, before: np.ndarray, down: np.ndarray, first: int) -> None:
    """What easing foot 1's swing (moving along +z) may not change: its plants, the frames before
    ``first`` (sent), its progress (never stepping back) and the ground under it."""
    assert np.array_equal(eased[down], before[down])
    assert np.array_equal(eased[:first], before[:first])
    assert np.all(np.diff(eased[:, 1, 2]) >= 0.0)
    assert np.all(eased[:, 1, 1] >= 0.0)


def test_a_swing_of_a_frame_between_far_plants_is_widened_into_a_step() -> None:
    """A walk -> static played by distance to a hard stop runs at 4-8x its clip (horse
    accel_brake): a hoof's swing is one frame between plants 66 cm apart, 33 cm a frame twice,
    and no ramp or retiming within it has frames to spread it over (16.6 cm after FK). The
    swing takes frames off its plants' ends where two other feet stand (never where fewer
    would: issue 27's walk support) and is stepped over them (jump_kernels.widen_swings): no
    step then jumps past the ease bound, the plants stay where they were on the frames still
    planted, and the frames taken are marked in the air."""

    from synth_core.compiled.jump_kernels import step_lengths, widen_swings
    from synth_core.quality.metrics import one_frame_jumps_mm
    from synth_core.runtime.footlock import JUMP_EASE

    T = 24
    out = np.zeros((T, 4, 3))
    out[11:, 0, 2] = 0.66
    out[10, 0] = (0.0, 0.04, 0.33)  # the one swing frame
    down = np.ones(T, np.bool_)
    down[10] = False
    air = np.zeros((T, 4), np.bool_)
    air[10, 0] = True
    air[:8, 1] = air[:8, 2] = True  # before frame 8, the left fore alone with the right hind
    air[13:, 2] = air[13:, 3] = True  # from frame 13, with the right fore
    before = out.copy()
    lengths = np.empty(T)
    step_lengths(out, 0, lengths)
    widen_swings(out, down, air, 0, 1.0, 0.08, np.empty((T + 4, 3)), lengths)
    assert one_frame_jumps_mm(out[None, :, 0:1]).max() <= JUMP_EASE * 1000 + 1.0
    assert np.array_equal(out[down, 0], before[down, 0])
    assert np.array_equal(air[:, 0], ~down)
    up = np.flatnonzero(~down)
    assert up[0] >= 8 and up[-1] <= 12  # frames taken only where two other feet stand
    assert up.size > 1 and np.all(np.diff(up) == 1)
    assert np.all(np.diff(out[:, 0, 2]) >= 0.0) and np.all(out[:, 0, 1] >= 0.0)
