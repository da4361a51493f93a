"""Build a library (speed maps + motion graph + clips) for a built-in animal, and report on it."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np

from synth_core import UP_AXIS
from synth_core.build import ik
from synth_core.build.artifact import Library
from synth_core.build.speed_map import (
    SpeedMap,
    SpeedRange,
    build_speed_map,
    cycle_displacement,
    default_ranges,
)
from synth_core.build.straight_crossings import ease_paws
from synth_core.motion import contacts as C
from synth_core.motion.clip import Motion
from synth_core.motion.contacts import detect_contacts_at
from synth_core.motion.skeleton import forward_kinematics
from synth_core.quality import metrics as M

GAIT_ORDER = ("walk", "trot", "canter", "gallop")


def build_builtin(animal: str, ranges: dict[str, SpeedRange] | None = None) -> Library:
    """The built-in horse or dog: generated clips, then a speed map per gait."""
    from synth_core.builtin.clips import GAITS, TRANSITIONS, build_clips

    started = time.perf_counter()
    clips = build_clips(animal)
    ranges = ranges or default_ranges({g: clips[g].speed_mps() for g in GAITS})
    maps = {g: build_speed_map(clips[g], ranges[g].speeds()) for g in GAITS}
    return Library(animal, clips["walk"].skeleton, clips["walk"].fps, maps, clips["idle"],
                   {name: eased_transition(clips[name]) for name in TRANSITIONS}, frozenset(),
                   source=f"built-in {animal} (synth_core.builtin: generated from gait biomechanics)",
                   extra={"ranges": {g: [r.low, r.high, r.count] for g, r in ranges.items()},
                          "build_seconds": round(time.perf_counter() - started, 3)})


def eased_transition(motion: Motion) -> Motion:
    """A generated transition with each paw's joints below the hinge through straight no faster
    than a stride rate can play them, as the speed maps' are
    (:func:`straight_crossings.ease_paws`): played by distance at up to twice its rate (a
    character accelerating through it), the dog's toes passed through straight in one shown frame
    at its lift-offs, a limb flip. Its legs are not solved
    again, so its stances are kept whole (a passage is slowed on its swing side alone): its feet
    stand where the generator put them."""
    rotations = ease_paws(motion.skeleton, motion.rotations, ik.limb_rigs(motion.skeleton), cyclic=False,
                          contacts=motion.contacts, breakover=0.0)
    return replace(motion, rotations=rotations)


def map_positions(speed_map: SpeedMap) -> np.ndarray:
    """World joint positions (N, F, J, 3) of every clip, limbs stretched as the IK asked."""
    rigs = ik.limb_rigs(speed_map.skeleton)
    offsets = ik.stretched_offsets(speed_map.skeleton, rigs, speed_map.stretch)
    pos, _ = forward_kinematics(speed_map.skeleton, speed_map.root_pos, speed_map.rotations, offsets)
    return np.asarray(pos)


def _looped_feet(speed_map: SpeedMap) -> tuple[np.ndarray, np.ndarray]:
    """Every clip's feet (N, 3F, 4, 3) and root (N, 3F, 3) after FK, three loops back to back
    (the root carried on), so a plant or swing over a clip's seam is measured whole."""
    feet = map_positions(speed_map)[:, :, speed_map.skeleton.foot_joints]
    advance = np.stack([cycle_displacement(r) for r in speed_map.root_pos])
    looped = np.concatenate([feet + k * advance[:, None, None] for k in range(3)], axis=1)
    root = np.concatenate([speed_map.root_pos + k * advance[:, None] for k in range(3)], axis=1)
    return looped, root


def clip_glide(speed_map: SpeedMap, ground: float) -> np.ndarray:
    """Per clip (N,), the near-ground glide ratio (:func:`metrics.near_ground_glide`) of its
    feet after FK, three loops back to back (the root carried on), heights over ``ground``."""
    looped, root = _looped_feet(speed_map)
    return np.array([M.near_ground_glide(f, f[..., UP_AXIS] - ground, r).ratio
                     for f, r in zip(looped, root, strict=True)])  # per clip: a ratio of means


def clip_strict_skate(speed_map: SpeedMap, ground: float) -> np.ndarray:
    """Per clip (N,), the p95 strict plant skate (mm, :func:`metrics.strict_plants` then
    :func:`metrics.foot_skate`: feet within 1 cm of ``ground`` for 3+ frames, whatever the
    annotation says) of its feet after FK, three loops back to back."""
    looped, _ = _looped_feet(speed_map)
    return np.array([M.foot_skate(f, M.strict_plants(M.foot_heights(f, ground))).p95_mm
                     for f in looped])


