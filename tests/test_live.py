"""Live synthesis (synth_core.runtime.live): points a few at a time, frames back within the documented
latency -- the batch plan's own frames, made incrementally."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from synth_core.motion.skeleton import forward_kinematics
from synth_core.quality import herd_sim as crowd
from synth_core.quality.metrics import foot_skate
from synth_core.runtime.bank import Bank
from synth_core.runtime.columns import Columns
from synth_core.runtime.live import LiveSynth
from synth_core.runtime.live_shards import LiveShards
from synth_core.runtime.streaming import Window
from synth_core.runtime.streaming import joined as shards_joined
from synth_core.runtime.synthesis import Options, synthesize
from synth_core.runtime.trajectory import TELEPORT_M, TrajectoryError
from tests.helpers.live import feed, joined


@pytest.fixture(scope="module")
def herd() -> np.ndarray:
    return crowd.simulate(24, 700, seed=3)


def test_live_frames_are_the_batch_plans_frames(bank: Bank, herd: np.ndarray) -> None:
    """(The reference backend runs the same planner and render source: tests/test_backends.py
    holds it to these, block by block and window by window.)"""
    batch = synthesize(bank, herd, 60.0, options=Options(seed=5, scale_range=(0.8, 1.2), foot_lock=False))
    assert batch.resample_rate == 1.0  # live cannot resample: compare where the batch did not either
    live = LiveSynth(bank, len(herd), 60.0, seed=5, scale_range=(0.8, 1.2), foot_lock=False)
    windows, lags = feed(live, herd)
    root, rot, gait, contacts = joined(windows)
    assert root.shape == batch.root_pos.shape and np.array_equal(live.scales, batch.scales)
    # Up to the last three segments: gaits are chosen on the speed LOOKAHEAD (2) segments ahead,
    # so the batch's last, shorter segment is read from the two segments before it on.
    t = slice(0, root.shape[1] - 3 * bank.mean_cycle)
    np.testing.assert_array_equal(gait[:, t], batch.gait[:, t])
    np.testing.assert_array_equal(contacts[:, t], batch.contacts[:, t])
    np.testing.assert_allclose(root[:, t], batch.root_pos[:, t], atol=1e-6)
    np.testing.assert_allclose(rot[:, t], batch.rotations[:, t], atol=1e-6)
    assert max(lags) <= live.latency_frames  # the documented latency, never more
    assert len(set(gait.ravel().tolist())) == 5  # standing and every gait: the test covers them


def test_a_ticks_kernels_run_on_the_calling_thread_alone(bank: Bank, herd: np.ndarray,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """A tick's kernels are small: fanned out to every core, each would wait for the slowest
    thread, on a busy machine a scheduler slice per call (render_pool.one_thread). The
    caller's own setting is back after every call."""
    numba = pytest.importorskip("numba")
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one thread here: nothing to show")
    from synth_core.compiled import kernels
    from synth_core.runtime import live as live_module

    seen: list[int] = []
    render = kernels.render_window

    def spy(*args: object, **kwargs: object) -> tuple[np.ndarray, np.ndarray]:
        seen.append(numba.get_num_threads())
        return render(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(live_module.kernels, "render_window", spy)
    numba.set_num_threads(2)
    live = LiveSynth(bank, 3, 60.0, seed=1)
    feed(live, herd[:3, :200])
    assert seen and set(seen) == {1}
    assert numba.get_num_threads() == 2


def test_points_at_30_fps_come_back_at_30_fps(bank: Bank) -> None:
    herd = crowd.simulate(8, 400, seed=4, fps=30.0)
    batch = synthesize(bank, herd, 30.0, options=Options(seed=1, foot_lock=False))
    live = LiveSynth(bank, len(herd), 30.0, seed=1, foot_lock=False)
    root, rot, gait, _ = joined(feed(live, herd, seed=2)[0])
    assert root.shape[1] == 400 and batch.root_pos.shape[1] == 799  # every other library frame
    t = slice(0, 400 - bank.mean_cycle)
    np.testing.assert_array_equal(gait[:, t], batch.gait[:, ::2][:, t])
    np.testing.assert_allclose(root[:, t], batch.root_pos[:, ::2][:, t], atol=1e-4)


def skate_mm(bank: Bank, scales: np.ndarray, root: np.ndarray, rot: np.ndarray,
             contacts: np.ndarray) -> tuple[float, float]:
    offsets = bank.skeleton.offsets[None, None] * scales[:, None, None, None].astype(np.float32)
    pos, _ = forward_kinematics(bank.skeleton, root, rot, offsets)
    stats = foot_skate(np.asarray(pos)[..., bank.skeleton.foot_joints, :], contacts)
    return stats.mean_mm, stats.p95_mm


def test_live_foot_lock_keeps_feet_nearly_as_still_as_the_batchs(bank: Bank, herd: np.ndarray) -> None:
    """A plant still going on at a block's end is pinned at its average so far, and moves to
    its whole average in the next block: a small step now and then, measured here."""
    batch = synthesize(bank, herd, 60.0, options=Options(seed=5, scale_range=(0.8, 1.2)))
    live = LiveSynth(bank, len(herd), 60.0, seed=5, scale_range=(0.8, 1.2))
    root, rot, gait, contacts = joined(feed(live, herd)[0])
    live_mean, live_p95 = skate_mm(bank, live.scales, root, rot, contacts)
    batch_mean, batch_p95 = skate_mm(bank, batch.scales, batch.root_pos, batch.rotations, batch.contacts)
    unlocked = LiveSynth(bank, len(herd), 60.0, seed=5, scale_range=(0.8, 1.2), foot_lock=False)
    f_root, f_rot, _, f_contacts = joined(feed(unlocked, herd)[0])
    free = skate_mm(bank, unlocked.scales, f_root, f_rot, f_contacts)
    assert live_p95 <= batch_p95 + 0.1 and live_mean <= 1.8, (live_mean, live_p95, batch_mean, batch_p95)
    assert live_mean < free[0] / 3  # the lock does its work live too


def test_bad_points_are_refused_naming_the_character(bank: Bank) -> None:
    live = LiveSynth(bank, 3, 60.0)
    ok = np.zeros((3, 5, 3))
    with pytest.raises(TrajectoryError, match=r"expected shape \(3, n >= 1, 3\), got \(2, 5, 3\)"):
        live.append(ok[:2])
    bad = ok.copy()
    bad[1, 2, 0] = np.nan
    with pytest.raises(TrajectoryError, match="character 1: points: NaN or Inf at its point 2"):
        live.append(bad)
    live.append(ok)
    jump = ok.copy()
    jump[2, 0] = [9.0, 0.0, 0.0]  # from the last point given: 9 m in one frame
    with pytest.raises(TrajectoryError, match="character 2: points: jumps 9.0 m in one frame"):
        live.append(jump)
    assert live.finish() is not None
    with pytest.raises(TrajectoryError, match="the trajectories have ended"):
        live.append(ok)
    with pytest.raises(TrajectoryError, match="at least 2 points"):
        LiveSynth(bank, 1, 60.0).finish()
    with pytest.raises(TrajectoryError, match=r"fps: must be within \(0, 60\]"):
        LiveSynth(bank, 1, 120.0)


def test_the_compiled_points_check_passes_what_the_numpy_check_passes(bank: Bank) -> None:
    """LiveSynth.check's compiled fast path (plan_kernels.points_fine) passes exactly the
    points the numpy checks pass: NaN and Inf anywhere, jumps just over and under the limit,
    from the last point given or (a session's first points) between the points only."""
    pytest.importorskip("numba")
    rng = np.random.default_rng(3)
    limit = TELEPORT_M
    cases = 0
    for first in (True, False):
        for trial in range(60):
            pts = np.cumsum(rng.uniform(-0.3, 0.3, (4, 6, 3)), axis=1)
            c, i = int(rng.integers(4)), int(rng.integers(6))
            kind = trial % 6
            if kind == 1:
                pts[c, i, int(rng.integers(3))] = [np.nan, np.inf, -np.inf][trial % 3]
            elif kind in (2, 3):  # a jump a hair over or under the limit
                before = pts[c, i - 1] if i > 0 else np.zeros(3)
                pts[c, i:] += before + [limit * (1.0001 if kind == 2 else 0.9999), 0.0, 0.0] - pts[c, i]
            results = []
            for backend in ("numba", "numpy"):
                live = LiveSynth(bank, 4, 60.0, backend=backend)
                if not first:
                    live.append(np.zeros((4, 1, 3)))
                try:
                    live.check(pts)
                    results.append("fine")
                except TrajectoryError as exc:
                    results.append(str(exc))
            assert results[0] == results[1], (first, trial)
            cases += results[0] != "fine"
    assert cases >= 40  # the refusals were exercised, not only the passes


def test_shards_make_the_sessions_frames_bit_for_bit(bank: Bank, herd: np.ndarray) -> None:
    """A session cut into shards (each advanced in its own thread, rendering on one, parts of
    its render taken by the threads done first) makes one LiveSynth's frames: its characters'
    draws (scales, gaits) by their index in the session."""
    seeds = np.where(np.arange(len(herd)) % 5 == 0, 11, -1)  # some characters with their own seed
    scales = np.where(np.arange(len(herd)) % 4 == 1, 1.1, np.nan)  # some given, the rest drawn
    options = {"seed": 5, "scale_range": (0.8, 1.2), "scales": scales, "seeds": seeds}
    whole = LiveSynth(bank, len(herd), 60.0, **options)  # type: ignore[arg-type]
    sharded = LiveShards(bank, len(herd), 60.0, shards=3, **options)  # type: ignore[arg-type]
    assert [len(p.scales) for p in sharded.parts] == [8, 8, 8]
    assert all(p.share is not None for p in sharded.parts) and whole.share is None
    np.testing.assert_array_equal(sharded.scales, whole.scales)
    assert sharded.latency_frames == whole.latency_frames
    rng = np.random.default_rng(1)
    i, windows = 0, 0
    while True:
        n = int(rng.integers(1, 45))
        done = i >= herd.shape[1]
        want = whole.finish() if done else whole.append(herd[:, i:i + n])
        got = sharded.finish() if done else sharded.append(herd[:, i:i + n])
        i += n
        assert (got is None) == (want is None)
        if got is not None and want is not None:
            assert len(got) == 3 and {w.start for w in got} == {want.start}
            one = shards_joined(got)
            for field in ("root_pos", "rotations", "gait", "contacts"):
                np.testing.assert_array_equal(getattr(one, field), getattr(want, field))
            windows += 1
        if done:
            break
    assert windows >= 5


def test_bounded_windows_join_to_the_unbounded_ones(bank: Bank, herd: np.ndarray) -> None:
    """append(points, frames) and finish(frames) give at most ``frames`` frames a window and
    take() the rest: joined, the frames of unbounded windows, bit for bit (a bounded window keeps
    the lock's whole context for the rest: dropping it after each, standing horses' long plants
    were averaged over fewer frames, 37 um apart). reuse_windows renders each window on the last
    one's pages."""
    options = {"seed": 5, "scale_range": (0.8, 1.2)}
    whole = LiveSynth(bank, len(herd), 60.0, **options)  # type: ignore[arg-type]
    bounded = LiveSynth(bank, len(herd), 60.0, reuse_windows=True, **options)  # type: ignore[arg-type]
    rng = np.random.default_rng(2)
    want, got, sizes, shared = [], [], [], 0
    i = 0
    while i <= herd.shape[1]:
        n = int(rng.integers(1, 90))
        done = i >= herd.shape[1]
        w = whole.finish() if done else whole.append(herd[:, i:i + n])
        want += [w] if w is not None else []
        b = bounded.finish(7) if done else bounded.append(herd[:, i:i + n], 7)
        last = None
        while b is not None:
            sizes.append(b.stop - b.start)
            shared += last is not None and np.shares_memory(last, b.rotations)
            last = b.rotations
            got.append(Window(b.start, b.root_pos, b.rotations.copy(), b.gait, b.contacts))
            b = bounded.take(7)
        i += n
    assert max(sizes) == 7 and len(got) > 2 * len(want) and shared > 0
    with pytest.raises(ValueError, match="frames: a window holds at least 1"):
        bounded.take(0)
    for a, b in zip(joined(got), joined(want), strict=True):
        np.testing.assert_array_equal(a, b)


def test_shards_refuse_bad_points_whole_naming_the_character(bank: Bank) -> None:
    sharded = LiveShards(bank, 6, 60.0, shards=3)
    ok = np.zeros((6, 5, 3))
    sharded.append(ok)
    jump = np.zeros((6, 5, 3))
    jump[5, 0] = [9.0, 0.0, 0.0]  # the last shard's last character
    with pytest.raises(TrajectoryError, match="character 5: points: jumps 9.0 m in one frame"):
        sharded.append(jump)
    # Nothing was taken, by any shard: each has the 5 points of the first message.
    assert [p.n_inputs for p in sharded.parts] == [5, 5, 5]
    with pytest.raises(TrajectoryError, match=r"expected shape \(6, n >= 1, 3\)"):
        sharded.append(ok[:4])
    with pytest.raises(TrajectoryError, match=r"scales: expected 6 values"):
        LiveShards(bank, 6, 60.0, scales=[1.0, 1.0])
    with pytest.raises(TrajectoryError, match="character 4: scale: must be a positive number"):
        LiveShards(bank, 6, 60.0, shards=2, scales=[1, 1, 1, 1, -1, 1])


def test_frames_kept_from_earlier_windows_are_the_frames_posed_again(bank: Bank, herd: np.ndarray) -> None:
    """kernels.render_window reading what earlier windows posed (a live session's windows share most of
    their lock context: the feet, and the legs of the PAD frames before a window, which its sink
    reads; not the ankle's side of the last frame sent, kernels.Posed.sides, against which a flip is
    straightened) gives the numbers of posing each whole context again, to rounding: what is read was
    posed by another window's call, whose compiled path (a frame posed as sent or as context) may
    round a last bit differently -- seen once, on a fresh compile: 2 of 96,000 root numbers, 7e-17 m
    apart."""
    pytest.importorskip("numba")
    from synth_core.compiled import kernels
    from synth_core.runtime.footlock import PAD
    from synth_core.runtime.synthesis import plan, prepare_batch

    options = Options(seed=5, scale_range=(0.8, 1.2))
    prep, h, keys = prepare_batch(bank, herd, 60.0, None, options, None, None)
    p = plan(bank, prep, h, keys, options.margin, compiled=True)
    C, T = p.yaw.shape
    posed = kernels.Posed.none(C, np.empty((T, C, 4, 3)))
    read = windows = 0
    for a in range(0, T, 25):
        b = min(a + 25, T)
        begin, end = kernels.lock_context(p.contacts, a, b)
        # Frames not posed: those before the window with their feet known, when the last window
        # kept the legs of the PAD frames before it (else those PAD frames are posed).
        after_last = posed.legs_at == a
        assert after_last.all() == (a >= PAD)  # every window after the first keeps them
        first_posed = np.minimum(posed.frames, np.where(after_last, a, a - PAD))
        read += int(np.clip(first_posed - begin, 0, None).sum())
        got = kernels.render_window(bank, p, a, b, begin, end, True, posed)
        want = kernels.render_window(bank, p, a, b, begin, end, True)
        np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-6)
        np.testing.assert_allclose(got[1], want[1], rtol=0, atol=1e-6)
        assert (posed.frames == end).all()  # each character's feet known up to its context's end
        assert (posed.legs_at == b).all()
        windows += 1
    assert read > 20 * C * (windows - 1)  # after the first, none of a context's 20+ frames before it
    # A window that does not start where the last ended poses the PAD frames before it.
    a = T // 2
    begin, end = kernels.lock_context(p.contacts, a, a + 25)
    got = kernels.render_window(bank, p, a, a + 25, begin, end, True, posed)
    want = kernels.render_window(bank, p, a, a + 25, begin, end, True)
    np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-6)
    np.testing.assert_allclose(got[1], want[1], rtol=0, atol=1e-6)
    # A live session's known feet are always C-contiguous views (so one compiled kernel serves
    # every session: a new layout would compile one mid-session), one character's too.
    for n in (1, 3):
        LiveSynth(bank, n, 60.0).append(herd[:n, :300])
    at = list(inspect.signature(kernels._render_windows.py_func).parameters).index("known_feet")
    assert {str(sig[at]) for sig in kernels._render_windows.signatures} == {"array(float64, 4d, C)"}


