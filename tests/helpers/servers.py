"""`quadsynth serve` started for a test on a free port, and what its /metrics read."""

from __future__ import annotations

import os
import random
import re
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx

PORT_LOW = 20000  # well above the ports system services listen on
STARTUP_TIMEOUT_S = 120.0  # the first start after an empty numba cache compiles the kernels (~30 s here)


def ephemeral_low() -> int:
    """The lowest port the kernel hands to outgoing connections (Linux; the IANA range elsewhere)."""
    try:
        return int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 49152


def free_port() -> int:
    """A port nothing listens on, drawn below the ephemeral range: a port the kernel picked for
    bind(0) is ephemeral, so a client's outgoing connection could take it before the server binds
    it (seen once as "Address already in use" starting nginx in tests/test_fanout.py)."""
    draw = random.Random()
    for _ in range(500):
        port = draw.randrange(PORT_LOW, max(PORT_LOW + 1, ephemeral_low()))
        with socket.socket() as sock:
            try:
                sock.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    raise AssertionError(f"no free port between {PORT_LOW} and {ephemeral_low()}")


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


def wait_until_ready(proc: subprocess.Popen[bytes], url: str) -> None:
    """Until the server at ``url`` answers /livez, then /readyz 200 (every library loaded)."""
    wait_until_live(proc, url)
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while httpx.get(f"{url}/readyz").status_code != 200:
        if time.monotonic() > deadline:
            raise AssertionError(f"server not ready within {STARTUP_TIMEOUT_S} s: "
                                 f"{httpx.get(f'{url}/readyz').text}")
        time.sleep(0.1)


@contextmanager
def running(tmp_path: Path,
            env: dict[str, str] | None = None) -> Iterator[tuple[str, subprocess.Popen[bytes]]]:
    """A `quadsynth serve` (one worker) on a free port, ready (/readyz 200): (url, process)."""
    port = free_port()
    proc = start(["--port", str(port), "--log-level", "warning"], tmp_path, env)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_until_ready(proc, url)
        yield url, proc
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(timeout=30)


def metric(url: str, name: str) -> float:
    for line in httpx.get(f"{url}/metrics").text.splitlines():
        if line.startswith(name + "{"):
            return float(line.rsplit(" ", 1)[1])
    raise AssertionError(f"{name} not in /metrics")


def wait_for(url: str, name: str, value: float, timeout: float = 90.0) -> None:
    """Until the metric ``name`` reads ``value`` (polled: the server's own state, not a sleep)."""
    deadline = time.monotonic() + timeout
    while metric(url, name) != value:
        assert time.monotonic() < deadline, f"{name} never reached {value}: {metric(url, name)}"
        time.sleep(0.05)


def in_flight(url: str) -> int:
    """Requests running or queued in this replica (its own /metrics)."""
    found = re.search(r"^quadsynth_in_flight{.*} (\d+)$", httpx.get(f"{url}/metrics").text, re.MULTILINE)
    assert found
    return int(found[1])
