"""The rotation encodings' world error and size on real synthesized motion:
``python -m bench.bench_wire [--quick]``. Prints one JSON object (docs/wire-format.md's table).

For each animal (horse, dog) and motion set -- the standard herd (500 characters x 500 frames at
60 fps, ``quadsynth eval``'s) and every edge-suite scenario's output (synth_core.quality.edge) --
each encoding's rotations are decoded and both motions put through FK (float64, each character
at its scale): the error is the distance between a joint's decoded and undecoded world position.
Reported at the feet (max and p99 over every foot-frame) and at every joint (max), with the bytes
of the rotations per joint-frame: whole motions (a REST answer), and cut into chunks of 28 frames
at 30 fps (a live session's; every other frame of the 60 fps motion). Not a test: no timing.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np
from numpy.typing import NDArray

from api_schemas import delta
from api_schemas.wire import decode_rotations, encode_rotations
from synth_core.build.motion_graph import HUBS
from synth_core.motion.skeleton import Skeleton, forward_kinematics
from synth_core.quality import edge, evaluate
from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.synthesis import Options, synthesize

LIVE_CHUNK = 28  # frames per live chunk at 30 fps (the horse's segment)


def roundtrip(q: NDArray[np.float32], encoding: str, skeleton: Skeleton, scales: NDArray[np.floating],
              chunk: int | None = None) -> tuple[NDArray[np.float32], int]:
    """``q (C, F, J, 4)`` encoded and decoded (in chunks of ``chunk`` frames), and its bytes."""
    if encoding != "delta":
        packed = encode_rotations(q, encoding)  # type: ignore[arg-type]
        return decode_rotations(packed, encoding), packed.nbytes  # type: ignore[arg-type]
    codes = np.stack([delta.joint_steps(skeleton.parents, skeleton.offsets, float(h)) for h in scales])
    F = q.shape[1]
    step = chunk or F
    parts, size = [], 0
    for a in range(0, F, step):
        buf, _ = delta.encode(q[:, a:a + step], codes)
        size += len(buf)
        parts.append(np.stack(delta.decode(buf)))
    return np.concatenate(parts, axis=1), size


def errors(skeleton: Skeleton, root: NDArray[Any], q: NDArray[Any], back: NDArray[Any],
           scales: NDArray[Any]) -> NDArray[np.float64]:
    """World position error ``(C, F, J)`` in mm, decoded against undecoded, float64 FK."""
    offsets = skeleton.offsets[None, None].astype(np.float64) * scales[:, None, None, None]
    a, _ = forward_kinematics(skeleton, root.astype(np.float64), q.astype(np.float64), offsets)
    b, _ = forward_kinematics(skeleton, root.astype(np.float64), back.astype(np.float64), offsets)
    return np.asarray(np.linalg.norm(a - b, axis=-1) * 1000.0)


def motions(bank: Bank, quick: bool) -> dict[str, tuple[NDArray[Any], NDArray[Any], NDArray[Any]]]:
    """name -> (root (C, F, 3), rotations (C, F, J, 4), scales (C,)) of the standard herd and the
    edge scenarios."""
    C, F = (60, 300) if quick else (500, 500)
    paths = crowd.simulate(C, F, seed=0, top=evaluate.crowd_top_speed(bank))
    r = synthesize(bank, paths, options=Options(scale_range=(0.8, 1.2), seed=0))
    out = {"standard": (r.root_pos, r.rotations, r.scales)}
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    for sc in edge.scenarios(gaits, bank.fps, 0):
        try:
            e = synthesize(bank, sc.positions, bank.fps, scales=sc.scales, options=Options(seed=0))
        except ValueError:
            continue  # a refused scenario has no motion to encode
        out[f"edge/{sc.name}"] = (e.root_pos, e.rotations, e.scales)
    return out


cache: dict[str, tuple[NDArray[Any], NDArray[Any], NDArray[Any]]] = {}


def run(quick: bool = False) -> dict[str, Any]:
    from synth_core.build.library_store import builtin_library

    out: dict[str, Any] = {"max_error_m_budget": delta.MAX_ERROR_M}
    for animal in ("horse", "dog"):
        bank = build_bank(builtin_library(animal))
        cache.clear()
        cache.update(motions(bank, quick))
        out[animal] = figures_cached(bank)
    return out


def figures_cached(bank: Bank) -> dict[str, Any]:
    """Per encoding, mode (REST at 60 fps; live chunks at 30 fps) and motion set (the standard
    herd; the edge suite's scenarios together): bytes per joint-frame and the errors."""
    sk = bank.skeleton
    feet = sk.foot_joints
    result: dict[str, Any] = {}
    for enc in ("s48", "delta"):
        for mode, chunk, stride in (("rest_60fps", None, 1), ("live_30fps_chunks", LIVE_CHUNK, 2)):
            for group in ("standard", "edge"):
                hoof, every, flat, size, jf = [], [], [], 0, 0
                for name, (root, q, scales) in cache.items():
                    if name.split("/")[0] != group:
                        continue
                    root, q = root[:, ::stride], q[:, ::stride]
                    back, nbytes = roundtrip(q, enc, sk, scales, chunk)
                    err = errors(sk, root, q, back, scales)
                    hoof.append(float(err[..., feet].max()))
                    flat.append(err[..., feet].reshape(-1))
                    every.append(float(err.max()))
                    size += nbytes
                    jf += q.shape[0] * q.shape[1] * q.shape[2]
                result.setdefault(enc, {}).setdefault(mode, {})[group] = {
                    "bytes_per_joint_frame": round(size / jf, 3),
                    "hoof_error_mm_max": round(max(hoof), 4),
                    "hoof_error_mm_p99": round(float(np.percentile(np.concatenate(flat), 99)), 4),
                    "joint_error_mm_max": round(max(every), 4), "joint_frames": jf}
    return result


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="a 60 x 300 standard herd instead of 500 x 500")
    print(json.dumps(run(parser.parse_args().quick), indent=2))
