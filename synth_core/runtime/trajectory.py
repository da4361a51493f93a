"""Trajectory preprocessing (Sung 2011, section 5): validate, smooth, resample, segment.

Input: one 3D root point per frame per character, ``(C, F, 3)`` metres, Y up, all characters
the same frame count at one frame rate. Steps, in the paper's order:

1. **Smooth** each path's timing with a Gaussian low-pass (``sigma`` frames) so a simulator's
   jitter does not become stride-by-stride speed changes -- along the path it sent, which the root
   follows (the simulator is the authority on where an agent is: :func:`gaussian.along_frames`);
   the body faces the way of the positions smoothed (:attr:`Prepared.facing`), which may lag.
2. **Segment** into ``m``-frame pieces (``m``: the library's mean gait cycle) and measure each
   piece's speed ``s = l / n`` (ground length over frames; reported in m/s) on the positions
   smoothed: the path sent zig-zags with a simulator's noise, and its length would read a
   standing agent jittering 1 mm a frame as walking at 0.07 m/s.
3. **Clock.** By default the simulator's clock is kept: one output frame per input frame (at the
   library's rate), whatever the speeds. A character (at its scale ``h``: it runs the library's
   motion at ``s / h``) faster than the library's fastest clip plays its fastest gait's stride
   faster, up to ``stride_rate`` times (synthesis' MAX_RATE); beyond that its feet cannot keep
   pace, and it gets a *warning* naming it, the frame and the speeds (its motion is still made).
   The paper's **resampling** is an option (``resample``): then, if any character is too fast,
   *every* trajectory is resampled by ``r = s_max / top`` -- time-uniformly, so each path keeps
   its shape and length, its point count grows by r, and the herd's formation is kept. Either
   way, a character faster than ``MAX_RESAMPLE`` times the top speed is refused (or, with
   ``skip_invalid``, dropped): a teleport or a unit mistake, not an animal.

Bad input raises :class:`TrajectoryError` naming the character and the problem, or, with
``skip_invalid``, drops that character and reports why (nobody else's work is lost).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from synth_core.runtime import gaussian

Floats = NDArray[np.float64]

DEFAULT_SIGMA = 4.0  # frames of Gaussian smoothing at the library's frame rate
TELEPORT_M = 5.0  # a jump longer than this between two frames is not locomotion
# Coordinates beyond this are refused: float32 root positions far out lose the centimetres a
# step is made of, and at |x| >= 1e16 headings and rotations came out zero-norm (issue 34).
MAX_COORDINATE_M = 1e6
ALL_INVALID = "every character was invalid"  # the refusal when skip_invalid leaves none
MAX_RESAMPLE = 8.0  # refuse trajectories needing more than 8x the frames
GROUND = [0, 2]  # the ground plane's axes (x, z): Y is up
# The same axes as a basic slice: indexing with it is a view, not numpy's gather of the list's
# (copying (C, F, 2) out of (C, F, 3) by a slice is 4x quicker: 0.8 vs 3.1 ms for 500 x 500; but
# np.diff of the strided view is slower than gathering first: segment_speeds gathers).
GROUND_AXES = slice(0, 3, 2)
ROWS = 256  # characters checked and smoothed at a time: their arrays stay in cache (a batch of
# 2,000 done at once cost twice as much per point as one of 500)
_R = TypeVar("_R")


@functools.cache
def _pool() -> ThreadPoolExecutor:
    return ThreadPoolExecutor(min(4, os.cpu_count() or 1), thread_name_prefix="trajectory")


def by_rows(work: Callable[[int], _R], n: int) -> list[_R]:
    """``work(a)`` for the rows ``[a, a + ROWS)`` of ``n`` characters, in order, on every core:
    scipy's filters and numpy release the GIL (smoothing 500 characters: 7.5 -> 4.1 ms on two
    cores, a tenth of a streamed batch's first chunk)."""
    starts = range(0, n, ROWS)
    if len(starts) == 1:
        return [work(0)]
    return list(_pool().map(work, starts))


