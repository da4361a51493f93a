"""Operator drills of issue 34 against running services: ``python -m bench.drills [--quick]``
prints one JSON object; not a test.

It starts what it drills (``quadsynth serve`` on free loopback ports with the environment's
settings, the default library directory): one service of two worker processes for the first
two drills, two one-worker replicas behind deploy/nginx.conf for the third (skipped, and said
so, where ``scripts/ensure-nginx`` finds no nginx). Each drill reports the worker processes'
peak RSS (sampled every 50 ms from /proc), /livez latency (p50, p99, max; polled every 20 ms
throughout), the status histogram of its requests and the bytes lost (answers that came short
of their Content-Length, as the client saw them).

- ``stalled``: three clients ask for a maximal f32 answer (250 characters x 8,000 frames, the
  2M character-frame limit: 1.28 GB) and never read it, while a fourth loops 8 MiB msgpack
  bodies (10,000 characters, refused after validation: an unknown animal). Target: every
  worker's RSS <= memory budget + 300 MB, /livez p99 <= 100 ms, no worker killed.
- ``largest``: the largest allowed f32 answer, then the same as JSON, each read whole. Target:
  peak RSS <= 1.5 x the budget.
- ``kill9``: four Python clients (api_schemas.client.Client, retries on) loop requests through
  nginx; one replica is killed with SIGKILL a third of the way in. Target: 0 requests lost as
  the clients see them; the retries they made are reported.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import msgpack
import numpy as np

from api_schemas.client import Client
from api_schemas.wire import blob
from service.settings import Settings
from synth_core.quality import herd_sim as crowd

REPO = Path(__file__).resolve().parents[1]
MSGPACK = "application/vnd.msgpack"
MB = 1 << 20


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def serve(port: int, workers: int) -> subprocess.Popen[bytes]:
    script = Path(sys.executable).with_name("quadsynth")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "quadsynth.cli"]
    return subprocess.Popen([*command, "serve", "--port", str(port), "--workers", str(workers),
                             "--log-level", "warning"], env=os.environ.copy(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def wait_ready(url: str, proc: subprocess.Popen[bytes], answers: int = 10) -> None:
    """Until ``answers`` /readyz in a row say ready (every worker loaded)."""
    deadline, ready = time.monotonic() + 600, 0
    while ready < answers:
        if proc.poll() is not None or time.monotonic() > deadline:
            raise SystemExit(f"drills: the service at {url} did not start")
        try:
            ready = ready + 1 if httpx.get(f"{url}/readyz", timeout=2).status_code == 200 else 0
        except httpx.TransportError:
            ready = 0
            time.sleep(0.2)


def workers(pid: int) -> list[int]:
    """A `quadsynth serve`'s worker processes (itself when it runs one)."""
    children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    spawned = [int(c) for c in children if b"spawn_main" in Path(f"/proc/{c}/cmdline").read_bytes()]
    return spawned or [pid]


def rss_mb(pid: int) -> float:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


class Watch:
    """While open: peak RSS of ``pids`` and /livez latencies of ``url``, sampled in threads."""

    def __init__(self, url: str, pids: list[int]) -> None:
        self.url, self.pids = url, pids
        self.peak = dict.fromkeys(pids, 0.0)
        self.livez: list[float] = []
        self.livez_failed = 0
        self.stop = threading.Event()

    def _rss(self) -> None:
        while not self.stop.wait(0.05):
            for pid in self.pids:
                self.peak[pid] = max(self.peak[pid], rss_mb(pid))

    def _livez(self) -> None:
        with httpx.Client(timeout=10) as client:
            while not self.stop.wait(0.02):
                t0 = time.perf_counter()
                try:
                    client.get(f"{self.url}/livez")
                    self.livez.append(time.perf_counter() - t0)
                except httpx.TransportError:
                    self.livez_failed += 1

    def __enter__(self) -> Watch:
        self.threads = [threading.Thread(target=self._rss), threading.Thread(target=self._livez)]
        for t in self.threads:
            t.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        for t in self.threads:
            t.join()

    def report(self) -> dict[str, Any]:
        ms = np.asarray(self.livez) * 1000 if self.livez else np.zeros(1)
        return {"peak_rss_mb": {str(p): round(v, 1) for p, v in self.peak.items()},
                "workers_alive": sum(Path(f"/proc/{p}").exists() for p in self.pids),
                "livez_ms": {"p50": round(float(np.percentile(ms, 50)), 1),
                             "p99": round(float(np.percentile(ms, 99)), 1),
                             "max": round(float(ms.max()), 1), "n": len(self.livez),
                             "failed": self.livez_failed}}


