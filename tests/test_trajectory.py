"""Trajectory preprocessing (paper section 5): errors naming the character, smoothing, resampling."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.runtime.trajectory import ROWS, TELEPORT_M, TrajectoryError, prepare, segment_speeds, smooth


def line(frames: int, speed: float, fps: float = 60.0, offset: float = 0.0) -> np.ndarray:
    z = np.arange(frames) * speed / fps
    return np.stack([np.full(frames, offset), np.zeros(frames), z], axis=-1)


def test_segment_speeds_are_length_over_frames() -> None:
    paths = np.stack([line(120, 2.0), line(120, 5.0)])
    speeds = segment_speeds(paths, 40, 60.0)
    assert speeds.shape == (2, 3)
    assert np.allclose(speeds, [[2.0] * 3, [5.0] * 3])


def test_resampling_keeps_every_path_length_and_the_formation() -> None:
    t = np.arange(200) / 60.0
    speed = 1.0 + 0.8 * np.sin(t)  # m/s, smooth
    heading = 0.3 * t
    step = np.stack([np.sin(heading), 0 * t, np.cos(heading)], axis=-1) * (speed / 60.0)[:, None]
    base = np.cumsum(step, axis=0)[None]
    herd = base + np.array([[0, 0, 0], [2, 0, 0], [0, 0, 3]])[:, None]  # three in formation
    fast = prepare(herd, 60.0, 60.0, top_speed=1.0, segment=40, scales=np.ones(3), sigma=0.0, resample=True)
    assert fast.resample_rate == pytest.approx(segment_speeds(herd, 40, 60.0).max(), rel=0.01)
    assert fast.resample_rate > 1.0
    assert fast.positions.shape[1] == round(199 * fast.resample_rate) + 1
    length = lambda p: np.linalg.norm(np.diff(p[..., [0, 2]], axis=1), axis=-1).sum(axis=1)  # noqa: E731
    assert np.allclose(length(fast.positions), length(herd), rtol=0.02)
    gap = fast.positions - fast.positions[:1]  # the formation: same offsets at every frame
    assert np.allclose(gap[1], [2, 0, 0], atol=1e-9) and np.allclose(gap[2], [0, 0, 3], atol=1e-9)
    assert segment_speeds(fast.positions, 40, 60.0).max() <= 1.02
    slow = prepare(herd, 60.0, 60.0, top_speed=100.0, segment=40, scales=np.ones(3), sigma=0.0, resample=True)
    assert slow.resample_rate == 1.0 and slow.positions.shape == herd.shape


def test_the_clock_is_kept_and_a_character_too_fast_even_at_the_stride_limit_is_warned_of() -> None:
    """By default no resampling: one frame out per frame in. A character faster than the
    library's top speed times the stride limit is named with the frame and speeds; one within
    the limit (its stride plays faster) is not; the others' paths are untouched."""
    herd = np.stack([line(300, 2.0), line(300, 3.5, offset=2.0), line(300, 5.0, offset=4.0)])
    herd[2, 150:] = herd[2, 150] + (herd[2, 150:] - herd[2, 150]) * 1.6  # 8 m/s from frame 150
    out = prepare(herd, 60.0, 60.0, top_speed=3.0, segment=40, scales=np.ones(3), sigma=0.0, stride_rate=1.6)
    assert out.resample_rate == 1.0 and out.positions.shape == herd.shape
    assert list(out.warnings) == [2]  # 3.5 m/s is within 3.0 x 1.6; 5 and then 8 m/s are not
    why = out.warnings[2]
    assert "at frame 0" in why and "8.0 m/s" in why and "4.80 m/s" in why and "resample" in why
    assert np.allclose(out.positions[:2], herd[:2])
    paper = prepare(herd, 60.0, 60.0, top_speed=3.0, segment=40, scales=np.ones(3), sigma=0.0,
                    stride_rate=1.6, resample=True)
    assert paper.resample_rate > 2.5 and paper.warnings == {}  # resampled: slow enough for the library


