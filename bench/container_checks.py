"""The checks ``scripts/container-test`` runs against the image it built (issue 32); not a test of
the pytest suite (minutes, and a container engine). Each prints one JSON object of figures and
exits non-zero with the reason when a check fails.

``python -m bench.container_checks single DOCKER IMAGE PORT``
    One container (host network, ``--cpus 1``), started twice: ready with horse and dog within
    15 s of ``docker start`` as uid 10001 (the kernels the build compiled are loaded, not
    compiled again), workers from the CPU quota, a synthesis answered, ``docker stop`` drains (no
    new connection taken, the request in flight finishes, the process exits before docker's
    SIGKILL). Then a container configured with a library it does not have
    (``QUADSYNTH_LIBRARIES=horse,dog,cat``): ``/readyz`` 503 naming ``cat`` missing, horse still
    served.

``python -m bench.container_checks compose DOCKER COMPOSE_COMMAND...`` (e.g. ``docker-compose -p P -f F``)
    The compose file (two replicas, nginx in front) up: both replicas healthy by the image's
    HEALTHCHECK, a herd fanned out through nginx (``quadsynth client synth --concurrency 4``) is
    the motion a local ``quadsynth synth`` makes; then again with one replica holding requests
    killed with SIGKILL: no character lost, none twice, the same motion.

``python -m bench.container_checks compose-file SOURCE OUT IMAGE NGINX_IMAGE``
    Writes OUT (and nginx.conf beside it): SOURCE, the repo's docker-compose.yml, for this engine.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from api_schemas.client import Client
from quadsynth.cli import main as cli
from synth_core.quality import herd_sim as crowd
from synth_core.runtime import trajectory_files as crowd_io

READY_TARGET_S = 15.0  # issue 32: ready with horse and dog <= 15 s after the first start


class Docker:
    def __init__(self, binary: str) -> None:
        self.binary = binary

    def __call__(self, *args: str, check: bool = True) -> str:
        done = subprocess.run([self.binary, *args], capture_output=True, text=True)
        if check and done.returncode != 0:
            raise SystemExit(f"docker {' '.join(args)}: {done.stderr.strip()}")
        return done.stdout.strip()

    def logs(self, name: str) -> str:
        done = subprocess.run([self.binary, "logs", name], capture_output=True, text=True)
        return done.stdout + done.stderr

    def running(self, name: str) -> bool:
        return self("inspect", "-f", "{{.State.Running}}", name) == "true"


def wait_for(what: str, ready: Callable[[], bool], alive: Callable[[], bool], timeout: float = 300) -> float:
    """Seconds until ``ready()`` (polled every 0.1 s); fails at once when ``alive()`` turns false."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        try:
            if ready():
                return time.monotonic() - t0
        except httpx.TransportError:
            pass
        if not alive():
            raise SystemExit(f"{what}: exited before it was ready")
        time.sleep(0.1)
    raise SystemExit(f"{what}: not ready in {timeout:.0f} s")


def readyz(url: str) -> httpx.Response:
    return httpx.get(f"{url}/readyz", timeout=2)


def in_flight(url: str) -> int:
    found = re.search(r"^quadsynth_in_flight{.*} (\d+)$", httpx.get(f"{url}/metrics").text, re.MULTILINE)
    assert found, "no quadsynth_in_flight in /metrics"
    return int(found[1])


def start_to_ready(docker: Docker, name: str, url: str) -> float:
    t0 = time.monotonic()
    docker("start", name)
    wait_for(name, lambda: readyz(url).status_code == 200, lambda: docker.running(name))
    return round(time.monotonic() - t0, 2)


