"""Node.js for the JS client's tests (installed by a project script; skipped without)."""

from __future__ import annotations

import subprocess

import pytest

from tests.helpers import REPO


def node_binary() -> str:
    run = subprocess.run([str(REPO / "scripts" / "ensure-node-deps")], capture_output=True, text=True,
                         timeout=900)
    if run.returncode != 0:
        pytest.skip(f"no node for the JS client's tests: {run.stderr.strip().splitlines()[-1:]}")
    return run.stdout.strip().splitlines()[-1]
