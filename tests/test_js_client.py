"""The JavaScript client (js/, an npm package) under Node against real `quadsynth serve`s:
`node --test js/test/*.test.js` with two services started here -- one as deployed, one that
closes slow consumers within a second (for the reconnection tests). Python computes the
reference pose (synth_core FK) of one request; the JS pose assembly must match it.

Node >= 20 and js/node_modules come from scripts/ensure-node-deps (Debian's packages, npm ci);
the test skips, quoting that script, only where it cannot install them."""

from __future__ import annotations

import json
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from api_schemas.client import Client
from synth_core.motion.skeleton import Skeleton, forward_kinematics
from synth_core.quality import herd_sim as crowd
from tests.helpers.node import node_binary
from tests.helpers.servers import running

REPO = Path(__file__).resolve().parents[1]
FLAKY = {"QUADSYNTH_WS_WINDOW": "1", "QUADSYNTH_WS_SEND_TIMEOUT_S": "1"}


@pytest.fixture(scope="module")
def services(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, str]]:
    with running(tmp_path_factory.mktemp("js")) as (url, _), \
            running(tmp_path_factory.mktemp("js-flaky"), FLAKY) as (flaky, _):
        yield url, flaky


def reference_pose(url: str, path: Path) -> None:
    """A request and, by synth_core's FK, its four feet's world positions every frame (scale
    applied to the offsets) and whether each is planted: what the JS pose assembly must give."""
    positions = crowd.simulate(3, 240, seed=5)
    with Client(url) as qs:
        motion = qs.synthesize(positions, animal="horse", seed=4, encoding="f32")
        detail = qs.library("horse")
    skeleton = Skeleton(tuple(detail["joint_names"]), np.array(detail["parents"]),
                        np.array(detail["offsets"], np.float32), np.array(detail["end_sites"]))
    feet = [detail["joint_names"].index(detail["feet"][f]) for f in ("LF", "RF", "LH", "RH")]
    characters = []
    for ch in motion.characters:
        offsets = skeleton.offsets * np.float32(ch.scale)
        world, _ = forward_kinematics(skeleton, ch.root, ch.rotations, offsets)
        characters.append({"scale": ch.scale, "feet": world[:, feet].tolist(),
                           "planted": ch.contacts.tolist()})
    request = {"animal": "horse", "seed": 4, "fps": 60,
               "characters": [{"id": str(c), "points": p.tolist()} for c, p in enumerate(positions)]}
    path.write_text(json.dumps({"request": request, "characters": characters}))


def test_the_js_client_passes_its_node_tests_against_real_services(
        services: tuple[str, str], tmp_path: Path) -> None:
    node = node_binary()
    url, flaky = services
    reference_pose(url, tmp_path / "pose.json")
    tests = sorted(str(p.relative_to(REPO)) for p in (REPO / "js" / "test").glob("*.test.js"))
    env = {**os.environ, "QUADSYNTH_URL": url, "QUADSYNTH_FLAKY_URL": flaky,
           "QUADSYNTH_POSE_FIXTURE": str(tmp_path / "pose.json")}
    run = subprocess.run([node, "--test", "--test-reporter=spec", *tests], cwd=REPO, env=env,
                         capture_output=True, text=True, timeout=600)
    print(run.stdout)
    assert run.returncode == 0, run.stdout[-6000:] + run.stderr[-2000:]
    assert "skipped 0" in run.stdout.replace("ℹ ", "") or "# skipped 0" in run.stdout, "a node test skipped"
