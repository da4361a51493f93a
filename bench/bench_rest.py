"""REST throughput: 500 horses x 500 frames (crowd-sim), msgpack, s48, over HTTP, end to end.

    ./scripts/serve &        # or any running service
    python -m bench.bench_rest --url http://127.0.0.1:8000

Prints one JSON object (best of ``--repeats``): rest_char_frames_per_s, seconds, response_bytes,
bytes_per_joint_frame. (The issue's `quadsynth bench-service` with WebSocket figures is not
written yet.)
"""

from __future__ import annotations

import argparse
import json
import time

import httpx
import msgpack
import numpy as np

from api_schemas.wire import blob
from synth_core import crowd


def run(url: str, characters: int = 500, frames: int = 500, repeats: int = 4) -> dict[str, float]:
    paths = crowd.simulate(characters, frames, seed=0).astype(np.float32)
    body = msgpack.packb({"seed": 1, "encoding": "s48",
                          "characters": [{"id": f"h{c}", "points": blob(p)} for c, p in enumerate(paths)]})
    best, size, joints = float("inf"), 0, 0
    with httpx.Client(base_url=url, timeout=300) as client:
        joints = len(client.get("/v1/libraries/horse").json()["joint_names"])
        for _ in range(repeats):
            t0 = time.perf_counter()
            response = client.post("/v1/synthesize", content=body,
                                   headers={"content-type": "application/vnd.msgpack"})
            best = min(best, time.perf_counter() - t0)
            response.raise_for_status()
            size = len(response.content)
        rotations = msgpack.unpackb(response.content)["characters"][0]["rotations"]
    return {"rest_char_frames_per_s": round(characters * frames / best), "seconds": round(best, 3),
            "response_bytes": size, "bytes_per_joint_frame": len(rotations["data"]) / (frames * joints)}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--url", default="http://127.0.0.1:8000")
    print(json.dumps(run(parser.parse_args().url)))
