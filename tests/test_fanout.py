"""Issue 32's target: a herd fanned out over two replicas behind nginx (`quadsynth client synth
--concurrency N`), one replica killed with SIGKILL while it holds requests: no character lost,
none twice, and the motion a local `quadsynth synth` makes."""

from __future__ import annotations

import json
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest

from quadsynth.cli import main
from synth_core.quality import herd_sim as crowd
from synth_core.runtime import trajectory_files as crowd_io
from tests.helpers.nginx import Cluster, nginx_cluster
from tests.helpers.requests import same_motion
from tests.helpers.servers import in_flight


@pytest.fixture(scope="module")
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    """(nginx URL, the two replicas' own URLs, their processes, nginx's error log)."""
    with nginx_cluster(tmp_path_factory) as running:
        yield running


def test_a_replica_killed_under_a_fanned_out_herd_loses_no_character(
        cluster: Cluster, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    url, replicas, procs, _ = cluster
    herd = crowd.simulate(16, 240, seed=5).astype(np.float32)
    traj = crowd_io.write_npz(tmp_path / "traj.npz", herd, 60.0)
    assert httpx.post(f"{replicas[0]}/_test/hold").status_code == 200  # its worker waits
    outcome: list[int] = []
    client = threading.Thread(target=lambda: outcome.append(main([
        "client", "synth", "--url", url, "--trajectories", str(traj), "--seed", "4", "--concurrency", "4",
        "--out", str(tmp_path / "remote")])))
    client.start()
    deadline = time.monotonic() + 120
    while in_flight(replicas[0]) < 1 and time.monotonic() < deadline and client.is_alive():
        time.sleep(0.05)  # waiting for a request to reach the held replica (a condition, not a delay)
    assert in_flight(replicas[0]) >= 1, "no request reached the held replica"
    procs[0].send_signal(signal.SIGKILL)  # dies holding them: connections reset mid-request
    procs[0].wait(timeout=30)
    client.join(300)
    assert outcome == [0], capsys.readouterr().err[-2000:]
    remote_summary = json.loads((tmp_path / "remote" / "summary.json").read_text())
    assert main(["synth", "--trajectories", str(traj), "--seed", "4", "--out", str(tmp_path / "local")]) == 0
    local_summary = json.loads((tmp_path / "local" / "summary.json").read_text())
    assert remote_summary == local_summary and remote_summary["characters"] == 16
    ids = np.load(tmp_path / "remote" / "motion.npz")["ids"]
    assert sorted(ids.tolist()) == sorted({str(i) for i in ids}) and len(ids) == 16  # none lost, none twice
    same_motion(tmp_path / "remote", tmp_path / "local")
