"""No hoof jumps more than issue 27's 6 cm in one frame after FK (metrics.one_frame_jumps_mm: a
step longer than the mean of the steps before and after it), in horse edge scenarios whose
stitches jumped it: a held transition fading out, a frame skipped at a contact change, settling
pinning a raised hoof (docs/stitch_jumps.md). The foot lock eases a target's one-frame jump into
a ramp over the swing frames around it (jump_kernels.ease_jumps).

Before it (main at 8b8a386) these read 8.31 (cruise_straight), 9.99 (uturn_canter), 12.16
(uturn_gallop) and 12.98 cm (mixed_sizes, scales 0.5-2.0)."""

from __future__ import annotations

import pytest

from synth_core.build.library_store import builtin_library
from synth_core.quality import evaluate
from synth_core.runtime.bank import Bank, build_bank

JUMP_TARGET_CM = 6.0  # issue 27: one-frame jump, after FK
SKATE_TARGET_MM = 3.0  # issue 27: strict plant skate p95 (planted frames are never moved)


@pytest.fixture(scope="module")
def horse() -> Bank:
    return build_bank(builtin_library("horse"))


@pytest.mark.parametrize("name", ["cruise_straight", "uturn_canter", "uturn_gallop", "mixed_sizes"])
def test_no_hoof_jumps_past_the_target_in_one_frame(horse: Bank, name: str) -> None:
    out = evaluate.edge_suite(horse, names=[name])["scenarios"][name]["figures"]
    assert out["jump_cm_max"] <= JUMP_TARGET_CM
    assert out["strict_skate_mm_p95"] <= SKATE_TARGET_MM


LL_SKATE_LIMIT_MM = 5.0  # issue 31: the low-latency mode's strict plant skate p95
LL_LATENCY_MS = 100.0  # the low-latency edge suite's budget (quadsynth eval --live low_latency)


@pytest.mark.parametrize(("animal", "name"), [("dog", "jitter_10hz"), ("horse", "moving_start")])
def test_no_foot_jumps_past_the_target_in_the_low_latency_mode(horse: Bank, animal: str, name: str) -> None:
    """The low-latency live mode eases the jumps of its frames not sent yet from the targets sent
    (jump_kernels.ease_unsent), and a ramp lowers no swing frame still moving over the ground
    to near its plants' height (jump_kernels._ramp): the dog's jitter_10hz, whose last swing
    frames before a touchdown it lowered under the strict-plant height, skated 6.6 mm (p95).
    On main at e2f3035 these read 10.07 cm (dog jitter_10hz) and 7.49 cm (horse moving_start)."""
    bank = horse if animal == "horse" else build_bank(builtin_library(animal))
    out = evaluate.edge_suite(bank, names=[name], live=True, latency_ms=LL_LATENCY_MS)["scenarios"][name]
    assert out["figures"]["jump_cm_max"] <= JUMP_TARGET_CM
    assert out["figures"]["strict_skate_mm_p95"] <= LL_SKATE_LIMIT_MM
