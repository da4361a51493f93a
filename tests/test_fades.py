"""Fades between pieces (issue 27): where a piece starts while the one before it is still fading
in (a piece that lasts a few frames between two transitions, e.g. the walk between static -> walk
and walk -> trot), the piece fading out under it must not vanish in one frame. Judged after FK on
the output motion (foot lock on, as a user gets it): before, hooves jumped 25-38 cm in one frame
there in most horse scenarios, paws 11 cm."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from synth_core.build.animals import build_builtin
from synth_core.build.motion_graph import HUBS
from synth_core.quality import edge, evaluate
from synth_core.quality import metrics as M
from synth_core.quality.reference import library_reference
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.plan import MARGIN
from synth_core.runtime.synthesis import Options, synthesize

JUMP_CM = 6.0  # the target for a one-frame foot jump


@functools.lru_cache(maxsize=2)
def animal_bank(animal: str) -> Bank:
    return build_bank(build_builtin(animal))


def starts_within_margin(stitches: np.ndarray) -> np.ndarray:
    """``(C, T)``: frames where a piece starts fewer than MARGIN frames after the one before."""
    out = np.zeros_like(stitches)
    for d in range(1, MARGIN):
        out[:, d:] |= stitches[:, d:] & stitches[:, :-d]
    return out


@pytest.mark.parametrize(("animal", "scenario"), [("horse", "cruise_straight"), ("horse", "corner_canter"),
                                                  ("horse", "stop_go"), ("dog", "mixed_sizes")])
def test_a_piece_fading_out_does_not_vanish_when_the_next_starts(animal: str, scenario: str) -> None:
    bank = animal_bank(animal)
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    sc = edge.scenarios(gaits, bank.fps, 0, [scenario])[0]
    result = synthesize(bank, sc.positions, bank.fps, scales=sc.scales, options=Options(seed=0))
    fk = evaluate.feet_after_fk(bank, result, library_reference(bank))
    jumps = M.one_frame_jumps_mm(fk.feet).max(axis=-1) / 10  # (C, T - 3): step f + 1 -> f + 2
    double = starts_within_margin(result.stitches)
    assert double.sum() >= 1  # the case is there
    near = np.zeros_like(double)
    for d in range(-3, 4):  # the steps around each such start
        near |= np.roll(double, d, axis=1)
    at = near[:, 2:-1]
    worst = float(jumps[at].max())
    c, f = np.argwhere(at & (jumps == worst))[0]
    assert worst <= JUMP_CM, (c, f + 2, worst)