class TrajectoryError(ValueError):
    """A trajectory the synthesis cannot use; ``character`` says whose (None: the whole batch)."""

    def __init__(self, message: str, character: int | str | None = None) -> None:
        super().__init__(message if character is None else f"character {character}: {message}")
        self.character, self.reason = character, message


class FrameLimitError(TrajectoryError):
    """The batch would come out with more character-frames than allowed, resampling included."""

    def __init__(self, characters: int, frames: int, rate: float, limit: int) -> None:
        super().__init__(f"{characters} characters x {frames} frames (paths resampled {rate:.4g}x) = "
                         f"{characters * frames} character-frames is over the limit of {limit}")
        self.characters, self.frames, self.rate, self.limit = characters, frames, rate, limit


@dataclass(frozen=True)
class Prepared:
    """Trajectories ready for synthesis, at the library's frame rate."""

    positions: Floats  # (C, F', 3) the path followed: the input's, its timing smoothed; resampled
    segment: int  # m, frames per segment
    segment_speeds: Floats  # (C, K) m/s, per segment, before scale
    resample_rate: float  # r >= 1 (1: not resampled)
    kept: NDArray[np.int64]  # indices of the input characters kept
    rejected: dict[int, str] = field(default_factory=dict)  # input index -> why it was skipped
    warnings: dict[int, str] = field(default_factory=dict)  # input index -> what could not be kept
    tempo: Floats | None = None  # (C,) each character's stride-frequency factor (None: all 1)
    facing: Floats | None = None  # (C, F', 3) the positions smoothed, whose way the body faces
    # (None: the path followed's)

    def rows(self, rows: slice) -> Prepared:
        """The characters ``rows`` alone (a chunk or part of the batch)."""
        return replace(self, positions=self.positions[rows], segment_speeds=self.segment_speeds[rows],
                       tempo=None if self.tempo is None else self.tempo[rows],
                       facing=None if self.facing is None else self.facing[rows])


