"""The compiled kernels against their references (synth_core.compiled.backend): the planner's
compiled machine against the same source run by the interpreter, bit for bit."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from synth_core.build.library_store import builtin_library
from synth_core.compiled import backend
from synth_core.compiled import plan_kernels as pk
from synth_core.compiled.jit import AVAILABLE
from synth_core.quality import evaluate
from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.draws import SCHEDULE_STREAM, uniform_streams
from synth_core.runtime.plan import (
    N_HUBS,
    Decisions,
    Headings,
    Plan,
    Planner,
    decision_step,
    empty_plan,
    frame_speeds,
    lookahead,
    plan,
)
from synth_core.runtime.synthesis import Options, prepare_batch

needs_numba = pytest.mark.skipif(not AVAILABLE, reason="numba is not installed: only the reference runs")


def test_backends_are_chosen_by_name_in_one_place() -> None:
    assert backend.planner("numpy") is pk.REFERENCE
    assert backend.planner("auto") is (pk.COMPILED if AVAILABLE else pk.REFERENCE)
    assert backend.compiled("numba") and not backend.compiled("numpy")
    with pytest.raises(ValueError, match="backend: must be one of"):
        backend.compiled("gpu")
    # The reference is the compiled kernels' own source, run by the interpreter.
    for name in ("advance", "headings", "points_fine"):
        ref, fast = getattr(pk.REFERENCE, name), getattr(pk.COMPILED, name)
        assert ref.__code__ is getattr(fast, "py_func", fast).__code__


@needs_numba
@pytest.mark.parametrize("animal", ["horse", "dog"])
def test_compiled_plan_equals_the_reference_bit_for_bit(animal: str) -> None:
    bank = build_bank(builtin_library(animal))
    paths = crowd.simulate(48, 700, seed=4, top=evaluate.crowd_top_speed(bank))
    paths[:4, 200:] = paths[:4, 200:201]  # some stop dead (back to standing) and stay
    prep, h, keys = prepare_batch(bank, paths, None, None, Options(scale_range=(0.7, 1.3), seed=2), None)
    for frames in (90, None):  # the first frames only (a stream's first window), then all
        ref = plan(bank, prep, h, keys, frames=frames)
        fast = plan(bank, prep, h, keys, frames=frames, compiled=True)
        for name in ("rows", "weights", "gait", "contacts", "stitches", "yaw", "path"):
            assert np.array_equal(getattr(ref, name), getattr(fast, name)), name
    # The plan used every gait and transitions between them (the comparison covered them).
    used = np.unique(ref.rows[..., 0])
    played = [((used >= p.offset) & (used < p.offset + p.frames * p.clips)).any()
              for p in [*bank.gaits.values(), *bank.transitions.values()]]
    assert all(played[:len(bank.gaits)]) and sum(played[len(bank.gaits):]) >= 4


@needs_numba
def test_planner_blocks_and_state_are_the_references(bank: Bank) -> None:
    """Both backends advanced block by block (random block sizes, every other frame sent, a
    decision at each block starting on one): the same rows and the same carried state."""
    rng = np.random.default_rng(5)
    paths = crowd.simulate(10, 400, seed=5, top=evaluate.crowd_top_speed(bank))
    prep, h, keys = prepare_batch(bank, paths, None, None, Options(scale_range=(0.7, 1.3), seed=5), None)
    C, T = prep.positions.shape[:2]
    m = prep.segment
    assert prep.tempo is not None
    v = frame_speeds(prep.segment_speeds / (h * prep.tempo)[:, None], m, T)
    step = decision_step(m)
    planners = {name: Planner(bank, h, prep.tempo, backend=name) for name in ("numba", "numpy")}
    headings = {name: Headings(C, name) for name in ("numba", "numpy")}
    ground = prep.positions[..., [0, 2]]
    t0 = 0
    while t0 < T - 1:
        t1 = min(T - 1, t0 + int(rng.integers(1, 3 * step)), -(-(t0 + 1) // step) * step)
        k = t0 // step
        asked = t0 % step == 0
        decisions = Decisions(k, v[:, [min(t0 + lookahead(m), T - 1)]] if asked else np.zeros((C, 0)),
                              uniform_streams(keys, SCHEDULE_STREAM + k, int(asked), N_HUBS))
        outs = {}
        for name, planner in planners.items():
            out = empty_plan(C, -(-t1 // 2) - -(-t0 // 2), h)
            planner.advance(t0, v[:, t0:t1], prep.positions[:, t0:t1 + 1], decisions, out, 2)
            lo = max(t0 - 1, 0)
            turned = headings[name].advance(ground[:, lo:t1 + 1], t0 - lo, t1 - t0, bank.fps, np.zeros(C),
                                            ahead=lambda who, lo=lo: ground[who, lo:])  # type: ignore[misc]
            outs[name] = (out, turned)
        for f in fields(Plan):
            if f.name not in ("scales", "yaw", "lean", "path"):  # yaw and lean: from Headings
                assert np.array_equal(getattr(outs["numba"][0], f.name), getattr(outs["numpy"][0], f.name))
        assert np.array_equal(outs["numba"][1], outs["numpy"][1])
        assert np.array_equal(planners["numba"].ints, planners["numpy"].ints)
        assert np.array_equal(planners["numba"].floats, planners["numpy"].floats)
        t0 = t1
    assert (planners["numpy"].ints[:, pk.CURRENT] > 1).any()  # they went beyond a walk


@needs_numba
def test_points_check_kernels_agree() -> None:
    rng = np.random.default_rng(1)
    for trial in range(40):
        pts = np.cumsum(rng.uniform(-2, 2, (3, 5, 3)), axis=1)
        if trial % 4 == 1:
            pts[trial % 3, trial % 5, 1] = np.nan
        last = np.full((3, 3), np.nan) if trial % 2 else pts[:, 0] + 1.0
        assert pk.COMPILED.points_fine(last, pts, 5.0) == pk.REFERENCE.points_fine(last, pts, 5.0)
