"""Plants stand where their clips stand the foot (issue 33's planted height, p95 <= 5 mm after
FK), not where the blended pose's FK puts it: a pose blended from two frames apart in a stance
(a piece fading out, held on its last frame, while the next plays on) swings the planted leg
through the chord between them, and FK puts the foot under both frames' heights
(bank.standing_heights, pose_kernels.clip_soles).

On main at a8ea90e, whose plants stood at their frames' FK, the low-latency scenarios below read
39.2 mm (horse accel_brake) and 34.6 mm (dog stop_go)."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.build.library_store import builtin_library
from synth_core.quality import evaluate
from synth_core.runtime.bank import build_bank, standing_heights, table_positions

PLANTED_LIMIT_MM = 5.0  # issue 33: planted feet over their gait's standing height, p95
LL_LATENCY_MS = 100.0  # the low-latency edge suite's budget (quadsynth eval --live low_latency)


@pytest.mark.parametrize(("animal", "name"), [("horse", "accel_brake"), ("dog", "stop_go")])
def test_low_latency_plants_stand_on_their_clips_soles(animal: str, name: str) -> None:
    bank = build_bank(builtin_library(animal))
    out = evaluate.edge_suite(bank, names=[name], live=True, latency_ms=LL_LATENCY_MS)["scenarios"][name]
    assert out["figures"]["planted_ground_mm_p95"] <= PLANTED_LIMIT_MM


def test_a_transitions_plants_stand_at_their_own_heights_not_the_clips() -> None:
    """A transition goes from one gait's standing heights to the other's: each of its plants
    stands at its own (its heights' low tenth), and a row between two plants at the nearer's."""
    bank = build_bank(builtin_library("dog"))
    pos = table_positions(bank)
    heights = pos[:, bank.skeleton.foot_joints, 1]
    table = standing_heights(bank, pos)
    piece = next(iter(bank.transitions.values()))
    rows = np.arange(piece.offset, piece.offset + piece.frames)
    for f in range(4):
        down = bank.contacts[rows, f]
        edges = np.flatnonzero(np.diff(np.concatenate([[0], down.astype(int), [0]])))
        assert len(edges) >= 4, "a transition with two plants of each foot"
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            assert np.allclose(table[rows[a:b], f], np.percentile(heights[rows[a:b], f], 10.0))
        between = np.flatnonzero(~down)
        between = between[(between > edges[0]) & (between < edges[-1] - 1)]
        for r in between:
            gaps = [max(a - r, r - (b - 1), 0) for a, b in zip(edges[::2], edges[1::2], strict=True)]
            a, b = edges[::2][int(np.argmin(gaps))], edges[1::2][int(np.argmin(gaps))]
            assert table[rows[r], f] == pytest.approx(np.percentile(heights[rows[a:b], f], 10.0))
