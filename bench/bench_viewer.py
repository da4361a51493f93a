"""Viewer benchmark: ``python -m bench.bench_viewer [--url URL] [--screenshot docs/viewer.png]``.

Opens /viewer in headless Chromium (scripts/ensure-chromium, js/browser/viewer-run.js) against a
service (started on a free port unless ``--url``) and prints one JSON object:

- ``first_pose_ms``: from the page's navigation start to the first animals drawn, for a small
  herd (best and all of ``--repeats`` fresh page loads);
- ``live``: a 1,000-animal herd streamed live for ``--seconds``: frames received per second
  against the stream's fps (the stream keeping up), stalls (playback caught up with the newest
  frame), the buffer ahead, the client's pose-assembly + upload time per drawn frame, and the
  draw rate (software GL here: headless Chromium has no GPU on this machine);
- ``pose_assembly_node``: the same world matrices for 1,000 animals of 40 joints under Node
  (js/bench/pose.js): the pose work alone, without the page's buffers and drawing.

The machine's load average is reported beside them: on a shared 2-core VM the draw rate and the
frame time follow it. Not a test.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import tempfile
from contextlib import nullcontext
from pathlib import Path
from typing import Any

from quadsynth.bench_service import local_service

REPO = Path(__file__).resolve().parents[1]


def tool(script: str) -> str:
    run = subprocess.run([str(REPO / "scripts" / script)], capture_output=True, text=True, timeout=900,
                         check=True)
    return run.stdout.strip().splitlines()[-1]


def view(url: str, herd: int, seconds: float, screenshot: str | None = None,
         animal: str = "horse") -> dict[str, Any]:
    args = [tool("ensure-node-deps"), "js/browser/viewer-run.js", "--url", url, "--chromium",
            tool("ensure-chromium"), "--animal", animal, "--herd", str(herd), "--seconds", str(seconds)]
    if screenshot:
        args += ["--screenshot", screenshot]
    run = subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=600, check=True)
    result: dict[str, Any] = json.loads(run.stdout.strip().splitlines()[-1])
    return result


def live_figures(seen: dict[str, Any]) -> dict[str, Any]:
    samples = seen["samples"][2:] or seen["samples"]  # after the first burst
    span = max((samples[-1]["t"] - samples[0]["t"]) / 1000, 1e-3)
    received = (samples[-1]["frames"] - samples[0]["frames"]) / span
    return {"animals": seen["herd"], "first_pose_ms": round(seen["firstDrawMs"]),
            "frames_received_per_s": round(received, 1), "stream_fps": seen["streamFps"],
            "stalls": seen["stalls"], "stalled_s": round(seen["stalledS"], 2),
            "buffer_ahead_s_min": round(min(s["aheadS"] for s in samples), 2),
            "client_frame_ms": round(seen["frameMs"], 1), "client_frame_ms_p95": round(seen["frameMsP95"], 1),
            "draws_per_s": round(seen["renderFps"], 2), "chunks": seen["chunks"],
            "console_errors": seen["consoleErrors"]}


def run(url: str | None, repeats: int, seconds: float, screenshot: str | None) -> dict[str, Any]:
    with local_service() if url is None else nullcontext(url) as base:
        firsts = [view(base, 50, 1)["firstDrawMs"] for _ in range(repeats)]
        live = view(base, 1000, seconds)
        if screenshot:
            with tempfile.TemporaryDirectory() as tmp:
                shot = str(Path(tmp) / "viewer.png")
                view(base, 200, 6, shot)
                Path(screenshot).write_bytes(Path(shot).read_bytes())
    pose = subprocess.run([tool("ensure-node-deps"), "js/bench/pose.js"], cwd=REPO, capture_output=True,
                          text=True, timeout=300, check=True)
    return {"first_pose_ms": {"herd": 50, "best": round(min(firsts)), "all": [round(f) for f in firsts]},
            "live": live_figures(live), "pose_assembly_node": json.loads(pose.stdout),
            "load_average": os.getloadavg()}


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", default=None, help="a running service (default: start one)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--screenshot", default=None, help="also save a 200-horse view here (PNG)")
    a = parser.parse_args()
    print(json.dumps(run(a.url, a.repeats, a.seconds, a.screenshot)))
