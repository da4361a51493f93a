"""The contacts a client gets are the feet the motion plants (docs/wire-format.md): measured after
FK on the output, in the batch and the low-latency live mode, on edge scenarios where the foot
lock steps a standing foot (turn_on_spot), holds plants on a turn and on a terrain."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.build.motion_graph import HUBS
from synth_core.quality import edge, evaluate
from synth_core.quality.live_run import play
from synth_core.quality.reference import library_reference
from synth_core.runtime.bank import Bank
from synth_core.runtime.synthesis import Options, Result, synthesize

# A foot flagged planted is on the ground: no higher (nor lower) than the edge suite lets a foot
# float (floating_cm_max <= 1 cm). What is left under it: the plant's height, the clip's own
# stance height over its sole (footlock: a plant stands at its frames' average), and the leg's
# reach slack (footlock.PLANTED_SLACK, 3 mm).
ON_GROUND_M = 0.01
STILL_M = 0.001  # a foot moving less than this a frame stands still
LONG_S = 0.5  # a foot standing still on the ground this long is planted...
EDGE_FRAMES = 2  # ... but for a frame or two at either end of its stand


def _run(bank: Bank, name: str, live: bool) -> tuple[Result, edge.Scenario]:
    """Edge scenario ``name`` (``<name>_on_slope``: on a 20% slope rising along z), its result."""
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    (sc,) = edge.scenarios(gaits, bank.fps, 0, [name.removesuffix("_on_slope")])
    if name.endswith("_on_slope"):
        sc = edge.on_terrain(sc, lambda x, z: 0.2 * z, name, sc.about + ", on a 20% slope")
    if live:
        return play(bank, sc.positions, sc.scales, 0, 100.0, sc.ground).result, sc
    return synthesize(bank, sc.positions, bank.fps, scales=sc.scales,
                      options=Options(seed=0, ground=sc.ground)), sc


def _stands(on_ground: np.ndarray, still: np.ndarray, long: int) -> list[tuple[int, int]]:
    """``[a, b)`` of each run of frames one foot stands still on the ground, ``long`` or longer."""
    both = np.concatenate([[False], on_ground & still, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(both))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a >= long]


@pytest.mark.parametrize(("name", "live"), [("turn_on_spot", False), ("turn_on_spot", True),
                                            ("uturn_walk", False), ("turn_on_spot_on_slope", False)])
def test_a_foot_flagged_planted_is_on_the_ground_and_a_standing_foot_is_flagged(
        bank: Bank, name: str, live: bool) -> None:
    result, sc = _run(bank, name, live)
    fk = evaluate.feet_after_fk(bank, result, library_reference(bank), sc.ground)
    up = np.abs(fk.heights)  # over the ground (the terrain's under the foot), the foot's sole taken off
    flagged = result.contacts
    assert flagged.any()
    worst = np.unravel_index(np.argmax(np.where(flagged, up, 0.0)), up.shape)
    assert up[flagged].max() <= ON_GROUND_M, f"flagged planted {up[worst] * 1000:.0f} mm up at {worst}"
    step = np.linalg.norm(np.diff(fk.feet, axis=1), axis=-1)
    still = np.concatenate([step[:, :1] < STILL_M, step < STILL_M], axis=1)
    missed = []
    for c in range(flagged.shape[0]):
        for f in range(4):
            for a, b in _stands(up[c, :, f] <= ON_GROUND_M, still[c, :, f], round(LONG_S * bank.fps)):
                off = int((~flagged[c, a + EDGE_FRAMES:b - EDGE_FRAMES, f]).sum())
                if off:
                    missed.append((c, f, a, b, off))
    assert not missed, f"standing feet flagged off (character, foot, frames, how many): {missed}"
