"""``quadsynth client synth``: a herd synthesized by a running service, as ``quadsynth synth`` makes it.

The herd goes in as many requests as the service's published limits need (characters, body
bytes, character-frames). Two request fields make the pieces one herd again: ``first_index``
(each character draws its gait and scale as in one request) and ``min_resample_rate`` (a piece
whose paths were resampled less than the fastest piece's is sent again at that rate, so every
character keeps the same frames and the formation holds). Same file, seed and options: the motion
``quadsynth synth`` makes locally, whatever the cut. With ``concurrency`` N the herd is cut into
at least N pieces and N requests are in flight at once, so N replicas behind a load balancer
share it (each request on a connection of its own).
"""

from __future__ import annotations

import queue
import re
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from api_schemas.client import CharacterMotion, Client, Motion, ServiceError
from synth_core.build.motion_graph import HUBS
from synth_core.motion.skeleton import Skeleton
from synth_core.runtime.synthesis import Result
from synth_core.runtime.trajectory import ALL_INVALID, resample

RATE_ALLOWANCE = 2.0  # output frames a piece is sized for: the retimed frames x this (resampling)
BODY_SLACK = 64 * 1024  # request bytes besides the characters (options, msgpack framing)
CHARACTER_BYTES = 256  # a character's bytes besides its float32 points: id (<= 128), keys, dtype, shape


@dataclass(frozen=True)
class Remote:
    """A herd made by the service: what ``quadsynth synth`` writes from."""

    result: Result
    skeleton: Skeleton
    hubs: tuple[str, ...]
    fps: float
    ids: list[str]  # of the characters kept, in result order
    requests: int


def skeleton_of(detail: dict[str, Any]) -> Skeleton:
    """The library's skeleton from ``GET /v1/libraries/{animal}``."""
    skeleton = Skeleton(tuple(detail["joint_names"]), np.array(detail["parents"]),
                        np.array(detail["offsets"], np.float32), np.array(detail["end_sites"]),
                        name=detail["skeleton_id"])
    return skeleton.with_feet(detail["feet"])


def bind_pose(url: str, animal: str, skeleton: Skeleton) -> NDArray[np.float32] | None:
    """The bind pose of the service's mesh of ``animal`` (its ``mesh.glb``'s joint rotations), so
    a herd written here wears the mesh the service serves; None (the rest pose) from a service
    without meshes."""
    from synth_core.export.gltf import bind_rotations

    with Client(url) as client:
        try:
            glb = client.mesh(animal)
        except ServiceError:
            return None
    return bind_rotations(glb, skeleton.n_joints)


def piece_size(limits: dict[str, Any], points: int, out_frames: int, extra_bytes: int = 0) -> int:
    """Characters per request that keep within every published limit (at least 1);
    ``extra_bytes``: sent with every request besides (a terrain)."""
    by_frames = limits["max_character_frames"] // max(1, int(out_frames * RATE_ALLOWANCE))
    by_body = (limits["max_body_bytes"] - BODY_SLACK - extra_bytes) // (points * 12 + CHARACTER_BYTES)
    return int(max(1, min(limits["max_characters"], by_frames, by_body)))


def _global_field(error: ServiceError, first: int) -> ServiceError:
    """The error with ``characters[k]`` counted in the whole herd, not in the request."""
    field = re.sub(r"^characters\[(\d+)\]", lambda m: f"characters[{int(m[1]) + first}]", error.field)
    return ServiceError(error.status, field, error.message)


