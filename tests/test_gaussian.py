"""The compiled Gaussian smoothing (synth_core.runtime.gaussian) is scipy's, bit for bit: the batch's and
the live mode's paths depend on it."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from synth_core.compiled import kernels
from synth_core.runtime import gaussian


@pytest.mark.parametrize("sigma", [0.6, 2.3, 4.0, 7.9])
def test_frames_are_scipys_bit_for_bit(sigma: float) -> None:
    rng = np.random.default_rng(int(sigma * 10))
    x = rng.normal(size=(7, 90, 3)) * 50 + 1e3  # far from the origin, as herds are
    whole = gaussian_filter1d(x, sigma, axis=1, mode="nearest")
    r = len(gaussian.weights(sigma)) - 1
    assert r == int(4 * sigma + 0.5)
    for first, n in ((r, 90 - 2 * r), (r + 5, 11), (0, 90), (90 - r - 1, 1), (3, 40)):  # some reach an end
        np.testing.assert_array_equal(gaussian.smooth_frames(x, sigma, first, n), whole[:, first:first + n])


def test_weights_sum_to_one_and_fall_off() -> None:
    w = gaussian.weights(4.0)
    assert len(w) == 17 and abs(w[0] + 2 * w[1:].sum() - 1.0) < 1e-12 and (np.diff(w) < 0).all()
    with pytest.raises(ValueError, match="read-only"):
        w[0] = 1.0  # shared by every caller: read-only


@pytest.mark.skipif(not kernels.AVAILABLE, reason="numba not installed")
def test_compiled_where_the_windows_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    """Frames whose windows lie inside are made by the compiled kernel; reaching an end, by
    scipy (its mode='nearest' extends the ends)."""
    x = np.random.default_rng(1).normal(size=(4, 60, 3))
    want = gaussian_filter1d(x, 4.0, axis=1, mode="nearest")
    gaussian.weights(4.0)  # cached before scipy is taken away

    def no_scipy(*args: object, **kwargs: object) -> None:
        raise AssertionError("scipy was called")

    monkeypatch.setattr(gaussian, "gaussian_filter1d", no_scipy)
    np.testing.assert_array_equal(gaussian.smooth_frames(x, 4.0, 16, 28), want[:, 16:44])
    with pytest.raises(AssertionError, match="scipy was called"):
        gaussian.smooth_frames(x, 4.0, 15, 28)


@pytest.mark.parametrize("sigma", [1e-308, 1e-200, 1e-3])
def test_a_vanishing_sigma_smooths_nothing_and_does_not_fail(sigma: float) -> None:
    x = np.random.default_rng(0).normal(size=(2, 30, 3))
    np.testing.assert_array_equal(gaussian.smooth_frames(x, sigma, 5, 20), x[:, 5:25])


def _circle(frames: int, radius: float, rad_per_frame: float) -> np.ndarray:
    a = np.arange(frames) * rad_per_frame
    return np.stack([radius * np.sin(a), np.zeros(frames), radius * (1 - np.cos(a))], axis=-1)[None]


def test_along_the_path_a_tight_fast_arc_keeps_its_radius() -> None:
    """Issue 27: a 0.5 m circle at a horse's gallop (7.7 m/s, 60 fps: 15 deg a frame). Smoothing
    its points pulls them 18 cm inside; smoothing its timing keeps them on the arc (within the
    0.42 cm sagitta of the 60 fps polyline sent, well inside the issue's 1 cm)."""
    x = _circle(120, 0.5, 7.7 / 60 / 0.5)
    off = np.abs(np.hypot(x[..., 0], x[..., 2] - 0.5) - 0.5)[:, 20:100]
    moved = np.hypot(*(gaussian.smooth_frames(x, 4.0, 20, 80) - x[:, 20:100])[..., [0, 2]].T)
    assert moved.max() > 0.1  # the positions smoothed: inside by > 10 cm
    kept = gaussian.along_frames(x, 4.0, 20, 80)
    radius = np.hypot(kept[..., 0], kept[..., 2] - 0.5)
    assert np.abs(radius - 0.5).max() <= 0.5 * (1 - np.cos(7.7 / 60 / 0.5 / 2)) + 1e-9 and off.max() < 1e-9


def test_along_the_path_a_held_input_moves_at_an_even_pace() -> None:
    """A 10 Hz simulator at 60 fps (each point held 6 frames) along a line: the point stays on the
    line and its speed, which jumps 0 -> 6x, is even within 1 % (a Gaussian of sigma 4 frames leaves
    exp(-(2 pi 4 / 6)^2 / 2) = 1.5e-4 of a 6-frame ripple)."""
    x = np.zeros((1, 120, 3))
    x[0, :, 2] = (np.arange(120) // 6) * 6 * 0.02  # 1.2 m/s held in 12 cm steps
    x[0, :, 0] = 3.0
    out = gaussian.along_frames(x, 4.0, 20, 80)
    assert np.array_equal(out[..., 0], np.full((1, 80), 3.0)) and (out[..., 1] == 0).all()
    speed = np.diff(out[0, :, 2])
    assert (speed > 0).all() and np.abs(speed / speed.mean() - 1).max() < 0.01


def test_along_the_path_a_window_gives_the_whole_paths_frames_bit_for_bit() -> None:
    """Each frame reads its own neighbours only (a live session smooths a window at a time)."""
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.normal(size=(5, 90, 3)) * [0.1, 0.01, 0.1], axis=1) + 1e3
    whole = gaussian.along_frames(x, 4.0, 16, 58)
    for a, n in ((16, 10), (30, 5), (40, 34)):
        part = x[:, a - 16:a + n + 16]
        np.testing.assert_array_equal(gaussian.along_frames(part, 4.0, 16, n), whole[:, a - 16:a - 16 + n])