def maximal_body(encoding: str, frames: int = 8000, characters: int = 250) -> dict[str, Any]:
    """``characters`` x 2 points spread over ``frames`` library frames: a tiny body, a maximal answer."""
    fps = 60.0 / (frames - 1)
    rng = np.random.default_rng(0)
    start = rng.uniform(-50, 50, (characters, 3)) * [1, 0, 1]
    paths = np.stack([start, start + [0.0, 0.0, 2.0]], axis=1).astype(np.float32)
    return {"fps": fps, "encoding": encoding, "seed": 1,
            "characters": [{"id": f"c{c}", "points": blob(paths[c])} for c in range(characters)]}


def big_body(limit: int) -> bytes:
    """Up to ``limit`` bytes of msgpack: 10,000 characters of 60 points for an unknown animal
    (all of it decoded and validated before the refusal)."""
    points = blob(np.zeros((60, 3), np.float32))
    body = {"animal": "no-such-animal",
            "characters": [{"id": f"c{c}", "points": points} for c in range(10_000)]}
    raw = bytes(msgpack.packb(body, use_bin_type=True))
    assert len(raw) <= limit, len(raw)
    return raw


def read_all(client: httpx.Client, raw: bytes, content_type: str) -> tuple[int, int]:
    """Status and bytes lost (Content-Length minus what came) of one request, read and dropped."""
    got, length = 0, -1
    try:
        with client.stream("POST", "/v1/synthesize", content=raw,
                           headers={"content-type": content_type}) as r:
            length = int(r.headers.get("content-length", -1))
            for piece in r.iter_raw():
                got += len(piece)
            return r.status_code, 0
    except httpx.TransportError:
        return -1, max(length - got, 0)


def stalled(url: str, pids: list[int], seconds: float) -> dict[str, Any]:
    settings = Settings.from_env()
    raw = bytes(msgpack.packb(maximal_body("f32"), use_bin_type=True))
    big = big_body(settings.max_body_bytes)
    host, port = url.removeprefix("http://").split(":")
    statuses: Counter[str] = Counter()
    lost = 0
    socks = []
    with Watch(url, pids) as watch:
        for _ in range(3):  # ask, never read
            sock = socket.socket()
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 16 * 1024)
            sock.connect((host, int(port)))
            sock.sendall(f"POST /v1/synthesize HTTP/1.1\r\nHost: {host}\r\nContent-Type: {MSGPACK}\r\n"
                         f"Content-Length: {len(raw)}\r\n\r\n".encode() + raw)
            socks.append(sock)
        end = time.monotonic() + seconds
        with httpx.Client(base_url=url, timeout=120) as client:
            while time.monotonic() < end:
                status, missing = read_all(client, big, MSGPACK)
                statuses[str(status)] += 1
                lost += missing
        for sock in socks:
            sock.close()
    return {**watch.report(), "big_bodies_status": dict(statuses), "bytes_lost": lost,
            "memory_budget_mb": settings.memory_budget_mb}


def largest(url: str, pids: list[int]) -> dict[str, Any]:
    settings = Settings.from_env()
    out: dict[str, Any] = {"memory_budget_mb": settings.memory_budget_mb}
    body = maximal_body("f32")
    for name, raw, kind in (
            ("f32_msgpack", bytes(msgpack.packb(body, use_bin_type=True)), MSGPACK),
            ("f32_json", json.dumps(body, default=lambda b: base64.b64encode(b).decode()).encode(),
             "application/json")):
        with Watch(url, pids) as watch, httpx.Client(base_url=url, timeout=600) as client:
            t0 = time.perf_counter()
            status, lost = read_all(client, raw, kind)
            seconds = time.perf_counter() - t0
        out[name] = {**watch.report(), "status": status, "bytes_lost": lost, "seconds": round(seconds, 2)}
    return out


