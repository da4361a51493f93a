"""Quality figures of a synthesized crowd, all from :mod:`synth_core.metrics` (``quadsynth eval``).

The standard scenario: ``crowd.simulate(500, 500, seed=0)`` trajectories (its top speed scaled
to the library's gaits, so every gait is asked for), scales random in [0.8, 1.2], seed 0, in the
paper's configuration it was first defined with (so its figures stay comparable): global
resampling where a character is too fast, s/h size matching, every character at its size's
tempo. The same herd is measured again in today's defaults (``defaults``): the caller's clock
kept, Froude size matching and each character's own tempo.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from synth_core import UP_AXIS, crowd
from synth_core import metrics as M
from synth_core.bank import Bank
from synth_core.build import sync_frames
from synth_core.contacts import touchdowns
from synth_core.skeleton import forward_kinematics
from synth_core.synthesis import Options, Result, headings, synthesize

STANDARD = {"characters": 500, "frames": 500, "seed": 0, "scale_range": (0.8, 1.2)}
STITCH_WINDOW = 2  # frames either side of a stitch where pops are looked for


def crowd_top_speed(bank: Bank) -> float:
    """A crowd-sim top speed that asks the library for its gallop at every scale in [0.8, 1.2]:
    1.25 x the slowest gallop clip (with the built-in horse, 5.9 m/s; crowd-sim's default is 7)."""
    return float(min(7.0, 1.25 * 1.2 * bank.speeds[max(bank.speeds)][0]))


def world_positions(bank: Bank, result: Result) -> NDArray[np.float32]:
    """FK of every joint, ``(C, T, J, 3)`` metres, each character at its scale."""
    offsets = bank.skeleton.offsets[None, None] * result.scales[:, None, None, None].astype(np.float32)
    pos, _ = forward_kinematics(bank.skeleton, result.root_pos, result.rotations, offsets)
    return np.asarray(pos, np.float32)


def footfall_preserved(bank: Bank, result: Result) -> tuple[float, float]:
    """Share of strides (LH touchdown to LH touchdown) played in one gait whose touchdown order
    is that gait's, taken from the library's own clips: of the strides played wholly in one
    piece, and of those with a piece starting inside (NaN where there are none).

    The second kind is apart because a transition's frames are labelled with the gait it leaves
    over its first half and the one it reaches over its second: a stride spanning its end (or
    start) is labelled one gait but steps partly in the transition, whose footfalls go from one
    gait's order to the other's (tests/test_library_clips.py). Counted as the gait's, these made
    long crowd-sim herds (horse, 200 x 2,000 frames) read 0.965 where every stride wholly in a
    trot was right: all 200 misses were such strides.

    A stride wholly in one piece is judged in phase (:func:`metrics.stride_in_order`): every foot
    lands once, within the gait's simultaneity window (:func:`build.sync_frames`) and a frame of
    where the clip's phase puts it -- whatever the character's tempo. One with a piece starting
    inside steps partly in a transition, whose touchdowns move between two gaits' phases: it is
    judged by the order of its touchdown groups alone, as the template's."""
    counts = np.zeros((2, 2), np.int64)  # (within one piece, across a piece start) x (total, matched)
    for hub, piece in bank.gaits.items():
        rows = slice(piece.offset, piece.offset + piece.frames)
        sync = sync_frames(piece.frames)
        template = [frozenset(g) for g in M.footfall_template(bank.contacts[rows], sync)]
        phases = M.footfall_phases(bank.contacts[rows])
        for c in range(len(result.gait)):  # per character: strides are ragged; not a hot path
            down = touchdowns(result.contacts[c])
            groups = M.touchdown_groups(result.contacts[c], sync)
            starts = [i for i, (_, g) in enumerate(groups) if "LH" in g]
            for a, b in zip(starts[:-1], starts[1:], strict=False):
                t0, t1 = groups[a][0], groups[b][0]
                if not np.all(result.gait[c, t0:t1 + 1] == hub):
                    continue
                if result.stitches[c, t0 + 1:t1].any():  # a piece starting at t1 starts the next
                    counts[1] += (1, int([g for _, g in groups[a:b]] == template))
                else:
                    counts[0] += (1, int(M.stride_in_order(down, t0, t1, phases, sync + 1.0)))
    within, spanning = (m / n if n else float("nan") for n, m in counts)
    return within, spanning


def near_stitches(stitches: NDArray[np.bool_], window: int) -> NDArray[np.bool_]:
    """``(C, F)``: frames within ``window`` frames of a stitch of the same character (a stitch
    near one end marks nothing near the other)."""
    F = stitches.shape[1]
    padded = np.pad(stitches, ((0, 0), (window, window)))
    near = np.zeros_like(stitches)
    for d in range(2 * window + 1):
        near |= padded[:, d:d + F]
    return near


def pop_ratio(bank: Bank, result: Result) -> float:
    """Largest joint angular acceleration near stitches over the largest within the library's clips."""
    if not result.stitches.any():
        return 0.0
    acc = M.angular_acceleration(result.rotations[:, :, 1:], bank.fps)  # the root turns with the path
    near = near_stitches(result.stitches, STITCH_WINDOW)[:, 1:-1]  # acc frame f is centred on f + 1
    clips = [bank.poses[p.offset + i * p.frames:p.offset + (i + 1) * p.frames, 1:]
             for p in bank.gaits.values() for i in range(p.clips)]
    reference = max(float(M.angular_acceleration(np.concatenate([c, c[:2]]), bank.fps).max())
                    for c in clips)
    return float(acc[near].max()) / max(reference, 1e-9)


def _share(x: float) -> float | None:
    return None if np.isnan(x) else round(float(x), 4)  # None: no such stride (JSON has no NaN)


def figures(bank: Bank, result: Result) -> dict[str, Any]:
    pos = world_positions(bank, result)
    feet = pos[..., bank.skeleton.foot_joints, :]
    ground = result.path[..., UP_AXIS]
    offset = (result.root_pos - result.path)[..., [0, 2]]
    yaw = headings(result.path, bank.fps)
    left = np.stack([np.cos(yaw), -np.sin(yaw)], axis=-1)  # the path's sideways direction
    sideways = np.abs(np.sum(offset * left, axis=-1)) * 100
    skate = M.foot_skate(feet, result.contacts)
    lowest = float((feet[..., UP_AXIS] - ground[..., None]).min())
    gait = np.bincount(result.gait.ravel(), minlength=len(bank.hubs))
    footfall = footfall_preserved(bank, result)
    return {
        "path_error_cm_max": round(float(sideways.max()), 4),
        "path_error_cm_mean": round(float(sideways.mean()), 4),
        "timing_error_cm_max": round(float(np.linalg.norm(offset, axis=-1).max() * 100), 3),
        "skate_mm_mean": round(skate.mean_mm, 4),
        "skate_mm_p95": round(skate.p95_mm, 4),
        "skating_ratio": round(skate.ratio, 5),
        "footfall_preserved": _share(footfall[0]),
        "footfall_across_transitions": _share(footfall[1]),
        "pop_ratio": round(pop_ratio(bank, result), 3),
        "penetration_mm": round(max(0.0, -lowest * 1000), 3),
        "gait_frames": {name: int(n) for name, n in zip(bank.hubs, gait, strict=False)},
        "nan_count": int(np.isnan(result.rotations).sum() + np.isnan(result.root_pos).sum()),
        "resample_rate": round(result.resample_rate, 4),
    }


PAPER = {"resample": True, "size_matching": "geometric", "tempo_spread": 0.0}


def standard(bank: Bank, characters: int = 500, frames: int = 500, seed: int = 0,
             backend: str = "auto") -> dict[str, Any]:
    """The standard scenario's figures (see the module doc), and under ``defaults`` the same
    herd's in today's default options."""
    paths = crowd.simulate(characters, frames, seed=seed, top=crowd_top_speed(bank))
    scale_range: tuple[float, float] = STANDARD["scale_range"]  # type: ignore[assignment]
    paper = synthesize(bank, paths, options=Options(scale_range=scale_range, seed=seed, backend=backend,
                                                    **PAPER))  # type: ignore[arg-type]
    today = synthesize(bank, paths, options=Options(scale_range=scale_range, seed=seed, backend=backend))
    return {"characters": characters, "frames": frames, "seed": seed, **figures(bank, paper),
            "defaults": figures(bank, today)}