def test_a_failing_shard_fails_the_tick_once_every_shard_is_done(bank: Bank,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """An unexpected error in one shard's thread reaches the caller -- once the other shards'
    work is over, none left running on the session's state."""
    import threading
    import time

    sharded = LiveShards(bank, 6, 60.0, shards=2)
    done = threading.Event()
    first, second = sharded.parts

    def fails(points: np.ndarray, frames: int | None) -> None:
        raise RuntimeError("shard 0 broke")

    def slow(points: np.ndarray, frames: int | None) -> None:
        time.sleep(0.3)
        done.set()

    monkeypatch.setattr(first, "append_checked", fails)
    monkeypatch.setattr(second, "append_checked", slow)
    with pytest.raises(RuntimeError, match="shard 0 broke"):
        sharded.append(np.zeros((6, 5, 3)))
    assert done.is_set()


def test_columns_keep_their_frames_through_moves_in_place_and_into_larger_arrays() -> None:
    cols = Columns(2, [((3,), np.float64)], room=8)
    frame, arrays_seen = 0, set()
    for n in (3, 3, 2, 5, 1, 12, 4, 30, 2):
        cols.reserve(n)[0][...] = np.arange(frame, frame + n)[None, :, None]  # each frame: its index
        frame += n
        arrays_seen.add(id(cols.arrays[0]))
        cols.drop_before(frame - 4)
        (kept,) = cols.columns(cols.start, cols.stop)
        assert cols.stop == frame and cols.frames == min(4, frame)
        want = np.arange(cols.start, cols.stop)
        np.testing.assert_array_equal(kept[:, :, 0], np.broadcast_to(want, (2, len(want))))
    assert len(arrays_seen) > 1  # it grew too
