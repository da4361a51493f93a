"""The compiled kernels against their references (synth_core.compiled.backend): each is the same
source run by the interpreter. The planner's compiled machine gives the same numbers bit for bit;
the render's (float32 tables, float64 arithmetic, a few fast-math flags and numba's own math
functions) to a rounding."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from synth_core.build.library_store import builtin_library
from synth_core.compiled import backend, ground_kernels, kernels
from synth_core.compiled import plan_kernels as pk
from synth_core.compiled.jit import AVAILABLE, interpreted
from synth_core.quality import evaluate
from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.draws import SCHEDULE_STREAM, uniform_streams
from synth_core.runtime.live import LiveSynth
from synth_core.runtime.plan import (
    N_HUBS,
    Decisions,
    Headings,
    Plan,
    Planner,
    character_leads,
    decision_step,
    empty_plan,
    frame_speeds,
    lookahead,
    plan,
)
from synth_core.runtime.streaming import BatchStream
from synth_core.runtime.synthesis import Options, Result, prepare_batch, synthesize
from tests.helpers.motion import herd_on_hills

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
    assert (kernels.COMPILED is kernels.REFERENCE) == (not AVAILABLE)
    for name in ("render_all", "render_windows", "lock_contexts"):
        ref, fast = getattr(kernels.REFERENCE, name), getattr(kernels.COMPILED, name)
        assert ref.__code__ is getattr(fast, "py_func", fast).__code__


def test_the_render_reference_calls_no_compiled_code() -> None:
    """Down to the last helper, in every kernel module, the reference runs source."""
    seen: set[int] = set()
    todo = [kernels.REFERENCE.render_all, kernels.REFERENCE.render_windows, kernels.REFERENCE.lock_contexts]
    while todo:
        f = todo.pop()
        if id(f) in seen:
            continue
        seen.add(id(f))
        for name in f.__code__.co_names:
            callee = f.__globals__.get(name)
            assert not hasattr(callee, "py_func"), (f.__name__, name)  # no numba dispatcher
            if callable(callee) and getattr(callee, "__module__", "").startswith("synth_core.compiled"):
                todo.append(callee)
    assert len(seen) >= 20  # the passes, FK, IK, plant targets, sink, terrain, vector helpers


def _close_motion(ref: Result, fast: Result) -> None:
    """The render's tolerance: float32 tables, float64 in the kernel."""
    dots = np.clip(np.abs(np.sum(ref.rotations * fast.rotations, axis=-1)), 0, 1)
    assert 2 * np.degrees(np.arccos(dots)).max() < 0.1  # degrees
    assert np.abs(ref.root_pos - fast.root_pos).max() < 1e-5  # metres
    assert np.array_equal(ref.contacts, fast.contacts) and np.array_equal(ref.gait, fast.gait)


@needs_numba
@pytest.mark.parametrize("foot_lock", [False, True])
def test_compiled_render_equals_the_reference(bank: Bank, foot_lock: bool) -> None:
    herd = crowd.simulate(6, 900, seed=0, top=6.0)[:, :400]
    opts = dict(scale_range=(0.7, 1.3), seed=3, foot_lock=foot_lock)
    ref = synthesize(bank, herd, options=Options(backend="numpy", **opts))  # type: ignore[arg-type]
    fast = synthesize(bank, herd, options=Options(backend="numba", **opts))  # type: ignore[arg-type]
    _close_motion(ref, fast)
    if foot_lock:  # the lock did something, and both did the same
        free_opts = {**opts, "foot_lock": False}
        free = synthesize(bank, herd, options=Options(backend="numba", **free_opts))  # type: ignore[arg-type]
        turn = np.abs(np.sum(free.rotations * fast.rotations, axis=-1))
        assert 2 * np.degrees(np.arccos(np.clip(turn, 0, 1))).max() > 1.0


@needs_numba
def test_compiled_render_equals_the_reference_on_a_terrain(bank: Bank) -> None:
    paths, field = herd_on_hills()
    opts = dict(scale_range=(0.8, 1.2), seed=4, ground=field)
    ref = synthesize(bank, paths, 60.0, options=Options(backend="numpy", **opts))  # type: ignore[arg-type]
    fast = synthesize(bank, paths, 60.0, options=Options(backend="numba", **opts))  # type: ignore[arg-type]
    _close_motion(ref, fast)
    # ... and the terrain did something: the bodies stand on it, not on the paths' y (0).
    flat = synthesize(bank, paths, 60.0, options=Options(backend="numba", scale_range=(0.8, 1.2), seed=4))
    assert np.abs(fast.root_pos[..., 1] - flat.root_pos[..., 1]).max() > 0.3


