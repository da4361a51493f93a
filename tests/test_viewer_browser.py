"""The viewer in a real browser: Debian's Chromium (scripts/ensure-chromium), driven by
playwright-core (js/browser/viewer-run.js), opens /viewer against a running `quadsynth serve` and
watches a live herd: chunks arrive, animals are drawn (pixels differ from the empty scene), no
console errors. The screenshot is kept in out/viewer-test.png. Timings are reported, not
asserted (`python -m bench.bench_viewer` measures them)."""

from __future__ import annotations

import json
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.helpers.node import node_binary
from tests.helpers.servers import running

REPO = Path(__file__).resolve().parents[1]


def chromium_binary() -> str:
    run = subprocess.run([str(REPO / "scripts" / "ensure-chromium")], capture_output=True, text=True,
                         timeout=900)
    if run.returncode != 0:
        pytest.skip(f"no chromium for the browser test: {run.stderr.strip().splitlines()[-1:]}")
    return run.stdout.strip().splitlines()[-1]


def view(node: str, chromium: str, url: str, herd: int, seconds: float, screenshot: Path,
         animal: str = "horse", query: str = "") -> dict[str, object]:
    """What js/browser/viewer-run.js saw (its JSON); `query`: more URL parameters."""
    run = subprocess.run([node, "js/browser/viewer-run.js", "--url", url, "--chromium", chromium,
                          "--animal", animal, "--herd", str(herd), "--seconds", str(seconds),
                          "--screenshot", str(screenshot), "--query", query],
                         cwd=REPO, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    result: dict[str, object] = json.loads(run.stdout.strip().splitlines()[-1])
    return result


@pytest.fixture(scope="module")
def url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with running(tmp_path_factory.mktemp("browser")) as (url, _):
        yield url


@pytest.mark.parametrize("animal", ["horse", "dog"])
def test_the_viewer_streams_and_draws_a_live_herd_in_chromium(url: str, tmp_path: Path, animal: str) -> None:
    chromium, node = chromium_binary(), node_binary()
    seen = view(node, chromium, url, 40, 5, tmp_path / "viewer.png", animal)
    print(json.dumps({k: v for k, v in seen.items() if k != "samples"}))
    # A service without a mesh for the animal answers its mesh.glb with 404: the viewer then
    # draws instanced bones. That one expected 404 aside, the console must stay clean.
    errors = [e for e in seen["consoleErrors"] if "/mesh.glb" not in str(e)]  # type: ignore[attr-defined]
    assert errors == [] and seen["errors"] == []
    assert int(seen["chunks"]) >= 2 and int(seen["frames"]) > 30  # type: ignore[call-overload]
    pixels = seen["pixels"]
    assert isinstance(pixels, dict) and pixels["differ"] > 0.002 * pixels["total"], pixels
    assert seen["firstDrawMs"] is not None and int(seen["drawn"]) >= 1  # type: ignore[call-overload]
    out = REPO / "out"
    out.mkdir(exist_ok=True)
    shutil.copy(tmp_path / "viewer.png", out / f"viewer-test-{animal}.png")


def test_the_viewer_walks_a_live_herd_on_hills_it_draws(url: str, tmp_path: Path) -> None:
    """`?terrain=hills`: the page makes a height field, sends it as the live session's `ground`
    and draws it; the service stands the herd on it (the points' y stay 0), so every animal's
    lowest foot is near the drawn ground under it, not at y = 0."""
    chromium, node = chromium_binary(), node_binary()
    seen = view(node, chromium, url, 20, 6, tmp_path / "viewer.png", "horse", "&terrain=hills")
    print(json.dumps({k: v for k, v in seen.items() if k not in ("samples", "terrainFeet")}))
    errors = [e for e in seen["consoleErrors"] if "/mesh.glb" not in str(e)]  # type: ignore[attr-defined]
    assert errors == [] and seen["errors"] == []
    terrain, feet = seen["terrain"], seen["terrainFeet"]
    assert isinstance(terrain, dict) and isinstance(feet, dict), (terrain, feet)
    assert terrain["vertices"] == terrain["nx"] * terrain["nz"] and terrain["high"] - terrain["low"] > 1.0
    lowest, under = feet["lowestFootOverGround"], feet["groundUnderRoot"]
    print(json.dumps(feet))
    assert len(lowest) == len(under) == 20
    # A herd standing on y = 0 instead would be up to a metre off these hills.
    assert max(abs(u) for u in under) > 0.2, under
    assert all(-0.02 < h < 0.1 for h in lowest), lowest
    out = REPO / "out"
    out.mkdir(exist_ok=True)
    shutil.copy(tmp_path / "viewer.png", out / "viewer-test-terrain.png")