def drain_on_stop(docker: Docker, name: str, url: str, herd: np.ndarray) -> float:
    """A request held in the worker (test hooks), then ``docker stop``: seconds the stop took."""
    with Client(url, timeout=120) as qs:
        httpx.post(f"{url}/_test/hold")
        answer: dict[str, Any] = {}
        worker = threading.Thread(target=lambda: answer.update(motion=qs.synthesize(herd[:5], seed=2)))
        worker.start()
        wait_for("a held request", lambda: bool(httpx.get(f"{url}/_test/held").json()["held"]),
                 worker.is_alive, timeout=60)
        t_stop = time.monotonic()
        stopper = subprocess.Popen([docker.binary, "stop", "-t", "30", name])
        refused = False  # draining: uvicorn takes no new connection while the request in flight finishes
        while stopper.poll() is None and worker.is_alive() and not refused:
            try:
                httpx.get(f"{url}/livez", timeout=1)
            except httpx.TransportError:
                refused = True
            time.sleep(0.05)
        worker.join(60)
        stopper.wait(60)
        stop_s = round(time.monotonic() - t_stop, 2)
    assert refused and not worker.is_alive(), "no drain seen"
    assert len(answer["motion"].characters) == 5, answer  # the request in flight finished
    exit_code = int(docker("inspect", "-f", "{{.State.ExitCode}}", name))
    # 0, or 143 when the re-raised SIGTERM ends it; 137 would be docker's SIGKILL after -t 30.
    assert exit_code in (0, 143) and stop_s < 30, f"exit {exit_code}:\n{docker.logs(name)}"
    return stop_s


def single(docker: Docker, image: str, port: int) -> dict[str, Any]:
    name, url = "quadsynth-container-test", f"http://127.0.0.1:{port}"
    docker("rm", "-f", name, check=False)
    # Test hooks: a route that holds the worker on an event, so that a request is surely in flight
    # at `docker stop` (the service releases it 1 s after SIGTERM). --cpus 1: the image counts its
    # workers from the CPU quota (one here, which the hold needs too: every request reaches it).
    docker("create", "--name", name, "--network", "host", "--cpus", "1", "-e", f"PORT={port}",
           "-e", "QUADSYNTH_TEST_HOOKS=1", image)
    figures: dict[str, Any] = {"first_start_to_ready_s": start_to_ready(docker, name, url)}
    status = readyz(url).json()
    assert status["status"] == "ready", status
    assert {s["name"] for s in status["library_status"]} == {"horse", "dog"}, status
    assert all(s["state"] == "loaded" for s in status["library_status"]), status
    uid = next(line.split()[1] for line in docker("exec", name, "cat", "/proc/1/status").splitlines()
               if line.startswith("Uid:"))
    assert uid == "10001", f"PID 1 runs as uid {uid}"
    figures["uid"] = int(uid)
    logs = docker.logs(name)
    assert "(--workers 1;" in logs, "workers not from the CPU quota (--cpus 1)"
    # The build compiled the kernels as this user for the installed code: a start loads them. A
    # kernel compiled again would add files to numba's cache in the container's own layer.
    added = [line for line in docker("diff", name).splitlines()
             if line.startswith("A /srv/quadsynth/numba-cache")]
    assert not added, f"kernels compiled again at the start: {added[:5]}"
    figures["kernels_compiled_at_start"] = len(added)
    herd = crowd.simulate(20, 240, seed=3).astype(np.float32)
    with Client(url, timeout=120) as qs:
        motion = qs.synthesize(herd, animal="dog", seed=1)
    assert len(motion.characters) == 20 and motion.characters[0].rotations.shape[1:] == (33, 4)
    figures["synthesis_characters"] = len(motion.characters)
    figures["stop_s"] = drain_on_stop(docker, name, url, herd)
    figures["drained"] = True
    figures["second_start_to_ready_s"] = start_to_ready(docker, name, url)
    docker("stop", name)
    slowest = max(figures["first_start_to_ready_s"], figures["second_start_to_ready_s"])
    assert slowest <= READY_TARGET_S, f"ready after {slowest} s (target {READY_TARGET_S})"
    figures["missing_library"] = missing_library(docker, image, port, herd)
    docker("rm", "-f", name)
    return figures


