"""deploy/nginx.conf in front of two `quadsynth serve` replicas on loopback (nginx installed by
scripts/ensure-nginx; the tests skip without it)."""

from __future__ import annotations

import re
import subprocess
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest

from tests.helpers import REPO
from tests.helpers.servers import free_port, start, wait_until_ready

QUEUED = 3  # per replica, behind its one request in flight
REPLICA_ENV = {"QUADSYNTH_MAX_IN_FLIGHT": "1", "QUADSYNTH_MAX_QUEUED": str(QUEUED),
               "QUADSYNTH_TEST_HOOKS": "1"}


def nginx_binary() -> str:
    run = subprocess.run([str(REPO / "scripts" / "ensure-nginx")], capture_output=True, text=True,
                         timeout=900)
    if run.returncode != 0:
        pytest.skip(f"no nginx for the load-balancer test: {run.stderr.strip().splitlines()[-1:]}")
    return run.stdout.strip().splitlines()[-1]


def local_config(replicas: list[int], port: int, workdir: Path) -> str:
    """deploy/nginx.conf with the replicas on loopback and everything it writes under `workdir`."""
    conf = (REPO / "deploy" / "nginx.conf").read_text()
    servers = "\n".join(f"        server 127.0.0.1:{p} max_fails=3 fail_timeout=5s;" for p in replicas)
    rewrites = [(r"^\s*server quadsynth:8000 resolve max_fails=3 fail_timeout=5s;.*$", servers),
                (r"^\s*resolver .*$", ""),
                (r"^pid .*$", f"pid {workdir}/nginx.pid;"),
                (r"client_body_temp_path \S+;", f"client_body_temp_path {workdir}/body;"),
                (r"proxy_temp_path \S+;", f"proxy_temp_path {workdir}/proxy;"),
                (r"listen 8080;", f"listen 127.0.0.1:{port};")]
    for pattern, replacement in rewrites:
        conf, n = re.subn(pattern, replacement, conf, flags=re.MULTILINE)
        assert n == 1, f"deploy/nginx.conf no longer has {pattern!r}"
    return conf


Cluster = tuple[str, list[str], list[subprocess.Popen[bytes]], Path]


@contextmanager
def nginx_cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    """(nginx URL, the two replicas' own URLs, their processes, nginx's error log)."""
    nginx = nginx_binary()
    ports = [free_port(), free_port()]
    procs = [start(["--port", str(p), "--log-level", "warning"], tmp_path_factory.mktemp(f"replica{i}"),
                   REPLICA_ENV) for i, p in enumerate(ports)]
    urls = [f"http://127.0.0.1:{p}" for p in ports]
    # nginx's workers drop root to `nobody`: its directory must be theirs to enter (pytest's is not).
    workdir = Path(tempfile.mkdtemp(prefix="quadsynth-nginx-"))
    workdir.chmod(0o755)
    front = free_port()
    (workdir / "nginx.conf").write_text(local_config(ports, front, workdir))
    balancer = subprocess.Popen([nginx, "-p", str(workdir), "-c", str(workdir / "nginx.conf"),
                                 "-e", str(workdir / "error.log"), "-g", "daemon off;"],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        for proc, url in zip(procs, urls, strict=True):
            wait_until_ready(proc, url)
        url = f"http://127.0.0.1:{front}"
        deadline = time.monotonic() + 10
        while True:
            assert balancer.poll() is None, balancer.stdout.read().decode()  # type: ignore[union-attr]
            try:
                httpx.get(f"{url}/livez", timeout=1)
                break
            except httpx.TransportError:
                assert time.monotonic() < deadline, "nginx did not answer"
                time.sleep(0.1)
        yield url, urls, procs, workdir / "error.log"
    finally:
        balancer.terminate()
        balancer.wait(timeout=10)
        for proc in procs:
            if proc.poll() is None:
                proc.terminate()
                proc.wait(timeout=30)