@contextmanager
def cluster() -> Iterator[tuple[str, list[subprocess.Popen[bytes]]]]:
    """Two one-worker replicas behind deploy/nginx.conf (tests/test_nginx.py's rewrite)."""
    from tests.test_nginx import local_config

    run = subprocess.run([str(REPO / "scripts" / "ensure-nginx")], capture_output=True, text=True,
                         timeout=900)
    if run.returncode != 0:
        raise SystemExit(f"no nginx: {run.stderr.strip()[-300:]}")
    nginx = run.stdout.strip().splitlines()[-1]
    ports = [free_port(), free_port()]
    procs = [serve(p, 1) for p in ports]
    workdir = Path(tempfile.mkdtemp(prefix="quadsynth-drill-"))
    workdir.chmod(0o755)
    front = free_port()
    (workdir / "nginx.conf").write_text(local_config(ports, front, workdir))
    balancer = subprocess.Popen([nginx, "-p", str(workdir), "-c", str(workdir / "nginx.conf"),
                                 "-e", str(workdir / "error.log"), "-g", "daemon off;"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for proc, port in zip(procs, ports, strict=True):
            wait_ready(f"http://127.0.0.1:{port}", proc)
        yield f"http://127.0.0.1:{front}", procs
    finally:
        balancer.terminate()
        balancer.wait(timeout=10)
        for proc in procs:
            if proc.poll() is None:
                proc.terminate()
                proc.wait(timeout=60)


def kill9(seconds: float) -> dict[str, Any]:
    herd = crowd.simulate(60, 400, seed=3).astype(np.float32)
    with cluster() as (url, procs):
        outcomes: Counter[str] = Counter()
        retries: list[int] = []
        stop = threading.Event()

        def load() -> None:
            with Client(url, timeout=120, max_retries=3) as qs:
                while not stop.is_set():
                    try:
                        qs.synthesize(herd, seed=2)
                        outcomes["200"] += 1
                    except Exception as exc:  # noqa: BLE001 - every failure is a lost request here
                        outcomes[type(exc).__name__] += 1
                retries.append(qs.retries)

        threads = [threading.Thread(target=load) for _ in range(4)]
        for t in threads:
            t.start()
        time.sleep(seconds / 3)
        procs[0].send_signal(signal.SIGKILL)
        time.sleep(seconds * 2 / 3)
        stop.set()
        for t in threads:
            t.join()
    lost = sum(n for k, n in outcomes.items() if k != "200")
    return {"outcomes": dict(outcomes), "requests_lost": lost, "client_retries": sum(retries)}


def run(quick: bool) -> dict[str, Any]:
    seconds = 8.0 if quick else 20.0
    out: dict[str, Any] = {}
    port = free_port()
    proc = serve(port, 2)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_ready(url, proc)
        pids = workers(proc.pid)
        out["baseline_rss_mb"] = {str(p): round(rss_mb(p), 1) for p in pids}
        out["stalled"] = stalled(url, pids, seconds)
        out["largest"] = largest(url, pids)
        out["service_metrics"] = _metrics(url)
    finally:
        proc.terminate()
        proc.wait(timeout=60)
    try:
        out["kill9"] = kill9(seconds)
    except SystemExit as exc:
        out["kill9"] = {"skipped": str(exc)}
    return out


def _metrics(url: str) -> dict[str, float]:
    """The refusal and cancellation counters of the worker that answers this scrape."""
    found = re.findall(r'^(quadsynth_(?:rejected|cancelled)_total)\{[^}]*?(?:reason="(\w+)")?\} (\S+)$',
                       httpx.get(f"{url}/metrics").text, re.MULTILINE)
    return {f"{name}/{reason}" if reason else name: float(value) for name, reason, value in found}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="shorter drills")
    args = parser.parse_args()
    print(json.dumps(run(args.quick), indent=2))


if __name__ == "__main__":
    main()