def check(positions: ArrayLike, fps: float, ids: list[str] | None = None) -> NDArray[np.floating]:
    """The batch as a ``(C, F, 3)`` float array (float32 stays float32: it is converted a few
    characters at a time), or :class:`TrajectoryError` for the whole batch."""
    if not (isinstance(fps, int | float) and np.isfinite(fps) and fps > 0):
        raise TrajectoryError(f"fps: must be a positive number, got {fps!r}")
    try:
        arr = np.asarray(positions)
        if arr.dtype not in (np.float32, np.float64):
            arr = np.asarray(arr, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TrajectoryError(f"positions: not an array of numbers ({exc})") from None
    if arr.ndim != 3 or arr.shape[-1] != 3:
        raise TrajectoryError(f"positions: expected shape (characters, frames, 3), got {arr.shape}")
    if arr.shape[0] == 0:
        raise TrajectoryError("positions: no characters")
    if ids is not None and len(ids) != arr.shape[0]:
        raise TrajectoryError(f"ids: {len(ids)} ids for {arr.shape[0]} trajectories")
    return arr


def resampled_frames(frames: int, rate: float) -> int:
    """Frames of a path of ``frames`` resampled ``rate`` times (whole frames, rounded up). A rate
    reported by another batch, (n - 1) / (F - 1), must give back n here: hence the slack."""
    return int(np.ceil((frames - 1) * rate - 1e-9)) + 1 if rate > 1.0 else frames


def problems(positions: NDArray[np.floating], fps: float) -> dict[int, str]:
    """Per character index, what is wrong with its trajectory (none: absent)."""
    if positions.shape[1] < 2:
        return {c: f"needs at least 2 points, got {positions.shape[1]}" for c in range(len(positions))}

    def rows(a: int) -> dict[int, str]:
        found: dict[int, str] = {}
        part = np.asarray(positions[a:a + ROWS], np.float64)
        finite = np.isfinite(part).all(axis=(1, 2))
        for c in np.flatnonzero(~finite):
            frame = int(np.flatnonzero(~np.isfinite(part[c]).all(axis=-1))[0])
            found[a + int(c)] = f"positions: NaN or Inf at frame {frame}"
        far = finite & (np.abs(part).max(axis=(1, 2), initial=0.0) > MAX_COORDINATE_M)
        for c in np.flatnonzero(far):
            frame = int(np.flatnonzero(np.abs(part[c]).max(axis=-1) > MAX_COORDINATE_M)[0])
            found[a + int(c)] = (f"positions: {np.abs(part[c, frame]).max():.3g} m at frame {frame} is "
                                 f"beyond the range of +-{MAX_COORDINATE_M:g} m (metres from the origin)")
        finite &= ~far
        d = np.diff(part if finite.all() else np.where(finite[:, None, None], part, 0.0), axis=1)
        jump = np.einsum("cfk,cfk->cf", d, d).max(axis=1) > TELEPORT_M**2
        for c in np.flatnonzero(finite & jump):
            step = np.linalg.norm(d[c], axis=-1)
            frame = int(step.argmax())
            found[a + int(c)] = (f"positions: jumps {step[frame]:.1f} m between frames {frame} and "
                                 f"{frame + 1} (limit {TELEPORT_M} m per frame: a teleport, not locomotion)")
        return found

    return {c: why for found in by_rows(rows, len(positions)) for c, why in found.items()}


def retime(positions: Floats, fps: float, target_fps: float) -> Floats:
    """Time-uniform linear resampling from ``fps`` to ``target_fps`` (same duration)."""
    if abs(fps - target_fps) < 1e-9:
        return positions
    F = positions.shape[1]
    n = max(2, int(round((F - 1) * target_fps / fps)) + 1)
    return resample(positions, n)


def resample(positions: Floats, n: int) -> Floats:
    """Every path resampled to ``n`` points, uniformly in time: same shape, same length."""
    F = positions.shape[1]
    t = np.linspace(0.0, F - 1, n)
    i0 = np.clip(np.floor(t).astype(np.int64), 0, F - 2)
    w = (t - i0)[None, :, None]
    return np.asarray(positions[:, i0] * (1 - w) + positions[:, i0 + 1] * w)


def smooth(positions: Floats, sigma: float, keep_shape: bool = False) -> Floats:
    """Gaussian low-pass along frames (``keep_shape``: of the timing only, the points kept on the
    path: :func:`gaussian.along_frames`). The ends are extended by point reflection (a path going
    on as it went), so a path at steady speed keeps its end points and its length."""
    if sigma <= 0:
        return positions
    F = positions.shape[1]
    pad = min(F - 1, int(np.ceil(4 * sigma)))
    head = 2 * positions[:, :1] - positions[:, pad:0:-1]
    tail = 2 * positions[:, -1:] - positions[:, -2:-2 - pad:-1]
    longer = np.concatenate([head, positions, tail], axis=1)
    return (gaussian.along_frames if keep_shape else gaussian.smooth_frames)(longer, sigma, pad, F)


def segment_speeds(positions: Floats, m: int, fps: float, along_ground: bool = False) -> Floats:
    """(C, K) ground speed of each m-frame segment, m/s (the last may be shorter);
    ``along_ground``: along the path's slope, not over the map (positions on a terrain)."""
    axes = slice(None) if along_ground else GROUND
    step = np.linalg.norm(np.diff(positions[..., axes], axis=1), axis=-1)  # (C, F-1)
    F1 = step.shape[1]
    K = max(1, -(-F1 // m))
    padded = np.zeros((step.shape[0], K * m))
    padded[:, :F1] = step
    counts = np.minimum(m, F1 - np.arange(K) * m).clip(min=1)
    return np.asarray(padded.reshape(-1, K, m).sum(axis=2) / counts * fps)


def smooth_and_measure(positions: NDArray[np.floating], kept: NDArray[np.int64], fps: float,
                       library_fps: float, sigma: float, segment: int) -> tuple[Floats, Floats, Floats]:
    """The ``kept`` characters' paths at the library's frame rate, followed (their timing
    smoothed) and smoothed (:func:`smooth`), and the smoothed paths' segment speeds -- ``ROWS``
    characters at a time (:func:`by_rows`), so no array the size of the batch is made but the
    results: fresh memory costs 0.5-2 ms per MB to first touch on a VM, and a batch of 10,000
    spent 1.9 s making six such arrays."""
    F = retime(np.asarray(positions[kept[:1]], np.float64), fps, library_fps).shape[1]
    followed, smoothed = np.empty((len(kept), F, 3)), np.empty((len(kept), F, 3))

    def rows(a: int) -> Floats:
        part = retime(np.asarray(positions[kept[a:a + ROWS]], np.float64), fps, library_fps)
        followed[a:a + ROWS] = smooth(part, sigma, keep_shape=True)
        smoothed[a:a + ROWS] = smooth(part, sigma)
        return segment_speeds(smoothed[a:a + ROWS], segment, library_fps)

    return followed, smoothed, np.concatenate(by_rows(rows, len(kept)))


def resample_and_measure(followed: Floats, smoothed: Floats, frames: int, segment: int,
                         fps: float) -> tuple[Floats, Floats, Floats]:
    """Both paths resampled to ``frames`` points, and the smoothed ones' segment speeds (``ROWS``
    characters at a time, as :func:`smooth_and_measure`)."""
    out, facing = np.empty((len(followed), frames, 3)), np.empty((len(followed), frames, 3))

    def rows(a: int) -> Floats:
        out[a:a + ROWS] = resample(followed[a:a + ROWS], frames)
        facing[a:a + ROWS] = resample(smoothed[a:a + ROWS], frames)
        return segment_speeds(facing[a:a + ROWS], segment, fps)

    return out, facing, np.concatenate(by_rows(rows, len(followed)))


# Arguments as synthesis.prepare_batch passes them (positionally); an options object is for when
# that caller changes too.
def prepare(positions: ArrayLike, fps: float, library_fps: float, top_speed: float,  # noqa: PLR0913, PLR0917
            segment: int,
            scales: NDArray[np.floating], sigma: float = DEFAULT_SIGMA,
            skip_invalid: bool = False, ids: list[str] | None = None,
            min_rate: float = 1.0, resample: bool = False, stride_rate: float = 1.0,
            tempo: NDArray[np.floating] | None = None, max_character_frames: int | None = None) -> Prepared:
    """Validate, bring to the library's frame rate, smooth, resample if asked (``resample``: where
    a character is too fast; and at least by ``min_rate``), segment. ``stride_rate``: how much
    faster than its fastest clip a gait's stride may play (a character faster than that at its
    scale gets a warning when the clock is kept). ``tempo (C,)``: each character's stride
    frequency factor k (it asks the library for ``s / (h k)``; default 1). :class:`FrameLimitError`
    before resampling when the kept characters would come out with more than
    ``max_character_frames`` frames in all."""
    arr = check(positions, fps, ids)
    _check_rates(sigma, min_rate)
    scales = np.asarray(scales, dtype=np.float64)
    names = ids or [str(c) for c in range(len(arr))]
    bad, kept = _valid(arr, fps, scales, names, skip_invalid)
    followed, smoothed, speeds = smooth_and_measure(arr, kept, fps, library_fps, sigma, segment)
    pace = scales if tempo is None else scales * np.asarray(tempo, np.float64)
    own = speeds / pace[kept, None]  # (C, K) the library's speed each character asks for
    unfit = _too_fast(own, MAX_RESAMPLE * top_speed, segment)
    if unfit:
        why = {int(kept[i]): (f"positions: moves at {s:.1f} m/s for its scale at frame {f}, more than "
                              f"{MAX_RESAMPLE:g}x the library's fastest {top_speed:.2f} m/s (check the "
                              f"unit: metres, and the fps)") for i, (f, s) in unfit.items()}
        if not skip_invalid:
            first = min(why)
            raise TrajectoryError(why[first], names[first])
        bad.update(why)
        stay = np.setdiff1d(np.arange(len(kept)), list(unfit))
        if len(stay) == 0:
            raise TrajectoryError(ALL_INVALID + ": " +
                                  "; ".join(f"{names[c]}: {w}" for c, w in sorted(bad.items())))
        kept, followed, smoothed = kept[stay], followed[stay], smoothed[stay]
        speeds, own = speeds[stay], own[stay]
    rate = max(1.0, float(own.max()) / top_speed) if resample else 1.0
    warnings = _too_fast_to_step(own, kept, top_speed, stride_rate, segment) if rate == 1.0 else {}
    rate = max(rate, min_rate)
    F = followed.shape[1]
    n = resampled_frames(F, rate)
    if max_character_frames is not None and n * len(kept) > max_character_frames:
        raise FrameLimitError(len(kept), n, rate, max_character_frames)
    if rate > 1.0:
        rate = (n - 1) / (F - 1)  # what it really is after rounding to whole frames
        # The paper's order: the smoothed paths are resampled (not the raw ones smoothed again:
        # that smoothed every resampled batch twice, a seventh of its synthesis time).
        followed, smoothed, speeds = resample_and_measure(followed, smoothed, n, segment, library_fps)
    return Prepared(followed, segment, speeds, float(rate), kept, bad, warnings,
                    None if tempo is None else np.asarray(tempo, np.float64)[kept], smoothed)


def _check_rates(sigma: float, min_rate: float) -> None:
    if not (np.isfinite(sigma) and 0 <= sigma <= 100):
        raise TrajectoryError(f"sigma: must be within [0, 100] frames, got {sigma}")
    if not (np.isfinite(min_rate) and 1.0 <= min_rate <= MAX_RESAMPLE):
        raise TrajectoryError(f"min_resample_rate: must be within [1, {MAX_RESAMPLE:g}], got {min_rate}")


def _valid(arr: NDArray[np.floating], fps: float, scales: NDArray[np.floating], names: list[str],
           skip_invalid: bool) -> tuple[dict[int, str], NDArray[np.int64]]:
    """The characters with a problem (index -> why) and those kept; a problem raises unless
    ``skip_invalid``, and so does having none left."""
    bad = problems(arr, fps)
    for i in np.flatnonzero(~(np.isfinite(scales) & (scales > 0))):
        bad.setdefault(int(i), f"scale: must be a positive number, got {scales[i]}")
    if bad and not skip_invalid:
        worst = min(bad)
        raise TrajectoryError(bad[worst], names[worst])
    kept = np.array([c for c in range(len(arr)) if c not in bad], dtype=np.int64)
    if len(kept) == 0:
        raise TrajectoryError(ALL_INVALID + ": " +
                              "; ".join(f"{names[c]}: {why}" for c, why in sorted(bad.items())))
    return bad, kept


def _too_fast_to_step(own: Floats, kept: NDArray[np.int64], top_speed: float, stride_rate: float,
                      segment: int) -> dict[int, str]:
    """Warnings for the characters faster than the library's fastest stride can step (the clock
    kept): character -> why."""
    limit = stride_rate * top_speed
    return {int(kept[i]): (f"moves at {s:.1f} m/s for its scale at frame {f}, faster than the "
                           f"library's fastest gait can step ({top_speed:.2f} m/s, its stride up "
                           f"to {stride_rate:g}x faster: {limit:.2f} m/s): its feet slide there; "
                           f"'resample' slows the herd's clock instead")
            for i, (f, s) in _too_fast(own, limit, segment).items()}


def _too_fast(speeds: Floats, limit: float, segment: int) -> dict[int, tuple[int, float]]:
    """Rows of ``speeds (C, K)`` (segment speeds) over ``limit``: row -> (the first such segment's
    first frame, the row's top speed)."""
    over = speeds > limit * (1 + 1e-9)
    rows = np.flatnonzero(over.any(axis=1))
    return {int(c): (int(over[c].argmax()) * segment, float(speeds[c].max())) for c in rows}
