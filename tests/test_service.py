"""`quadsynth serve` really starts the service: /livez, /readyz, /v1/libraries over loopback HTTP."""

from __future__ import annotations

import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import msgpack
import numpy as np
import pytest

from api_schemas.wire import blob
from service.cpus import available_cpus
from tests.helpers.servers import free_port, start, wait_until_live


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
    cores = available_cpus()  # the CPU quota's cores, as serve counts them (service.cpus)
    assert len(worker_processes(proc.pid)) == (cores if cores > 1 else 0)  # one core: no supervisor
    assert httpx.get(f"{url}/livez").status_code == 200


def test_livez(server: str) -> None:
    response = httpx.get(f"{server}/livez")
    assert response.status_code == 200 and response.json() == {"status": "ok"}


def test_readyz_once_libraries_are_loaded(server: str) -> None:
    response = httpx.get(f"{server}/readyz")
    assert response.status_code == 200
    answer = response.json()
    assert answer["status"] == "ready" and answer["libraries"] == 2
    assert sorted(answer["library_status"], key=lambda s: s["name"]) == [
        {"name": "dog", "state": "loaded", "reason": ""}, {"name": "horse", "state": "loaded", "reason": ""}]


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


def test_a_missing_or_broken_library_keeps_readyz_at_503_naming_it(tmp_path: Path) -> None:
    """Configured for a cat it has no file of, and given a corrupt file: the horse and dog still
    serve, but /readyz says 503 with a status per library (no load balancer sends it traffic)."""
    (tmp_path / "library").mkdir()
    (tmp_path / "library" / "zebra.qslib.npz").write_bytes(b"PK\x03\x04 truncated")
    port = free_port()
    proc = start(["--port", str(port)], tmp_path, {"QUADSYNTH_LIBRARIES": "horse,dog,cat"})
    url = f"http://127.0.0.1:{port}"
    try:
        wait_until_live(proc, url)
        while (ready := httpx.get(f"{url}/readyz")).json()["status"] == "starting":
            time.sleep(0.1)
        assert ready.status_code == 503 and ready.json()["status"] == "incomplete"
        states = {s["name"]: s for s in ready.json()["library_status"]}
        assert {n: s["state"] for n, s in states.items()} == {
            "horse": "loaded", "dog": "loaded", "cat": "missing", "zebra.qslib.npz": "failed"}
        assert "truncated or corrupt" in states["zebra.qslib.npz"]["reason"]
        listed = httpx.get(f"{url}/v1/libraries").json()["libraries"]
        assert sorted(lib["source"] for lib in listed) == ["dog.qslib.npz", "horse.qslib.npz"]
        assert str(tmp_path) not in ready.text + httpx.get(f"{url}/v1/libraries").text  # no server paths
        points = np.zeros((30, 3), np.float32)
        points[:, 2] = np.linspace(0.0, 0.5, 30)
        body = {"animal": "cat", "characters": [{"id": "a", "points": blob(points)}]}
        unknown = httpx.post(f"{url}/v1/synthesize", content=msgpack.packb(body),
                             headers={"content-type": "application/vnd.msgpack"})
        assert unknown.status_code == 404 and unknown.json()["error"]["field"] == "animal", unknown.text
        served = httpx.post(f"{url}/v1/synthesize", content=msgpack.packb({**body, "animal": "horse"}),
                            headers={"content-type": "application/vnd.msgpack"})
        assert served.status_code == 200  # what is loaded still serves
    finally:
        proc.terminate()
        output = proc.communicate(timeout=30)[0].decode()
    steps = [line.split(": ", 1)[1].split(":")[0].split(" ")[0] for line in output.splitlines()
             if line.startswith("quadsynth serve: ")]
    assert steps[:3] == ["port", "libraries", "kernels"] and steps[-1] == "starting", output
    assert "(built horse.qslib.npz, dog.qslib.npz in " in output


def test_a_taken_port_fails_before_anything_is_built(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        proc = start(["--port", str(taken.getsockname()[1])], tmp_path)
        output, _ = proc.communicate(timeout=30)
    assert proc.returncode == 2 and b"cannot listen on 127.0.0.1:" in output and b"in use" in output, output
    assert not (tmp_path / "library").exists()  # nothing built, nothing compiled