@needs_numba
def test_compiled_windows_equal_the_reference(bank: Bank) -> None:
    """A stream's windows (each over its lock context) and a live session's (reading the feet
    and legs earlier windows posed: kernels.Posed) by both backends."""
    paths = crowd.simulate(4, 300, seed=6, top=9.0)
    made: dict[str, list[np.ndarray]] = {}
    for name in ("numba", "numpy"):
        opts = Options(scale_range=(0.8, 1.2), seed=6, backend=name)
        stream = [w.rotations for w in BatchStream(bank, paths, options=opts, chunk_frames=40).windows()]
        live = LiveSynth(bank, len(paths), 60.0, seed=6, backend=name)
        windows = [w for a in range(0, 300, 20) if (w := live.append(paths[:, a:a + 20])) is not None]
        windows += [w for w in [live.finish()] if w is not None]
        made[name] = [np.concatenate(stream, axis=1), np.concatenate([w.rotations for w in windows], axis=1),
                      np.concatenate([w.root_pos for w in windows], axis=1)]
    for ref, fast in zip(made["numpy"][:2], made["numba"][:2], strict=True):
        assert ref.shape == fast.shape == (4, 300, bank.skeleton.n_joints, 4)
        dots = np.clip(np.abs(np.sum(ref * fast, axis=-1)), 0, 1)
        assert 2 * np.degrees(np.arccos(dots)).max() < 0.1
    assert np.abs(made["numpy"][2] - made["numba"][2]).max() < 1e-5


@needs_numba
def test_compiled_lock_context_is_the_references() -> None:
    rng = np.random.default_rng(7)
    # Runs of random lengths (1 to 12 frames), so windows start and end in plants, in swings,
    # at the first and the last frame.
    lengths = rng.integers(1, 13, size=(50, 4, 40))
    flags = np.arange(40) % 2 == rng.integers(0, 2, size=(50, 4, 1))
    contacts = np.stack([np.stack([np.repeat(flags[c, f], lengths[c, f])[:90] for f in range(4)], axis=-1)
                         for c in range(50)])
    for start, stop in [(0, 1), (0, 90), (3, 17), (40, 55), (80, 90), (89, 90), (11, 12)]:
        want = kernels.lock_context(contacts, start, stop, compiled=False)
        got = kernels.lock_context(contacts, start, stop)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])


@needs_numba
def test_compiled_ground_sampling_is_the_references() -> None:
    rng = np.random.default_rng(1)
    heights = rng.normal(size=(30, 50))
    x, z = rng.uniform(-3.0, 30.0, (2, 7, 11))  # some outside the grid
    at = interpreted(vars(ground_kernels))["ground_at"]
    want = np.array([at(heights, -1.0, 0.5, 0.5, a, b) for a, b in zip(x.ravel(), z.ravel(), strict=True)])
    assert np.array_equal(ground_kernels.ground_samples(heights, -1.0, 0.5, 0.5, x, z), want.reshape(x.shape))


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
    used = np.unique(ref.rows[..., 0] % bank.own)  # either lead
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
    leads = character_leads(bank, keys)  # both leads among the ten
    planners = {name: Planner(bank, h, prep.tempo, leads, backend=name) for name in ("numba", "numpy")}
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
            lo = max(t0 - 1, 0)
            turned = headings[name].advance(ground[:, lo:t1 + 1], t0 - lo, t1 - t0, bank.fps, np.zeros(C),
                                            ahead=lambda who, lo=lo: ground[who, lo:])  # type: ignore[misc]
            planner.advance(t0, v[:, t0:t1], prep.positions[:, t0:t1 + 1], turned[3], decisions, out, 2)
            outs[name] = (out, turned)
        for f in fields(Plan):
            if f.name not in ("scales", "yaw", "lean", "path", "way"):  # yaw to way: not the planner's
                assert np.array_equal(getattr(outs["numba"][0], f.name), getattr(outs["numpy"][0], f.name))
        assert all(np.array_equal(a, b) for a, b in zip(outs["numba"][1], outs["numpy"][1], strict=True))
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
