"""`quadsynth serve` really starts the service: /livez, /readyz, /v1/libraries over loopback HTTP."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

STARTUP_TIMEOUT_S = 30.0


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def quadsynth_command() -> list[str]:
    script = Path(sys.executable).with_name("quadsynth")
    return [str(script)] if script.exists() else [sys.executable, "-m", "quadsynth.cli"]


def start(args: list[str], tmp_path: Path, env: dict[str, str] | None = None) -> subprocess.Popen[bytes]:
    env = {**os.environ, "QUADSYNTH_LIBRARY_DIR": str(tmp_path / "library"), **(env or {})}
    return subprocess.Popen([*quadsynth_command(), "serve", *args], env=env,
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


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    port = free_port()
    proc = start(["--port", str(port), "--log-level", "warning"], tmp_path_factory.mktemp("srv"))
    url = f"http://127.0.0.1:{port}"
    try:
        wait_until_live(proc, url)
        yield url
    finally:
        proc.terminate()
        proc.wait(timeout=10)


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