def missing_library(docker: Docker, image: str, port: int, herd: np.ndarray) -> dict[str, Any]:
    """Configured for an animal it has no library for: started, serving what it has, never ready."""
    name, url = "quadsynth-container-test-cat", f"http://127.0.0.1:{port}"
    docker("rm", "-f", name, check=False)
    docker("create", "--name", name, "--network", "host", "--cpus", "1", "-e", f"PORT={port}",
           "-e", "QUADSYNTH_LIBRARIES=horse,dog,cat", image)
    docker("start", name)
    # Loading is done once the status names every library; it must then stay 503.
    wait_for(name, lambda: readyz(url).json()["status"] not in ("starting",), lambda: docker.running(name))
    answer = readyz(url)
    states = {s["name"]: s["state"] for s in answer.json()["library_status"]}
    assert answer.status_code == 503 and answer.json()["status"] == "incomplete", answer.text
    assert states == {"horse": "loaded", "dog": "loaded", "cat": "missing"}, states
    with Client(url, timeout=120) as qs:
        served = len(qs.synthesize(herd[:3], animal="horse", seed=1).characters)
    health = wait_for_health(docker, name, {"unhealthy"}, timeout=90)
    docker("rm", "-f", name)
    return {"readyz": answer.status_code, "states": states, "horse_served": served, "docker_health": health}


def wait_for_health(docker: Docker, name: str, wanted: set[str], timeout: float) -> str:
    """The image's HEALTHCHECK verdict, once it is one of ``wanted``."""
    health = ""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        health = docker("inspect", "-f", "{{.State.Health.Status}}", name)
        if health in wanted:
            return health
        time.sleep(0.5)
    raise SystemExit(f"{name}: health {health!r} after {timeout:.0f} s, wanted {sorted(wanted)}")


def address(docker: Docker, name: str) -> str:
    return docker("inspect", "-f", "{{range .NetworkSettings.Networks}}{{.IPAddress}}{{end}}", name)


def fan_out(url: str, traj: Path, out: Path) -> int:
    return cli(["client", "synth", "--url", url, "--trajectories", str(traj), "--seed", "4",
                "--concurrency", "4", "--out", str(out)])


def same_herd(remote: Path, local: Path, characters: int) -> None:
    """The remote motion is the local one: every character once, same figures (the wire's f32)."""
    a, b = np.load(remote / "motion.npz"), np.load(local / "motion.npz")
    ids = a["ids"].tolist()
    assert len(ids) == characters and len(set(ids)) == characters, f"lost or doubled: {ids}"
    for key in ("gait", "contacts", "ids", "scales"):
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    for key in ("root_pos", "rotations"):
        np.testing.assert_allclose(a[key], b[key], atol=1e-5, err_msg=key)


