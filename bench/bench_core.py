"""Core throughput benchmark: batched FK, BVH parsing, contact detection. Prints one JSON object.

    python -m bench.bench_core [--characters 500] [--frames 500]

Uses the real dog skeleton when ../shared/mocap is beside the repo, else a made-up one, so it
runs anywhere. Timings are best of three; this is a benchmark, not a test.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from synth_core.motion import bvh, quat
from synth_core.motion.contacts import detect_contacts
from synth_core.motion.skeleton import forward_kinematics

MANN = Path(__file__).resolve().parents[1].parent / "shared" / "mocap" / "mann_dog"


def best_of(fn: Callable[[], object], repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--characters", type=int, default=500)
    parser.add_argument("--frames", type=int, default=500)
    args = parser.parse_args()
    source = MANN / "D1_053_KAN01_001.bvh"
    if not source.exists():
        raise SystemExit(f"needs the real dog mocap at {source}")
    motion = bvh.read(source)
    C, F = args.characters, args.frames
    rng = np.random.default_rng(0)
    picks = rng.integers(0, motion.n_frames, size=(C, F))
    rotations = motion.rotations[picks]  # (C, F, J, 4)
    root = motion.root_pos[picks]
    fk_s = best_of(lambda: forward_kinematics(motion.skeleton, root, rotations))
    text = source.read_text()
    parse_s = best_of(lambda: bvh.parse(text))
    contacts_s = best_of(lambda: detect_contacts(motion))
    rot64 = quat.normalize(rng.normal(size=(C * F, 4)))
    mul_s = best_of(lambda: quat.mul(rot64, rot64))
    print(json.dumps({
        "fk_char_frames_per_s": round(C * F / fk_s),
        "fk_joints": motion.skeleton.n_joints,
        "bvh_parse_mb_per_s": round(len(text) / parse_s / 1e6, 2),
        "contacts_frames_per_s": round(motion.n_frames / contacts_s),
        "quat_mul_per_s": round(C * F / mul_s),
        "characters": C,
        "frames": F,
    }))


if __name__ == "__main__":
    main()
