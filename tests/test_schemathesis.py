"""Schemathesis against the running service's own OpenAPI document: every route, bodies in JSON
and msgpack (tests/schemathesis_hooks.py), and no answer may be a server error, an undocumented
status, a wrong content type or a body that breaks its documented schema."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.helpers.servers import running

HOOKS = Path(__file__).with_name("schemathesis_hooks.py")
LIMITS = {"QUADSYNTH_MAX_CHARACTERS": "4", "QUADSYNTH_MAX_FRAMES": "400",
          "QUADSYNTH_MAX_CHARACTER_FRAMES": "2000", "QUADSYNTH_MAX_BODY_BYTES": "65536"}
CHECKS = "not_a_server_error,status_code_conformance,content_type_conformance,response_schema_conformance"


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with running(tmp_path_factory.mktemp("st"), LIMITS) as (url, _):
        yield url


def schemathesis(server: str, workdir: Path, *options: str) -> tuple[str, list[str]]:
    """A schemathesis run (a fixed seed: the same cases on every run) with ``options``: its
    report, and the status of every synthesize POST it made (logged by the hooks)."""
    command = [str(Path(sys.executable).with_name("schemathesis")), "run", f"{server}/openapi.json",
               "--checks", CHECKS, "--max-examples", "100", "--seed", "20261121", "--workers", "1",
               "--no-color", *options]
    log = workdir / "answers.txt"
    env = {**os.environ, "SCHEMATHESIS_HOOKS": str(HOOKS), "QUADSYNTH_FUZZ_LOG": str(log)}
    run = subprocess.run(command, env=env, cwd=workdir, capture_output=True, text=True, timeout=600)
    report = run.stdout + run.stderr
    assert run.returncode == 0, report[-4000:]
    assert " passed" in report, report[-2000:]
    assert "failed" not in report and "errored" not in report, report[-4000:]
    answers = [line.split()[:3] for line in log.read_text().splitlines()]
    return report, [status for method, path, status in answers
                    if (method, path) == ("POST", "/v1/synthesize")]


def test_schemathesis_finds_no_server_error_and_no_answer_off_the_spec(server: str, tmp_path: Path) -> None:
    report, synthesize = schemathesis(server, tmp_path)  # every route, phase and mode
    # Every operation selected: the 8 of this service (routes added later only add to it).
    selected = re.search(r"(\d+) selected / \1 total", report)
    assert selected and int(selected.group(1)) >= 8, report[-2000:]
    assert not any(status.startswith("5") for status in synthesize), Counter(synthesize)


def test_schemathesis_reaches_the_synthesis(server: str, tmp_path: Path) -> None:
    """Bodies the schema allows, made consistent by the hooks (blobs that hold their shape),
    fuzzed: most are synthesized, none is a server error."""
    report, synthesize = schemathesis(server, tmp_path, "--include-path", "/v1/synthesize",
                                      "--phases", "fuzzing", "--mode", "positive")
    assert len(synthesize) >= 50, report[-2000:]
    assert synthesize.count("200") >= 0.3 * len(synthesize), Counter(synthesize)
    assert not any(status.startswith("5") for status in synthesize), Counter(synthesize)
