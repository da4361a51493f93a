"""`quadsynth client synth` against a real service with small limits: the herd goes in several
requests and comes back as the motion `quadsynth synth` makes locally, with the same files."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pygltflib
import pytest

from quadsynth.cli import main
from synth_core.motion import bvh
from synth_core.quality import herd_sim as crowd
from synth_core.runtime import trajectory_files as crowd_io
from tests.helpers.requests import same_motion
from tests.helpers.servers import free_port, running

LIMITS = {"QUADSYNTH_MAX_CHARACTERS": "8", "QUADSYNTH_MAX_CHARACTER_FRAMES": "20000",
          "QUADSYNTH_TEST_HOOKS": "1"}  # /_test/hold: the worker waits, so requests pile up in flight


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with running(tmp_path_factory.mktemp("cli"), LIMITS) as (url, _):
        yield url


@pytest.fixture(scope="module")
def herd() -> np.ndarray:
    """20 horses, one of them (17, in the last request) too fast for the library even at its
    fastest stride rate: resampled with --resample, else warned of."""
    positions = crowd.simulate(20, 300, seed=1)
    positions[17] = positions[17, :1] + (positions[17] - positions[17, :1]) * 5.0
    return positions.astype(np.float32)


def run(*argv: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, dict[str, object], str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    lines = out.strip().splitlines()
    return code, json.loads(lines[-1]) if code == 0 else {}, err


@pytest.mark.parametrize("resample", [True, False])
def test_client_synth_cuts_the_herd_and_gets_the_local_motion(server: str, herd: np.ndarray, tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str],
                                                               resample: bool) -> None:
    traj = crowd_io.write_npz(tmp_path / "traj.npz", herd, 60.0)
    flag = ["--resample"] if resample else []
    code, summary, err = run("client", "synth", "--url", server, "--trajectories", str(traj), "--seed", "7",
                             "--out", str(tmp_path / "remote"), "--bvh", "--glb", str(tmp_path / "r.glb"),
                             *flag, capsys=capsys)
    assert code == 0, err
    # 8 + 8 + 4 characters (resampled: then the first two again at the last's rate)
    assert f"{5 if resample else 3} request(s)" in err
    assert ("warning: character 17: moves at" in err) != resample
    code, local, err = run("synth", "--trajectories", str(traj), "--seed", "7",
                           "--out", str(tmp_path / "local"), "--glb", str(tmp_path / "l.glb"), *flag,
                           capsys=capsys)
    assert code == 0, err
    assert summary == local
    if resample:
        assert float(summary["resample_rate"]) > 1.0  # type: ignore[arg-type]
        assert summary["warnings"] == {}
    else:  # the clock kept: a frame out per frame in, the too-fast horse named
        assert summary["resample_rate"] == 1.0 and summary["frames"] == herd.shape[1]
        assert list(summary["warnings"]) == ["17"]  # type: ignore[call-overload]
    same_motion(tmp_path / "remote", tmp_path / "local")
    files = sorted(p.name for p in (tmp_path / "remote").glob("*.bvh"))
    assert files == sorted(f"{c}.bvh" for c in range(20))
    motion = bvh.read(tmp_path / "remote" / "17.bvh", feet=None)
    assert motion.n_frames == summary["frames"] and (tmp_path / "r.glb").read_bytes()[:4] == b"glTF"
    assert (tmp_path / "remote" / "17.contacts.json").exists()
    # The herd wears the mesh the service serves, a skin per character, as a local synth's does.
    remote_glb, local_glb = (pygltflib.GLTF2().load(str(tmp_path / name)) for name in ("r.glb", "l.glb"))
    assert len(remote_glb.skins) == len(local_glb.skins) == 20
    mesh = [g.accessors[g.meshes[0].primitives[0].attributes.POSITION] for g in (remote_glb, local_glb)]
    assert mesh[0].count == mesh[1].count and mesh[0].max == mesh[1].max


def test_client_synth_skips_or_names_a_bad_character_by_its_place_in_the_herd(
        server: str, herd: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = herd[:12].copy()
    bad[9, 40] = np.nan  # the second request's second character
    traj = crowd_io.write_npz(tmp_path / "bad.npz", bad, 60.0)
    code, _, err = run("client", "synth", "--url", server, "--trajectories", str(traj),
                       "--out", str(tmp_path / "refused"), capsys=capsys)
    assert code == 2 and "characters[9]" in err and "NaN" in err, err
    code, summary, err = run("client", "synth", "--url", server, "--trajectories", str(traj),
                             "--skip-invalid", "--out", str(tmp_path / "remote"), capsys=capsys)
    assert code == 0 and summary["characters"] == 11, (summary, err)
    assert list(summary["skipped"]) == ["9"]  # type: ignore[call-overload]
    code, local, err = run("synth", "--trajectories", str(traj), "--skip-invalid",
                           "--out", str(tmp_path / "local"), capsys=capsys)
    assert code == 0 and summary == local
    same_motion(tmp_path / "remote", tmp_path / "local")


def test_client_synth_says_when_the_service_cannot_be_reached(herd: np.ndarray, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    traj = crowd_io.write_npz(tmp_path / "traj.npz", herd[:2], 60.0)
    code, _, err = run("client", "synth", "--url", f"http://127.0.0.1:{free_port()}",
                       "--trajectories", str(traj), "--out", str(tmp_path / "o"), capsys=capsys)
    assert code == 2 and "cannot reach the service" in err


def in_flight(url: str) -> int:
    metrics = httpx.get(f"{url}/metrics").text
    return int(float(next(line.split()[1] for line in metrics.splitlines()
                          if line.startswith("quadsynth_in_flight{"))))


def test_client_synth_with_concurrency_has_n_requests_in_flight_and_the_local_motion(
        server: str, herd: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    traj = crowd_io.write_npz(tmp_path / "traj.npz", herd, 60.0)
    httpx.post(f"{server}/_test/hold")  # the worker waits: the requests sent meanwhile stay in flight
    outcome: list[tuple[int, dict[str, object], str]] = []
    client = threading.Thread(target=lambda: outcome.append(run(
        "client", "synth", "--url", server, "--trajectories", str(traj), "--seed", "7", "--concurrency", "3",
        "--out", str(tmp_path / "remote"), capsys=capsys)))
    client.start()
    try:
        deadline = time.monotonic() + 60
        while in_flight(server) < 3 and time.monotonic() < deadline and client.is_alive():
            time.sleep(0.05)
        assert in_flight(server) == 3  # one running (held), two queued: the herd's three pieces at once
    finally:
        httpx.post(f"{server}/_test/release")
        client.join(120)
    code, summary, err = outcome[0]
    assert code == 0, err
    assert "3 request(s)" in err  # 7 + 7 + 6 characters (>= 3 pieces); the clock kept: no second round
    code, local, err = run("synth", "--trajectories", str(traj), "--seed", "7",
                           "--out", str(tmp_path / "local"), capsys=capsys)
    assert code == 0 and summary == local, err
    same_motion(tmp_path / "remote", tmp_path / "local")


def test_concurrency_below_one_is_refused(tmp_path: Path, herd: np.ndarray,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    traj = crowd_io.write_npz(tmp_path / "traj.npz", herd[:2], 60.0)
    code, _, err = run("client", "synth", "--url", "http://127.0.0.1:9", "--trajectories", str(traj),
                       "--concurrency", "0", "--out", str(tmp_path / "out"), capsys=capsys)
    assert code == 2 and "concurrency: must be at least 1, got 0" in err
