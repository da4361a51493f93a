"""The library artifact: round trip, no pickle, clear errors on tampered or truncated files; CLI."""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import numpy as np
import pytest

from quadsynth.cli import main
from service.libraries import LibraryRegistry
from synth_core.build.animals import build_builtin
from synth_core.build.artifact import Library, LibraryFileError, load_library, save_library
from synth_core.motion import bvh


@pytest.fixture(scope="module")
def dog() -> Library:
    return build_builtin("dog")


@pytest.fixture(scope="module")
def saved(dog: Library, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return save_library(dog, tmp_path_factory.mktemp("lib") / "dog.qslib.npz")


def rewrite(source: Path, target: Path, **changes: np.ndarray) -> Path:
    """A copy of an artifact with some arrays replaced (or, given None, removed)."""
    with np.load(source, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    for key, value in changes.items():
        key = key.replace("__", "/")
        if value is None:
            del arrays[key]
        else:
            arrays[key] = value
    np.savez(target, **arrays)
    return target


def test_round_trip_keeps_every_array_and_the_graph(dog: Library, saved: Path) -> None:
    again = load_library(saved)
    assert again.animal == "dog" and again.skeleton.names == dog.skeleton.names
    assert [f.chain for f in again.skeleton.feet] == [f.chain for f in dog.skeleton.feet]
    for gait, m in dog.maps.items():
        n = again.maps[gait]
        assert np.array_equal(n.speeds, m.speeds) and np.array_equal(n.rotations, m.rotations)
        assert np.array_equal(n.root_pos, m.root_pos) and np.array_equal(n.contacts, m.contacts)
        assert np.array_equal(n.stretch, m.stretch) and n.source_speed == m.source_speed
    for name, clip in dog.transitions.items():
        assert np.array_equal(again.transitions[name].rotations, clip.rotations)
        assert np.array_equal(again.transitions[name].contacts, clip.contacts)
    assert np.array_equal(again.idle.rotations, dog.idle.rotations)
    assert again.graph.nodes == dog.graph.nodes and again.graph.n_edges == dog.graph.n_edges


def test_the_file_holds_no_pickled_objects(saved: Path) -> None:
    with np.load(saved, allow_pickle=False) as npz:  # would raise on an object array
        assert all(npz[k].dtype != object for k in npz.files)


@pytest.mark.parametrize(("change", "message"), [
    ({"version": np.array(2)}, "version: this QuadSynth reads version 1"),
    ({"format": np.array("something-else")}, "format: expected 'quadsynth-library'"),
    ({"map__trot__rotations": None}, "map/trot/rotations: missing"),
    ({"map__trot__rotations": np.zeros((60, 30, 5, 4), np.float32)}, r"map/trot/rotations: expected shape"),
    ({"map__walk__root_pos": np.full((60, 46, 3), np.nan, np.float32)}, "map/walk/root_pos: holds NaN"),
    ({"skeleton__parents": np.array([5] * 33, np.int32)}, "skeleton: `parents` must be topological"),
    ({"meta": np.array("{not json")}, "meta: not the expected JSON"),
    ({"clip__idle__contacts": np.zeros((600, 4), np.float32)}, "clip/idle/contacts: expected dtype kind 'b'"),
])
def test_tampered_files_fail_naming_the_key(saved: Path, tmp_path: Path, change: dict, message: str) -> None:
    bad = rewrite(saved, tmp_path / "bad.qslib.npz", **change)
    with pytest.raises(LibraryFileError, match=message):
        load_library(bad)


def test_an_object_array_is_refused_not_unpickled(saved: Path, tmp_path: Path) -> None:
    bad = rewrite(saved, tmp_path / "pickled.qslib.npz", meta=np.array([{"evil": 1}], dtype=object))
    with pytest.raises(LibraryFileError, match="pickle|Object arrays"):
        load_library(bad)


@pytest.mark.parametrize("keep", [0.1, 0.5, 0.95])
def test_truncated_files_fail_cleanly(saved: Path, tmp_path: Path, keep: float) -> None:
    data = saved.read_bytes()
    cut = tmp_path / "cut.qslib.npz"
    cut.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(LibraryFileError, match="cut.qslib.npz"):
        load_library(cut)


def test_not_a_zip_and_missing_file(tmp_path: Path) -> None:
    junk = tmp_path / "junk.qslib.npz"
    junk.write_bytes(b"\x00\x01 not a library" * 10)
    with pytest.raises(LibraryFileError, match="not a readable QuadSynth library"):
        load_library(junk)
    with pytest.raises(LibraryFileError, match="no such file"):
        load_library(tmp_path / "absent.qslib.npz")


def test_a_failed_save_leaves_the_old_file_whole(dog: Library, saved: Path, tmp_path: Path) -> None:
    target = tmp_path / "keep.qslib.npz"
    target.write_bytes(saved.read_bytes())
    broken = Library(dog.animal, dog.skeleton, dog.fps, dog.maps, dog.idle, dog.transitions,
                     extra={"unserializable": object()})
    with pytest.raises(TypeError):
        save_library(broken, target)
    assert load_library(target).animal == "dog"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.qslib.npz"]  # no temporary left behind


def test_registry_loads_good_files_builds_missing_built_ins_and_skips_bad_ones(saved: Path,
                                                                              tmp_path: Path) -> None:
    (tmp_path / "dog.qslib.npz").write_bytes(saved.read_bytes())
    (tmp_path / "broken.qslib.npz").write_bytes(b"PK\x03\x04 truncated")
    registry = LibraryRegistry(tmp_path)
    registry.load()
    assert set(registry.libraries) == {"horse", "dog"}  # horse was missing: built
    assert (tmp_path / "horse.qslib.npz").exists()
    assert registry.summaries["dog"].gaits == ["walk", "trot", "canter", "gallop"]
    assert list(registry.errors) == ["broken.qslib.npz"]  # its name: the server's path is not shown
    assert str(tmp_path) not in registry.errors["broken.qslib.npz"]
    assert not registry.complete  # a library file that failed: not ready (service.libraries)


@pytest.mark.parametrize(("umask", "mode"), [(0o022, 0o644), (0o002, 0o664), (0o077, 0o600)])
def test_saved_files_honour_the_umask(dog: Library, tmp_path: Path, umask: int, mode: int) -> None:
    previous = os.umask(umask)
    try:
        path = save_library(dog, tmp_path / "dog.qslib.npz")
    finally:
        os.umask(previous)
    assert stat.S_IMODE(path.stat().st_mode) == mode  # mkstemp alone gives 0600 whatever the umask


def test_cli_build_report_and_export_speedmap(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "horse.qslib.npz"
    assert main(["build", "--animal", "horse", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["report", str(out), "--json"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 1
    figures = json.loads(lines[0])
    assert figures["animal"] == "horse"
    assert set(figures["gaits"]) == {"walk", "trot", "canter", "gallop"}
    assert set(figures["gaits"]["trot"]) >= {"clips", "frames", "speed_min", "speed_max", "skate_mm_mean",
                                            "skate_mm_p95", "footfall_preserved", "max_limb_stretch_pct"}
    assert figures["graph"]["nodes"] == ["static", "walk", "trot", "canter", "gallop"]
    assert len(figures["graph"]["transitions"]) == 8
    assert main(["export-speedmap", str(out), "--out", str(tmp_path / "sm")]) == 0
    files = sorted(p.name for p in (tmp_path / "sm").glob("*.bvh"))
    assert len(files) == 12
    library = load_library(out)
    slowest = f"walk_{library.maps['walk'].speeds[0]:.2f}.bvh"
    assert slowest in files
    clip = bvh.read(tmp_path / "sm" / slowest)
    assert clip.n_frames == library.maps["walk"].n_frames
    assert abs(clip.speed_mps() - library.maps["walk"].speeds[0]) < 0.01 * library.maps["walk"].speeds[0]


def test_cli_build_errors_are_clear(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", str(tmp_path / "nothing.qslib.npz")]) == 2
    assert "no such file" in capsys.readouterr().err