def test_a_character_no_animal_could_follow_is_refused_alone() -> None:
    """Faster than MAX_RESAMPLE x the library's top speed: an error naming the character, or
    with skip_invalid that character skipped and the others kept."""
    herd = np.stack([line(200, 2.0), line(200, 40.0, offset=2.0), line(200, 1.0, offset=4.0)])
    with pytest.raises(TrajectoryError, match=r"character 1: .*moves at 40.0 m/s .* at frame 0") as exc:
        prepare(herd, 60.0, 60.0, top_speed=3.0, segment=40, scales=np.ones(3), sigma=0.0)
    assert exc.value.character == "1"
    out = prepare(herd, 60.0, 60.0, top_speed=3.0, segment=40, scales=np.ones(3), sigma=0.0,
                  skip_invalid=True)
    assert list(out.kept) == [0, 2] and list(out.rejected) == [1] and out.positions.shape == (2, 200, 3)
    assert np.allclose(out.positions, herd[[0, 2]])


def test_the_smoothed_paths_are_resampled_in_the_papers_order() -> None:
    """Smooth, measure, then resample the smoothed paths (each point on the smoothed path's
    polyline, time-uniformly), with segment speeds measured on the smoothed positions returned."""
    rng = np.random.default_rng(4)
    herd = np.stack([line(300, 2.0), line(300, 3.0, offset=1.0)])
    herd += rng.normal(0, 0.01, (2, 300, 3)) * [1, 0, 1]
    once = prepare(herd, 60.0, 60.0, 10.0, 40, np.ones(2), sigma=3.0)
    longer = prepare(herd, 60.0, 60.0, 10.0, 40, np.ones(2), sigma=3.0, min_rate=1.5)
    n = longer.positions.shape[1]
    assert n == 1 + int(np.ceil(299 * 1.5))  # whole frames: the rate is what they make
    assert once.resample_rate == 1.0 and longer.resample_rate == (n - 1) / 299
    t = np.linspace(0, 299, n)
    for c in range(2):
        want = np.stack([np.interp(t, np.arange(300), once.positions[c, :, k]) for k in range(3)], axis=-1)
        assert np.allclose(longer.positions[c], want, atol=1e-12)
    # Speeds on the positions smoothed (facing), not on the followed path's noisy zig-zag.
    assert longer.facing is not None
    assert np.array_equal(longer.segment_speeds, segment_speeds(longer.facing, 40, 60.0))


def test_a_batch_of_many_row_blocks_keeps_its_order_and_its_errors() -> None:
    """Checked and smoothed ROWS characters at a time, the blocks on every core: each character's
    result and each error land at its own index."""
    rng = np.random.default_rng(5)
    C = 2 * ROWS + 37
    herd = np.stack([line(120, 1.0 + 2.0 * rng.random(), offset=3.0 * c) for c in range(C)])
    herd += rng.normal(0, 0.01, herd.shape) * [1, 0, 1]
    herd[ROWS + 3, 50] = np.nan
    herd[C - 1, 80:] += [2 * TELEPORT_M, 0, 0]
    out = prepare(herd, 60.0, 60.0, 10.0, 40, np.ones(C), sigma=2.0, skip_invalid=True)
    assert sorted(out.rejected) == [ROWS + 3, C - 1]
    assert "NaN or Inf at frame 50" in out.rejected[ROWS + 3] and "jumps" in out.rejected[C - 1]
    assert list(out.kept) == [c for c in range(C) if c not in (ROWS + 3, C - 1)]
    for i in (0, ROWS - 1, ROWS + 3, 2 * ROWS, len(out.kept) - 1):
        alone = prepare(herd[out.kept[i]][None], 60.0, 60.0, 10.0, 40, np.ones(1), sigma=2.0)
        assert np.array_equal(out.positions[i], alone.positions[0])
        assert np.array_equal(out.segment_speeds[i], alone.segment_speeds[0])


def test_big_characters_are_judged_at_their_own_scale() -> None:
    """A horse twice the size runs the library's motion at half the speed: no resampling."""
    path = line(100, 6.0)[None]
    assert prepare(path, 60.0, 60.0, 4.0, 40, np.array([1.0]), sigma=0.0, resample=True).resample_rate > 1.4
    assert prepare(path, 60.0, 60.0, 4.0, 40, np.array([2.0]), sigma=0.0, resample=True).resample_rate == 1.0


