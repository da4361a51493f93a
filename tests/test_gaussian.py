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
