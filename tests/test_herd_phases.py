"""Herds out of step (issue 28): a herd of 20 horses of one size, started together (the crowd-sim
herd: stand, speed up to a gallop, slow to a walk), measured after FK on the exported motion --
how often two horses show the same 4-foot contact pattern (metrics.same_pattern_share)."""

from __future__ import annotations

import pytest

from synth_core.build.library_store import builtin_library
from synth_core.quality import herd_sim as crowd
from synth_core.quality import metrics as M
from synth_core.quality.evaluate import world_positions
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.synthesis import Options, synthesize

TARGET = 0.30  # issue 28 (random phases ~0.22; the gait's chance level, a trot ~0.34, a walk ~0.13)
CHARACTERS, FRAMES = 20, 1000


@pytest.fixture(scope="module")
def bank() -> Bank:
    return build_bank(builtin_library("horse"))


def share(bank: Bank, **options: float) -> float:
    """The herd's same-pattern share, feet down = within 1 cm of the ground for 3 frames (FK)."""
    paths = crowd.simulate(CHARACTERS, FRAMES, seed=0)
    result = synthesize(bank, paths, options=Options(scale_range=(1.0, 1.0), seed=0, **options))  # type: ignore[arg-type]
    feet = world_positions(bank, result)[:, :, bank.skeleton.foot_joints]
    return M.same_pattern_share(M.strict_plants(M.foot_heights(feet, result.path[..., 1])))


def test_each_characters_own_tempo_moves_a_herd_of_one_size_out_of_step(bank: Bank) -> None:
    assert share(bank) < share(bank, tempo_spread=0.0) - 0.03


@pytest.mark.xfail(strict=True, reason=(
    "0.384 (0.557 over the first 500 frames): every horse leaves standing by the one static -> walk "
    "transition at the same distance, and transitions play by distance, so the herd is in step "
    "through the start and the speed-up (frames 60-350: 0.87-0.47); a phase drawn by a stride "
    "faster or slower for a while after each change (<= 30%, on the speed map) reached 0.370, a "
    "phase jump within the footfall-keeping window 0.361 but stretched legs 2.3% and cut "
    "footfall_preserved (docs/herd_phases.md). Needs starts with either fore foot first "
    "(mirrored clips or several start transitions)."))
def test_a_herd_of_one_size_started_together_steps_out_of_step(bank: Bank) -> None:
    assert share(bank) <= TARGET