def compose(docker: Docker, compose_cmd: list[str]) -> dict[str, Any]:
    """Up (the compose file's own replica count), fan a herd out through nginx, kill a replica
    holding requests under a second fan-out; the caller downs the project."""
    t0 = time.monotonic()
    subprocess.run([*compose_cmd, "up", "-d", "--no-build"], check=True, capture_output=True)
    listed = subprocess.run([*compose_cmd, "ps", "-q"], check=True, capture_output=True, text=True)
    ids = listed.stdout.split()
    names = {docker("inspect", "-f", "{{.Name}}", i).lstrip("/"): i for i in ids}
    replicas = sorted(n for n in names if "_quadsynth_" in n)
    balancer = next(n for n in names if "_nginx_" in n)
    assert len(replicas) == 2, f"replicas: {replicas}"
    for name in replicas:
        wait_for_health(docker, name, {"healthy"}, timeout=120)
    figures: dict[str, Any] = {"replicas": len(replicas),
                               "up_to_both_healthy_s": round(time.monotonic() - t0, 1)}
    urls = {name: f"http://{address(docker, name)}:8000" for name in replicas}
    front = f"http://{address(docker, balancer)}:8080"
    wait_for("nginx", lambda: readyz(front).status_code == 200, lambda: docker.running(balancer), timeout=60)
    with tempfile.TemporaryDirectory() as scratch:
        tmp = Path(scratch)
        characters = 16
        herd = crowd.simulate(characters, 240, seed=5).astype(np.float32)
        traj = crowd_io.write_npz(tmp / "traj.npz", herd, 60.0)
        assert cli(["synth", "--trajectories", str(traj), "--seed", "4", "--out", str(tmp / "local")]) == 0
        served_before = {n: requests_served(u) for n, u in urls.items()}
        t1 = time.monotonic()
        assert fan_out(front, traj, tmp / "both") == 0
        figures["fan_out_s"] = round(time.monotonic() - t1, 2)
        same_herd(tmp / "both", tmp / "local", characters)
        figures["requests_per_replica"] = sorted(requests_served(u) - served_before[n]
                                                 for n, u in urls.items())
        assert min(figures["requests_per_replica"]) >= 1, "nginx sent every request to one replica"

        victim = replicas[0]
        assert httpx.post(f"{urls[victim]}/_test/hold").status_code == 200  # its worker waits
        outcome: list[int] = []
        client = threading.Thread(target=lambda: outcome.append(fan_out(front, traj, tmp / "killed")))
        client.start()
        wait_for("a request held by the victim", lambda: in_flight(urls[victim]) >= 1, client.is_alive, 120)
        docker("kill", "-s", "KILL", victim)  # dies holding them: connections reset mid-request
        client.join(300)
        assert outcome == [0], outcome
        same_herd(tmp / "killed", tmp / "local", characters)
        figures["killed_replica"] = {"characters": characters, "lost": 0, "doubled": 0,
                                     "motion": "= local synth"}
    return figures


def requests_served(url: str) -> int:
    """Synthesis requests this replica answered (its own /metrics)."""
    text = httpx.get(f"{url}/metrics").text
    return sum(int(float(m[1])) for m in re.finditer(
        r'^quadsynth_requests_total{[^}]*route="/v1/synthesize"[^}]*} (\S+)$', text, re.MULTILINE))


def compose_file(source: Path, out: Path, image: str, nginx_image: str) -> None:
    """The repo's compose file for this engine: the images built here instead of a build and a
    registry's nginx, the test hooks on, nginx reached at its container's address (no published
    port to collide with), and deploy/nginx.conf without ``resolve`` on the upstream server (an
    nginx >= 1.27.3 parameter; Debian bookworm's 1.22 resolves the name once, at its start: both
    replicas, which exist by then)."""
    import yaml

    spec = yaml.safe_load(source.read_text())
    service, balancer = spec["services"]["quadsynth"], spec["services"]["nginx"]
    service.pop("build", None)
    service["image"] = image
    service.setdefault("environment", {})["QUADSYNTH_TEST_HOOKS"] = "1"
    balancer["image"] = nginx_image
    balancer.pop("ports", None)
    conf = (source.parent / "deploy" / "nginx.conf").read_text()
    line = re.compile(r"^(\s*server quadsynth:8000) resolve( .*)$", re.MULTILINE)
    assert len(line.findall(conf)) == 1, "deploy/nginx.conf: no `server quadsynth:8000 resolve ...` line"
    (out.parent / "nginx.conf").write_text(line.sub(r"\1\2", conf))
    balancer["volumes"] = [f"{out.parent / 'nginx.conf'}:/etc/nginx/nginx.conf:ro"]
    out.write_text(yaml.safe_dump(spec, sort_keys=False))


def run(argv: list[str]) -> int:
    if argv[0] == "compose-file":
        compose_file(Path(argv[1]), Path(argv[2]), argv[3], argv[4])
        return 0
    docker = Docker(argv[1])
    if argv[0] == "single":
        figures = single(docker, argv[2], int(argv[3]))
    elif argv[0] == "compose":
        figures = compose(docker, argv[2:])
    else:
        raise SystemExit(f"unknown check {argv[0]!r}: single or compose")
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(run(sys.argv[1:]))
