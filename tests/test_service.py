"""`quadsynth serve` really starts the service: /livez, /readyz, /v1/libraries over loopback HTTP."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest

STARTUP_TIMEOUT_S = 120.0  # the first start after an empty numba cache compiles the kernels (~30 s here)


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def quadsynth_command() -> list[str]:
    script = Path(sys.executable).with_name("quadsynth")
    return [str(script)] if script.exists() else [sys.executable, "-m", "quadsynth.cli"]


def start(args: list[str], tmp_path: Path, env: dict[str, str] | None = None,
          workers: int | None = 1) -> subprocess.Popen[bytes]:
    """`quadsynth serve` with `args`; one worker process unless told (tests that hold the workers or
    count requests need them all in one process); workers=None keeps serve's default."""
    env = {**os.environ, "QUADSYNTH_LIBRARY_DIR": str(tmp_path / "library"), **(env or {})}
    env.pop("WEB_CONCURRENCY", None)
    more = [] if workers is None else ["--workers", str(workers)]
    return subprocess.Popen([*quadsynth_command(), "serve", *more, *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


def wait_until_live(proc: subprocess.Popen[bytes], url: str) -> None:
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise AssertionError(f"server exited early: {proc.stdout.read().decode()}")  # type: ignore[union-attr]
        try:
            if httpx.get(f"{url}/livez", timeout=1.0).status_code == 200:
                return
        except httpx.TransportError:
            time.sleep(0.1)
    raise AssertionError(f"server did not answer /livez within {STARTUP_TIMEOUT_S} s")


@contextmanager
def running(tmp_path: Path,
            env: dict[str, str] | None = None) -> Iterator[tuple[str, subprocess.Popen[bytes]]]:
    """A `quadsynth serve` (one worker) on a free port, ready (/readyz 200): (url, process)."""
    port = free_port()
    proc = start(["--port", str(port), "--log-level", "warning"], tmp_path, env)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_until_live(proc, url)
        while httpx.get(f"{url}/readyz").status_code != 200:
            time.sleep(0.1)
        yield url, proc
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(timeout=30)


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, subprocess.Popen[bytes]]]:
    """`quadsynth serve` with its defaults: one worker process per core."""
    port = free_port()
    proc = start(["--port", str(port), "--log-level", "warning"], tmp_path_factory.mktemp("srv"),
                 workers=None)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_until_live(proc, url)
        yield url, proc
    finally:
        proc.terminate()
        assert proc.wait(timeout=30) in (0, -signal.SIGTERM)


@pytest.fixture(scope="module")
def server(served: tuple[str, subprocess.Popen[bytes]]) -> str:
    return served[0]


def worker_processes(pid: int) -> list[int]:
    """uvicorn's worker processes under `pid` (multiprocessing spawn children; not its resource tracker)."""
    children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    return [int(c) for c in children if b"spawn_main" in Path(f"/proc/{c}/cmdline").read_bytes()]


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc to count processes")
def test_serve_starts_one_worker_process_per_core_by_default(
        served: tuple[str, subprocess.Popen[bytes]]) -> None:
    url, proc = served
    cores = os.cpu_count() or 1
    assert len(worker_processes(proc.pid)) == (cores if cores > 1 else 0)  # one core: no supervisor
    assert httpx.get(f"{url}/livez").status_code == 200


def test_livez(server: str) -> None:
    response = httpx.get(f"{server}/livez")
    assert response.status_code == 200 and response.json() == {"status": "ok"}


def test_readyz_once_libraries_are_loaded(server: str) -> None:
    response = httpx.get(f"{server}/readyz")
    assert response.status_code == 200
    assert response.json() == {"status": "ready", "libraries": 2}


def test_libraries_lists_the_built_in_animals(server: str) -> None:
    response = httpx.get(f"{server}/v1/libraries")
    assert response.status_code == 200
    libraries = {lib["animal"]: lib for lib in response.json()["libraries"]}
    assert set(libraries) == {"horse", "dog"}
    assert libraries["horse"]["joints"] >= 30
    assert libraries["dog"]["feet"] == {"LF": "L_FrontToe_end", "RF": "R_FrontToe_end",
                                        "LH": "L_HindToe_end", "RH": "R_HindToe_end"}
    assert libraries["horse"]["fps"] == 60.0


def test_openapi_describes_the_routes(server: str) -> None:
    paths = httpx.get(f"{server}/openapi.json").json()["paths"]
    assert {"/livez", "/readyz", "/v1/libraries"} <= set(paths)


def test_unknown_passthrough_option_fails_with_usage(tmp_path: Path) -> None:
    proc = start(["--port", str(free_port()), "--no-such-option"], tmp_path)
    output, _ = proc.communicate(timeout=30)
    assert proc.returncode != 0
    assert b"no-such-option" in output
