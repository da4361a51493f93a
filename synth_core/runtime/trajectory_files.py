"""Trajectory files: the ``.npz`` crowd-sim writes, and the CSV a crowd tool exports.

``.npz``: ``positions (C, F, 3)`` float32 metres (Y up), optional ``ids (C,)`` strings and ``fps``.

CSV: one row per character per frame, a header naming the columns ``id, frame, x, y, z`` in any
order (case-insensitive; other columns are ignored). Every character must have the same frames,
consecutive integers (``frame`` need not start at 0). Errors name the line and the problem: a
missing column, a value that is not a number, a repeated (id, frame), a gap in a character's
frames, characters covering different frames.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

COLUMNS = ("id", "frame", "x", "y", "z")
DEFAULT_FPS = 60.0


class TrajectoryFileError(ValueError):
    """A trajectory file that cannot be read; the message names the file, line and problem."""


@dataclass(frozen=True)
class Trajectories:
    positions: NDArray[np.float32]  # (C, F, 3) metres
    ids: list[str]
    fps: float


def read_csv(path: str | Path, fps: float = DEFAULT_FPS) -> Trajectories:
    path = Path(path)
    with path.open(newline="") as f:
        reader = csv.reader(f)
        col, width = _header(path, reader)
        rows: dict[str, dict[int, tuple[float, float, float]]] = {}
        for line, row in enumerate(reader, start=2):
            if not row or all(not v.strip() for v in row):
                continue
            cid, frame, xyz = _row(path, line, row, col, width)
            frames = rows.setdefault(cid, {})
            if frame in frames:
                raise TrajectoryFileError(f"{path}: line {line}: character {cid!r} frame {frame} repeated")
            frames[frame] = xyz
    if not rows:
        raise TrajectoryFileError(f"{path}: no data rows")
    span = _common_span(path, rows)
    ids = list(rows)
    positions = np.array([[rows[c][f] for f in range(span[0], span[1] + 1)] for c in ids], np.float32)
    return Trajectories(positions, ids, fps)


def _header(path: Path, reader: Iterator[list[str]]) -> tuple[dict[str, int], int]:
    """The index of each of ``COLUMNS`` in the header line, and how many columns it names."""
    try:
        header = next(reader)
    except StopIteration:
        raise TrajectoryFileError(f"{path}: empty file (expected a header {','.join(COLUMNS)})") from None
    names = [h.strip().lower() for h in header]
    missing = [c for c in COLUMNS if c not in names]
    if missing:
        raise TrajectoryFileError(f"{path}: line 1: header {header} lacks column(s) {missing} "
                                  f"(need {','.join(COLUMNS)} in any order)")
    return {c: names.index(c) for c in COLUMNS}, len(names)


def _row(path: Path, line: int, row: list[str], col: dict[str, int],
         width: int) -> tuple[str, int, tuple[float, float, float]]:
    """One data line's character id, frame and (x, y, z)."""
    if len(row) < width:
        raise TrajectoryFileError(f"{path}: line {line}: {len(row)} values, "
                                  f"the header has {width}")
    cid = row[col["id"]].strip()
    try:
        frame_f = float(row[col["frame"]])
        xyz = tuple(float(row[col[c]]) for c in "xyz")
    except ValueError:
        raise TrajectoryFileError(f"{path}: line {line}: not a number in {row}") from None
    if not frame_f.is_integer():
        raise TrajectoryFileError(f"{path}: line {line}: frame must be an integer, got {frame_f}")
    if not all(np.isfinite(xyz)):
        raise TrajectoryFileError(f"{path}: line {line}: x, y, z must be finite, got {xyz}")
    return cid, int(frame_f), xyz  # type: ignore[return-value]


def _common_span(path: Path, rows: dict[str, dict[int, tuple[float, float, float]]]) -> tuple[int, int]:
    """The frames ``[first, last]`` every character covers, each without a gap."""
    first_id = next(iter(rows))
    span = (min(rows[first_id]), max(rows[first_id]))
    for cid, frames in rows.items():
        lo, hi = min(frames), max(frames)
        if len(frames) != hi - lo + 1:
            gaps = sorted(set(range(lo, hi + 1)) - set(frames))
            raise TrajectoryFileError(f"{path}: character {cid!r}: frames missing {gaps[:10]}"
                                      f"{' ...' if len(gaps) > 10 else ''} (frames must be consecutive)")
        if (lo, hi) != span:
            raise TrajectoryFileError(f"{path}: character {cid!r} covers frames {lo}-{hi}, character "
                                      f"{first_id!r} {span[0]}-{span[1]}: every character needs "
                                      "the same frames")
    return span


def read_npz(path: str | Path, fps: float | None = None) -> Trajectories:
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            if "positions" not in data:
                raise TrajectoryFileError(f"{path}: no `positions` array (expected (C, F, 3) metres)")
            positions = np.asarray(data["positions"], np.float32)
            ids = [str(i) for i in data["ids"]] if "ids" in data else [str(c) for c in range(len(positions))]
            stored = float(data["fps"]) if "fps" in data else DEFAULT_FPS
    except (OSError, ValueError) as exc:
        if isinstance(exc, TrajectoryFileError):
            raise
        raise TrajectoryFileError(f"{path}: not a readable .npz file ({exc})") from None
    if positions.ndim != 3 or positions.shape[-1] != 3:
        raise TrajectoryFileError(f"{path}: expected `positions` to have shape (C, F, 3), "
                                  f"got {positions.shape}")
    if len(ids) != len(positions):
        raise TrajectoryFileError(f"{path}: {len(ids)} ids for {len(positions)} characters")
    return Trajectories(positions, ids, stored if fps is None else fps)


def read(path: str | Path, fps: float | None = None) -> Trajectories:
    """A ``.npz`` or ``.csv`` trajectory file (``fps``: overrides the file's; CSV default 60)."""
    suffix = Path(path).suffix.lower()
    if suffix == ".csv":
        return read_csv(path, DEFAULT_FPS if fps is None else fps)
    if suffix == ".npz":
        return read_npz(path, fps)
    raise TrajectoryFileError(f"{path}: unknown trajectory format {suffix!r} (use .npz or .csv)")


def write_npz(path: str | Path, positions: NDArray[np.floating], fps: float,
              ids: list[str] | None = None) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    names = ids or [str(c) for c in range(len(positions))]
    np.savez_compressed(path, positions=np.asarray(positions, np.float32), ids=np.array(names), fps=fps)
    return path