def test_other_frame_rates_are_brought_to_the_librarys() -> None:
    out = prepare(line(31, 2.0, fps=30.0)[None], 30.0, 60.0, 10.0, 40, np.ones(1), sigma=0.0)
    assert out.positions.shape[1] == 61
    assert np.allclose(segment_speeds(out.positions, 40, 60.0), 2.0)


def test_smoothing_removes_jitter_but_keeps_the_ends() -> None:
    rng = np.random.default_rng(1)
    path = line(200, 2.0)[None] + rng.normal(0, 0.02, (1, 200, 3)) * [1, 0, 1]
    out = smooth(path, 4.0)
    assert np.abs(np.diff(out[0, :, 0], 2)).max() < np.abs(np.diff(path[0, :, 0], 2)).max() / 5
    assert np.allclose(out[0, [0, -1], 2], path[0, [0, -1], 2], atol=0.05)


@pytest.mark.parametrize(("edit", "message"), [
    (lambda p: p.__setitem__((1, 5, 0), np.nan), r"character b: positions: NaN or Inf at frame 5"),
    (lambda p: p.__setitem__((2, slice(50, None), 2), 100.0),
     r"character c: positions: jumps .* m between frames 49 and 50"),
])
def test_bad_characters_are_named_or_skipped(edit, message: str) -> None:
    paths = np.stack([line(100, 2.0, offset=k) for k in range(3)])
    edit(paths)
    with pytest.raises(TrajectoryError, match=message):
        prepare(paths, 60.0, 60.0, 10.0, 40, np.ones(3), ids=["a", "b", "c"])
    kept = prepare(paths, 60.0, 60.0, 10.0, 40, np.ones(3), skip_invalid=True, ids=["a", "b", "c"])
    assert kept.kept.tolist() == [0] + [k for k in (1, 2) if k not in kept.rejected]
    assert len(kept.rejected) == 1 and kept.positions.shape[0] == 2
    assert np.allclose(kept.positions[0], smooth(paths[:1], 4.0)[0])  # the others' work is intact


def test_whole_batch_errors() -> None:
    ones = np.ones(1)
    with pytest.raises(TrajectoryError, match=r"positions: expected shape \(characters, frames, 3\)"):
        prepare(np.zeros((4, 3)), 60.0, 60.0, 10.0, 40, ones)
    with pytest.raises(TrajectoryError, match="needs at least 2 points"):
        prepare(np.zeros((1, 1, 3)), 60.0, 60.0, 10.0, 40, ones)
    with pytest.raises(TrajectoryError, match="fps: must be a positive number"):
        prepare(line(10, 1.0)[None], 0.0, 60.0, 10.0, 40, ones)
    with pytest.raises(TrajectoryError, match="scale: must be a positive number, got -1"):
        prepare(line(10, 1.0)[None], 60.0, 60.0, 10.0, 40, -ones)
    with pytest.raises(TrajectoryError, match=r"more than 8x the library's fastest"):
        prepare(line(100, 0.9 * TELEPORT_M * 60)[None], 60.0, 60.0, 10.0, 40, ones)
    with pytest.raises(TrajectoryError, match="every character was invalid"):
        prepare(np.full((2, 10, 3), np.inf), 60.0, 60.0, 10.0, 40, np.ones(2), skip_invalid=True)


def test_a_rate_reported_by_one_batch_gives_another_batch_the_same_frames() -> None:
    t = np.arange(200) / 60.0
    fast = np.stack([3.0 * t, 0 * t, 0 * t], axis=-1)[None]  # 3 m/s
    slow = np.stack([0.5 * t, 0 * t, 0 * t], axis=-1)[None]
    first = prepare(fast, 60.0, 60.0, 2.2, 40, np.ones(1), sigma=0.0, resample=True)
    assert first.resample_rate > 1.0
    second = prepare(slow, 60.0, 60.0, 2.2, 40, np.ones(1), sigma=0.0, min_rate=first.resample_rate)
    assert second.resample_rate == first.resample_rate
    assert second.positions.shape == first.positions.shape
    assert prepare(slow, 60.0, 60.0, 2.2, 40, np.ones(1), sigma=0.0).resample_rate == 1.0
    with pytest.raises(TrajectoryError, match=r"min_resample_rate: must be within \[1, 8\], got 0.5"):
        prepare(slow, 60.0, 60.0, 2.2, 40, np.ones(1), min_rate=0.5)
