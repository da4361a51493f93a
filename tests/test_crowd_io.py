"""Trajectory files: crowd-sim's .npz and a crowd tool's CSV, with errors naming line and problem."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from synth_core.quality import herd_sim as crowd
from synth_core.runtime import trajectory_files as crowd_io
from synth_core.runtime.trajectory_files import TrajectoryFileError


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_csv_columns_by_header_name_in_any_order(tmp_path: Path) -> None:
    rows = ["Z,frame,extra,x,id,y"]
    for cid in ("a", "b"):
        for f in range(10, 13):
            rows.append(f"{f * 0.5},{f},ignored,{f * 0.1},{cid},{0.0 if cid == 'a' else 1.0}")
    traj = crowd_io.read(write(tmp_path / "t.csv", "\n".join(rows)))
    assert traj.ids == ["a", "b"] and traj.positions.shape == (2, 3, 3) and traj.fps == 60.0
    assert np.allclose(traj.positions[1, :, 1], 1.0)
    assert np.allclose(traj.positions[0, :, 2], [5.0, 5.5, 6.0])


@pytest.mark.parametrize(("text", "message"), [
    ("", "empty file"),
    ("id,frame,x,y\na,0,1,2\n", r"lacks column\(s\) \['z'\]"),
    ("id,frame,x,y,z\na,0,1,2,3\na,1,1,oops,3\n", "line 3: not a number"),
    ("id,frame,x,y,z\na,0,1,2,3\na,0,1,2,3\n", "line 3: character 'a' frame 0 repeated"),
    ("id,frame,x,y,z\na,0,1,2,3\na,1,1,2,3\na,3,1,2,3\n", r"character 'a': frames missing \[2\]"),
    ("id,frame,x,y,z\na,0,1,2,3\na,1,1,2,3\nb,0,1,2,3\n", "character 'b' covers frames 0-0"),
    ("id,frame,x,y,z\na,0.5,1,2,3\n", "frame must be an integer"),
    ("id,frame,x,y,z\na,0,nan,2,3\n", "must be finite"),
    ("id,frame,x,y,z\na,0,1\n", "line 2: 3 values"),
])
def test_bad_csv_is_refused_naming_the_problem(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(TrajectoryFileError, match=message):
        crowd_io.read(write(tmp_path / "t.csv", text))


def test_npz_round_trip_and_errors(tmp_path: Path) -> None:
    positions = crowd.simulate(4, 50, seed=1)
    path = crowd_io.write_npz(tmp_path / "t.npz", positions, 30.0, ["w", "x", "y", "z"])
    traj = crowd_io.read(path)
    assert traj.ids == ["w", "x", "y", "z"] and traj.fps == 30.0
    assert np.array_equal(traj.positions, positions)
    np.savez(tmp_path / "bad.npz", other=np.zeros(3))
    with pytest.raises(TrajectoryFileError, match="no `positions`"):
        crowd_io.read(tmp_path / "bad.npz")
    np.savez(tmp_path / "flat.npz", positions=np.zeros((3, 2)))
    with pytest.raises(TrajectoryFileError, match=r"shape \(C, F, 3\)"):
        crowd_io.read(tmp_path / "flat.npz")
    with pytest.raises(TrajectoryFileError, match="unknown trajectory format"):
        crowd_io.read(write(tmp_path / "t.txt", "x"))


def test_crowd_sim_stands_then_runs_up_to_gallop_and_back_keeping_separation() -> None:
    positions = crowd.simulate(60, 500, seed=0)
    speed = np.linalg.norm(np.diff(positions[..., [0, 2]], axis=1), axis=-1) * 60
    assert speed[:, :50].max() < 0.05  # standing
    assert speed.max(axis=1).min() > 6.0 and speed[:, -1].max() < 2.5  # gallop, then a walk/trot
    accel = np.abs(np.diff(speed, axis=1)) * 60
    assert np.percentile(accel, 99) < 4.0  # m/s^2: an animal's, not a teleport
    gaps = np.linalg.norm(positions[:, None, :, [0, 2]] - positions[None, :, :, [0, 2]], axis=-1)
    gaps[np.arange(60), np.arange(60)] = np.inf
    assert gaps.min() > 1.0  # metres between any two, at every frame


def test_crowd_sim_agents_never_step_backwards_as_they_start() -> None:
    # Drift that grew with speed once pushed agents ~20 cm backwards as the herd set off: an animal
    # would turn round for that and straight back (its feet sliding), not what a herd does.
    positions = crowd.simulate(60, 500, seed=0).astype(np.float64)
    step = np.diff(positions[..., [0, 2]], axis=1)
    herd = step.mean(axis=0, keepdims=True)  # the herd's direction of travel each frame
    herd /= np.maximum(np.linalg.norm(herd, axis=-1, keepdims=True), 1e-12)
    along = np.sum(step * herd, axis=-1) * 60  # m/s along it
    assert along.min() > -0.01
