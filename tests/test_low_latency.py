"""The low-latency live mode (issue 31): poses within the latency budget, counted in frames of
lag between the last point received and the last pose sent; feet planted after FK; the causal
fits it smooths with."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from api_schemas import LiveRequest, models
from synth_core.motion.contacts import runs
from synth_core.quality import evaluate
from synth_core.quality import herd_sim as crowd
from synth_core.quality.live_run import play
from synth_core.quality.reference import library_reference
from synth_core.runtime import causal, gaussian, live
from synth_core.runtime.bank import Bank
from synth_core.runtime.live import LiveSynth
from synth_core.runtime.live_shards import LiveShards
from synth_core.runtime.trajectory import TrajectoryError


@pytest.fixture(scope="module")
def herd() -> np.ndarray:
    return crowd.simulate(10, 600, seed=21)


@pytest.mark.parametrize("latency_ms", [50.0, 150.0, 400.0])
def test_poses_lag_their_points_by_the_budget_at_most(bank: Bank, herd: np.ndarray,
                                                      latency_ms: float) -> None:
    run = play(bank, herd, latency_ms=latency_ms, points_per_tick=3)
    budget = int(latency_ms * bank.fps / 1000)
    assert run.latency_frames == budget
    assert run.lags.max() <= budget  # never later than the budget, a tick after another
    assert run.lags[len(run.lags) // 2:].min() >= budget - 3  # and no frame held back for nothing
    assert LiveSynth(bank, 2, bank.fps).latency_frames > 5 * budget  # the exact mode: seconds late


def test_points_at_30_fps_come_back_within_the_budget(bank: Bank) -> None:
    herd = crowd.simulate(4, 300, seed=5, fps=30.0)
    synth = LiveSynth(bank, 4, 30.0, latency_ms=150.0)
    lags = []
    for i in range(herd.shape[1]):  # a point a tick: a 30 fps simulator
        synth.append(herd[:, i:i + 1])
        lags.append(2 * i + 1 - synth.rendered)  # library frames: the last point received is 2 i
    assert max(lags) <= synth.latency_frames == 9
    assert synth.finish() is not None and synth.rendered == 2 * herd.shape[1] - 1


def test_feet_stay_planted_after_fk(bank: Bank, herd: np.ndarray) -> None:
    run = play(bank, herd, seed=2, latency_ms=150.0)
    figures = evaluate.edge_figures(bank, run.result, herd, herd.shape[1], library_reference(bank))
    assert figures["strict_skate_mm_p95"] <= 5.0  # issue 31's targets
    assert figures["glide_ratio"] <= 0.12
    assert figures["nan_count"] == 0
    assert len(set(run.result.gait.ravel().tolist())) >= 4  # it moved through the gaits


def test_a_budget_out_of_range_is_refused_naming_it(bank: Bank) -> None:
    with pytest.raises(TrajectoryError, match=r"latency_ms: must be within \[50, 2000\] ms"):
        LiveSynth(bank, 2, 60.0, latency_ms=10.0)
    with pytest.raises(TrajectoryError, match="latency_ms"):
        LiveSynth(bank, 2, 60.0, latency_ms=float("nan"))
    assert (models.LATENCY_MS, models.LOW_LATENCY_MS) == (live.LATENCY_MS, live.LOW_LATENCY_MS)


def test_the_live_request_names_the_field_and_its_limits() -> None:
    chars = [{"id": "a"}]
    with pytest.raises(ValidationError, match="latency_ms"):
        LiveRequest.model_validate({"characters": chars, "latency_ms": 20})
    with pytest.raises(ValidationError, match="latency_ms\n  Value error, only with mode low_latency"):
        LiveRequest.model_validate({"characters": chars, "mode": "exact", "latency_ms": 200})
    with pytest.raises(ValidationError, match="mode"):
        LiveRequest.model_validate({"characters": chars, "mode": "fast"})
    assert LiveRequest.model_validate({"characters": chars}).budget_ms is None
    assert LiveRequest.model_validate({"characters": chars, "mode": "low_latency"}).budget_ms == 100.0
    assert LiveRequest.model_validate({"characters": chars, "latency_ms": 80}).budget_ms == 80.0


def test_the_fit_follows_a_steady_path_without_lag() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(80.0)
    steady = np.stack([0.25 * t + 3, np.zeros_like(t), -0.1 * t], axis=-1)[None]
    for behind, ahead in ((16, 0), (16, 4), (24, 2)):
        value, slope = causal.fit_weights(4.0, behind, ahead)
        got = causal.apply(steady, value, behind, 30, 40)
        np.testing.assert_allclose(got, steady[:, 30:70], atol=1e-9)  # no lag on a straight line
        np.testing.assert_allclose(causal.apply(steady, slope, behind, 30, 40)[0],
                                   np.broadcast_to([0.25, 0.0, -0.1], (40, 3)), atol=1e-9)
        noisy = steady + rng.normal(0, 0.05, steady.shape)
        assert np.std(causal.apply(noisy, value, behind, 30, 40) - steady[:, 30:70]) < 0.05  # noise averaged
    # Read symmetrically, the fit's value is the Gaussian the batch smooths with.
    value, _ = causal.fit_weights(4.0, 16, 16)
    kernel = gaussian.weights(4.0)
    np.testing.assert_allclose(value, np.concatenate([kernel[:0:-1], kernel]), atol=1e-12)


def _targets(feet: np.ndarray, contacts: np.ndarray, most: int, compiled: bool = True) -> np.ndarray:
    """foot_kernels.plant_targets of one character (compiled, or its source interpreted)."""
    from synth_core.compiled import foot_kernels
    run = foot_kernels.plant_targets if compiled else getattr(foot_kernels.plant_targets, "py_func",
                                                              foot_kernels.plant_targets)
    out = np.empty(feet.shape)
    run(feet, contacts, out, most)
    return out


def test_a_plants_target_can_average_its_first_frames_only() -> None:
    rng = np.random.default_rng(3)
    feet = rng.normal(size=(40, 4, 3))
    contacts = rng.random((40, 4)) < 0.7
    for most in (1, 3, 1000):
        got = _targets(feet, contacts, most)
        np.testing.assert_allclose(_targets(feet, contacts, most, compiled=False), got, atol=1e-12)
        for f in range(4):  # each plant at the average of its first `most` frames
            for start, stop in runs(contacts[:, f]):
                want = feet[start:min(stop, start + most), f].mean(axis=0)
                np.testing.assert_allclose(got[start:stop, f], np.broadcast_to(want, (stop - start, 3)),
                                           atol=1e-12)
    # A plant's target is its first frame's foot with most=1: what frames after it hold changes nothing.
    later = feet.copy()
    later[1:] += 1.0
    first = contacts[0] & contacts[1]
    np.testing.assert_allclose(_targets(later, contacts, 1)[1][first], feet[0][first], atol=1e-12)


def test_shards_make_the_low_latency_sessions_frames(bank: Bank, herd: np.ndarray) -> None:
    whole = LiveSynth(bank, len(herd), 60.0, seed=4, latency_ms=100.0)
    shards = LiveShards(bank, len(herd), 60.0, seed=4, shards=3, latency_ms=100.0)
    assert shards.latency_frames == whole.latency_frames
    for i in range(0, 300, 7):
        a, b = whole.append(herd[:, i:i + 7]), shards.append(herd[:, i:i + 7])
        assert (a is None) == (b is None)
        if a is not None and b is not None:
            joined = np.concatenate([w.root_pos for w in b])
            np.testing.assert_array_equal(joined, a.root_pos)
            np.testing.assert_array_equal(np.concatenate([w.gait for w in b]), a.gait)