def synthesize(url: str, positions: NDArray[np.floating], fps: float, ids: list[str], *,
               animal: str = "horse", progress: Callable[[int, int], None] | None = None,
               timeout: float = 600.0, concurrency: int = 1, **options: Any) -> Remote:
    """``positions`` (C, F, 3) at ``fps`` through the service at ``url``, ``concurrency`` requests
    in flight at once; ``options``: the request's fields (seed, sigma, scale_min, scale_max,
    skip_invalid, encoding, foot_lock)."""
    if concurrency < 1:
        raise ValueError(f"concurrency: must be at least 1, got {concurrency}")
    C, F = positions.shape[:2]
    clients: queue.SimpleQueue[Client] = queue.SimpleQueue()
    opened = [Client(url, timeout=timeout) for _ in range(concurrency)]
    for one in opened:
        clients.put(one)
    try:
        client = opened[0]
        limits, detail = client.limits(), client.library(animal)
        out_frames = int(np.ceil((F - 1) * detail["fps"] / fps)) + 1
        # At least N pieces for N in flight.
        ground = options.get("ground")
        extra = len(ground["heights"]["data"]) if isinstance(ground, dict) else 0
        size = max(1, min(piece_size(limits, F, out_frames, extra), -(-C // concurrency)))
        pieces = [(a, min(a + size, C)) for a in range(0, C, size)]
        done: dict[tuple[int, int], Motion] = {}

        def send(a: int, b: int, rate: float) -> None:
            mine = clients.get()  # a client (connection) per request in flight
            try:
                done[(a, b)] = mine.synthesize(positions[a:b], ids[a:b], animal=animal, fps=fps,
                                               first_index=a, min_resample_rate=rate, **options)
            except ServiceError as exc:
                if not (options.get("skip_invalid") and exc.status == 422 and ALL_INVALID in exc.message):
                    raise _global_field(exc, a) from None
                # Every character of this piece was bad: skipped, as they would be in one request.
                done[(a, b)] = Motion(animal, detail["skeleton_id"], detail["fps"], 1.0, [],
                                      [{"index": i, "reason": exc.message} for i in range(b - a)])
            finally:
                clients.put(mine)
            sent.append((a, b))
            if progress:
                progress(len(sent), len(pieces) + len(slower))

        sent: list[tuple[int, int]] = []
        slower: list[tuple[int, int]] = []
        with ThreadPoolExecutor(concurrency, thread_name_prefix="request") as pool:
            list(pool.map(lambda p: send(p[0], p[1], 1.0), pieces))  # list(): the first error raises here
            rate = max(m.resample_rate for m in done.values())
            slower += [p for p, m in done.items() if m.resample_rate < rate and m.characters]
            # The formation: every piece at the fastest piece's rate.
            list(pool.map(lambda p: send(p[0], p[1], rate), slower))
        requests = len(sent)
    finally:
        for one in opened:
            one.close()

    result, made = _assembled(done, positions, rate)
    return Remote(result, skeleton_of(detail), tuple(HUBS), float(detail["fps"]), made, requests)


def _assembled(done: dict[tuple[int, int], Motion], positions: NDArray[np.floating],
               rate: float) -> tuple[Result, list[str]]:
    """The pieces' motion as one herd's :class:`Result` (indices in the whole herd), and the ids
    of the characters made."""
    kept: list[int] = []
    characters: list[CharacterMotion] = []
    rejected: dict[int, str] = {}
    warnings: dict[int, str] = {}
    for (a, b), motion in sorted(done.items()):
        skipped = {int(s["index"]): str(s["reason"]) for s in motion.skipped}
        rejected.update({a + i: why for i, why in skipped.items()})
        warnings.update({a + int(w["index"]): str(w["reason"]) for w in motion.warnings})
        kept += [a + i for i in range(b - a) if i not in skipped]
        characters += motion.characters
    lengths = {len(ch.root) for ch in characters}
    if len(lengths) != 1:
        raise ValueError(f"characters came back with different frame counts {sorted(lengths)}: "
                         "give every character the same number of points")
    T = lengths.pop()
    kept_idx = np.array(kept, np.int64)
    result = Result(
        root_pos=np.stack([ch.root for ch in characters]),
        rotations=np.stack([ch.rotations for ch in characters]),
        gait=np.stack([ch.gait for ch in characters]),
        contacts=np.stack([ch.contacts for ch in characters]),
        stitches=np.zeros((len(characters), T), bool),
        scales=np.array([ch.scale for ch in characters]),
        path=resample(np.asarray(positions[kept_idx], np.float64), T),  # the ground under each root
        resample_rate=rate, kept=kept_idx, rejected=rejected, warnings=warnings)
    return result, [ch.id for ch in characters]
