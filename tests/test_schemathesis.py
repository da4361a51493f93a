"""Schemathesis against the running service's own OpenAPI document: every route, bodies in JSON
and msgpack (tests/schemathesis_hooks.py), and no answer may be a server error, an undocumented
status, a wrong content type or a body that breaks its documented schema."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.test_service import running

HOOKS = Path(__file__).with_name("schemathesis_hooks.py")
LIMITS = {"QUADSYNTH_MAX_CHARACTERS": "4", "QUADSYNTH_MAX_FRAMES": "400",
          "QUADSYNTH_MAX_CHARACTER_FRAMES": "2000", "QUADSYNTH_MAX_BODY_BYTES": "65536"}
CHECKS = "not_a_server_error,status_code_conformance,content_type_conformance,response_schema_conformance"


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with running(tmp_path_factory.mktemp("st"), LIMITS) as (url, _):
        yield url


def test_schemathesis_finds_no_server_error_and_no_answer_off_the_spec(server: str, tmp_path: Path) -> None:
    # A fixed seed: the same cases on every run (schemathesis prints the seed it used).
    command = [str(Path(sys.executable).with_name("schemathesis")), "run", f"{server}/openapi.json",
               "--checks", CHECKS, "--max-examples", "100", "--seed", "20261121", "--workers", "1",
               "--no-color"]
    env = {**os.environ, "SCHEMATHESIS_HOOKS": str(HOOKS)}
    run = subprocess.run(command, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    report = run.stdout + run.stderr
    assert run.returncode == 0, report[-4000:]
    # Every operation selected: the 8 of this service (routes added later only add to it).
    selected = re.search(r"(\d+) selected / \1 total", report)
    assert selected and int(selected.group(1)) >= 8 and " passed" in report, report[-2000:]
    assert "failed" not in report and "errored" not in report, report[-4000:]