def footfall_gaps(speed_map: SpeedMap, positions: np.ndarray) -> np.ndarray:
    """Per clip, the largest change (in frames) of any two feet's touchdown phase gap.

    Contacts are re-detected on each clip's motion (three loops back to back, the root carried
    on; the middle one is judged) and every pair's cyclic touchdown gap is compared with the
    source annotation's. A clip whose re-detection fails (a foot never plants) scores inf.

    A clip keeps the source's footfall when no gap moves by more than ``sync_frames``. Why gaps,
    not the sign of each pair's order: two feet half a stride apart (a walk's or a trot's left
    and right) have no order on a cycle -- one frame of detection noise turns "0.49 after" into
    "0.49 before". A gap that moves by at most the sync window keeps every order that exists
    (pairs further apart than the window cannot swap) and keeps feet that land together in the
    source landing together. The window covers re-detection noise: the real dog's contacts,
    annotated on the whole take, re-detect up to 2 frames differently on a looped clip even
    where the clip's feet are pinned exactly to the annotation.
    """
    F = speed_map.n_frames
    want = C.footfall_pattern(speed_map.contacts, cyclic=True).mean_phases
    feet = positions[:, :, speed_map.skeleton.foot_joints]
    leg = speed_map.skeleton.leg_length()
    ground = float(feet[..., 1].min())
    gap = _cyclic(want[:, None] - want[None, :])
    worst = np.empty(speed_map.n_clips)
    for c in range(speed_map.n_clips):  # per clip: contact detection is per character
        advance = cycle_displacement(speed_map.root_pos[c])
        looped_feet = np.concatenate([feet[c] + k * advance for k in range(3)])
        looped_root = np.concatenate([speed_map.root_pos[c] + k * advance for k in range(3)])
        detected = detect_contacts_at(looped_feet, looped_root, speed_map.fps, leg, ground=ground)
        detected = C.settle_plants(detected, looped_feet[..., UP_AXIS], C.SETTLE * leg)
        got = C.footfall_pattern(detected[F:2 * F], cyclic=True).mean_phases
        change = np.abs(_cyclic(_cyclic(got[:, None] - got[None, :]) - gap)) * F
        worst[c] = round(float(change.max()), 6) if np.all(np.isfinite(got)) else np.inf
    return worst


def sync_frames(n_frames: int) -> int:
    """Touchdowns this close (6% of the stride, at least 2 frames) count as simultaneous."""
    return max(2, round(0.06 * n_frames))


def _cyclic(phase: np.ndarray) -> np.ndarray:
    return (phase + 0.5) % 1.0 - 0.5


def report(library: Library) -> dict[str, Any]:
    """The figures of ``quadsynth report``: per gait, then the graph."""
    gaits: dict[str, Any] = {}
    for gait, m in library.maps.items():
        pos = map_positions(m)
        feet = pos[:, :, m.skeleton.foot_joints]
        skate = M.foot_skate(feet, np.broadcast_to(m.contacts, feet.shape[:-1]))
        gaps = footfall_gaps(m, pos)
        measured = np.array([m.clip(i).speed_mps() for i in range(m.n_clips)])
        gaits[gait] = {
            "clips": m.n_clips, "frames": m.n_frames,
            "speed_min": round(float(m.speeds[0]), 4), "speed_max": round(float(m.speeds[-1]), 4),
            "skate_mm_mean": round(skate.mean_mm, 4), "skate_mm_p95": round(skate.p95_mm, 4),
            "footfall_preserved": float(np.mean(gaps <= sync_frames(m.n_frames))),
            "footfall_gap_change_frames_max": float(gaps.max()) if np.isfinite(gaps.max()) else None,
            "max_limb_stretch_pct": round(float(m.stretch.max() - 1.0) * 100, 3),
            "speed_error_pct_max": round(float(np.abs(measured / m.speeds - 1).max() * 100), 4),
            "source_speed": round(m.source_speed, 4),
        }
    graph = library.graph
    return {"animal": library.animal, "source": library.source, "gaits": gaits,
            "graph": {"nodes": graph.nodes, "edges": graph.n_edges,
                      "transitions": sorted(graph.transitions),
                      "generated_transitions": sorted(library.generated),
                      "static_to_gallop": graph.connected("static", "gallop")
                      and graph.connected("gallop", "static")}}
