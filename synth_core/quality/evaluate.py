"""Quality figures of a synthesized crowd, all from :mod:`synth_core.quality.metrics` (``quadsynth eval``).

The standard scenario: ``crowd.simulate(500, 500, seed=0)`` trajectories (its top speed scaled
to the library's gaits, so every gait is asked for), scales random in [0.8, 1.2], seed 0, in the
paper's configuration it was first defined with (so its figures stay comparable): global
resampling where a character is too fast, s/h size matching, every character at its size's
tempo. The same herd is measured again in today's defaults (``defaults``): the caller's clock
kept, Froude size matching and each character's own tempo.

The edge suite (``--suite edge``): the scenarios of :mod:`synth_core.quality.edge`, each measured on the
output after FK from foot heights alone (:func:`edge_figures`), against issue 27's targets.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from synth_core import UP_AXIS
from synth_core.build.animals import sync_frames
from synth_core.build.motion_graph import HUBS
from synth_core.motion.contacts import touchdowns
from synth_core.motion.mirror import FOOT_SWAP
from synth_core.motion.skeleton import Skeleton, forward_kinematics
from synth_core.quality import edge, live_run
from synth_core.quality import herd_sim as crowd
from synth_core.quality import metrics as M
from synth_core.quality.reference import LibraryReference, library_reference
from synth_core.runtime.bank import STATIC, Bank
from synth_core.runtime.plan import MARGIN
from synth_core.runtime.synthesis import N_HUBS, Options, Result, headings, synthesize
from synth_core.runtime.terrain import HeightField

Floats = NDArray[np.float64]

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


G = TypeVar("G", bound=np.generic)


def own_lead(result: Result, feet: NDArray[G]) -> NDArray[G]:
    """``feet (C, T, 4)``, a figure per foot, as on the library's lead: LF and RF, LH and RH
    swapped for the characters on the other (Result.mirrored), whose canter or gallop has the
    mirrored footfall order."""
    if result.mirrored is None or not result.mirrored.any():
        return feet
    return np.asarray(np.where(result.mirrored[:, None, None], feet[..., FOOT_SWAP], feet))


def on_lead(result: Result, own: Floats, mirror: Floats) -> Floats:
    """Per character, ``own`` (a library figure, per foot last) or for those on the other lead
    (Result.mirrored) ``mirror``, the mirror rows' own: ``(C, ...)``."""
    if result.mirrored is None:
        return np.broadcast_to(own, (len(result.scales), *own.shape))
    lead = result.mirrored.reshape(-1, *([1] * own.ndim))
    return np.asarray(np.where(lead, mirror[None], own[None]))


def footfall_preserved(bank: Bank, result: Result, contacts: NDArray[np.bool_] | None = None,
                       clip_contacts: NDArray[np.bool_] | None = None) -> tuple[float, float]:
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
    judged by the order of its touchdown groups alone, as the template's (as is every stride of
    a gait whose clip has a foot landing other than once a stride).

    ``contacts (C, T, 4)``: the feet planted in the output (default: the plan's, ``result``'s);
    ``clip_contacts (K, 4)``: the same kind of contacts of the library's pose rows (default:
    its annotation), to take the templates from."""
    planted = own_lead(result, result.contacts if contacts is None else contacts)  # either lead's order
    clip_contacts = bank.contacts if clip_contacts is None else clip_contacts
    counts = np.zeros((2, 2), np.int64)  # (within one piece, across a piece start) x (total, matched)
    for hub, piece in bank.gaits.items():
        rows = slice(piece.offset, piece.offset + piece.frames)
        sync = sync_frames(piece.frames)
        template = [frozenset(g) for g in M.footfall_template(clip_contacts[rows], sync)]
        try:
            phases: dict[str, float] | None = M.footfall_phases(clip_contacts[rows])
        except ValueError:
            phases = None
        for c in range(len(result.gait)):  # per character: strides are ragged; not a hot path
            down = touchdowns(planted[c])
            groups = M.touchdown_groups(planted[c], sync)
            starts = [i for i, (_, g) in enumerate(groups) if "LH" in g]
            for a, b in zip(starts[:-1], starts[1:], strict=False):
                t0, t1 = groups[a][0], groups[b][0]
                if not np.all(result.gait[c, t0:t1 + 1] == hub):
                    continue
                across = bool(result.stitches[c, t0 + 1:t1].any())  # a piece starting at t1 starts the next
                if across or phases is None:
                    matched = [g for _, g in groups[a:b]] == template
                else:
                    matched = M.stride_in_order(down, t0, t1, phases, sync + 1.0)
                counts[int(across)] += (1, int(matched))
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


# --- The edge suite (issue 27): scenarios of synth_core.quality.edge, figures after FK -----------------

# A rig's foot joint may sit above the sole: the real dog's paw end sites are 2-2.5 cm (fore) and
# 0.5-1 cm (hind) up while planted. Plants, support and floating are measured from each foot's
# own standing height, the low tenth of its heights while annotated planted in the library clips
# (the paw rolls in stance; its median is 1 cm higher behind). The glide is measured from the
# ground itself, as the published figure and the real dog's 0.066-0.106 are.
SLOW_BODY = 0.1  # m/s: "floating" is the lowest foot's height while the body is slower than this
BODY_SPEED_WINDOW_S = 0.25  # the body's speed, averaged over this (a stride's surge is no speed)

# figure -> (comparison, limit): the targets, for every scenario and animal.
EDGE_TARGETS: dict[str, tuple[str, float]] = {
    "glide_ratio": ("<=", 0.10),
    "strict_skate_mm_p95": ("<=", 3.0),
    "jump_cm_max": ("<=", 6.0),
    "limb_flips": ("<=", 0),
    "walk_support_share": (">=", 1.0),
    "single_support_ratio_max": ("<=", 1.0),
    "stretch_pct_max": ("<=", 3.0),
    "floating_cm_max": ("<=", 1.0),
    # "never a root that slides over pinned feet": over four feet down while the body is slow,
    # the root moves over them no more than a standing animal shifts its weight (a few cm)
    "stand_drift_cm_max": ("<=", 5.0),
    "path_cm_max": ("<=", 1.0),
    "clock_kept": ("==", 1),
}
# ... and issue 33's, for the scenarios on a terrain (the flat ones report the figures too).
TERRAIN_TARGETS: dict[str, tuple[str, float]] = {
    "planted_ground_mm_p95": ("<=", 5.0),
    "penetration_mm": ("<=", 5.0),
    "pitch_error_deg_max": ("<=", 5.0),
}
PITCH_WINDOW_S = 1.0  # the body's pitch is judged on its mean over about a stride
HIGHER_IS_BETTER = {"walk_support_share", "still_four_down_share", "footfall_preserved",
                    "footfall_across_transitions", "clock_kept"}


def _round(x: float, digits: int = 4) -> float | None:
    return None if not np.isfinite(x) else round(float(x), digits)


@dataclass(frozen=True, eq=False)
class Feet:
    """A result's joints and feet after FK, as the edge figures read them."""

    positions: Floats  # (C, T, J, 3) world
    feet: Floats  # (C, T, 4, 3) world
    above_ground: Floats  # (C, T, 4) height over the ground (the path's height)
    heights: Floats  # (C, T, 4) height over the foot's standing height (LibraryReference.soles)
    down: NDArray[np.bool_]  # (C, T, 4) strict plants of ``heights``


def feet_after_fk(bank: Bank, result: Result, ref: LibraryReference,
                  ground: HeightField | None = None) -> Feet:
    """``ground``: heights are over the terrain under each foot (else the path's height)."""
    pos = np.asarray(world_positions(bank, result), np.float64)
    feet = pos[..., bank.skeleton.foot_joints, :]
    if ground is None:
        above_ground = np.asarray(M.foot_heights(feet, result.path[..., UP_AXIS]), np.float64)
    else:
        above_ground = feet[..., UP_AXIS] - ground.sample(feet[..., 0], feet[..., 2])
    soles = on_lead(result, ref.soles, ref.mirror_soles) * result.scales[:, None, None]  # (C, hubs, 4)
    heights = M.over_standing(above_ground, soles, result.gait, result.stitches, MARGIN).astype(np.float64)
    return Feet(pos, feet, above_ground, heights, M.strict_plants(heights, open_ends=True))


def rest_pitch(bank: Bank) -> float:
    """The library's median body pitch (degrees, hips to shoulders) on flat ground."""
    sk = bank.skeleton
    pos = np.asarray(forward_kinematics(sk, np.zeros((bank.own, 3)), bank.poses[:bank.own])[0], np.float64)
    return float(np.median(body_pitch(pos, sk)))


def body_pitch(positions: Floats, skeleton: Skeleton) -> Floats:
    """``(...)`` degrees: the line from the hips' midpoint to the shoulders' over the horizontal."""
    top = np.array([f.chain[0] for f in skeleton.feet])
    d = positions[..., top[:2], :].mean(axis=-2) - positions[..., top[2:], :].mean(axis=-2)
    return np.asarray(np.degrees(np.arctan2(d[..., UP_AXIS], np.linalg.norm(d[..., [0, 2]], axis=-1))))


def ground_figures(bank: Bank, result: Result, fk: Feet, ground: HeightField | None,
                   ref: LibraryReference) -> dict[str, Any]:
    """Issue 33's figures: how far annotated planted feet stand from the ground (over their
    standing height, mm), and the body's pitch against the ground's slope between the front and
    hind feet (a stride's mean, over the library's own pitch on flat ground, degrees)."""
    planted = np.abs(fk.heights[result.contacts]) * 1000.0
    front, hind = fk.feet[..., :2, :].mean(axis=-2), fk.feet[..., 2:, :].mean(axis=-2)
    if ground is None:
        rise = np.zeros(front.shape[:-1])
    else:
        rise = ground.sample(front[..., 0], front[..., 2]) - ground.sample(hind[..., 0], hind[..., 2])
    run_ = np.linalg.norm((front - hind)[..., [0, 2]], axis=-1)
    slope = np.degrees(np.arctan2(rise, np.maximum(run_, 1e-6)))
    stride = max(3, int(PITCH_WINDOW_S * bank.fps))
    off = ndimage.uniform_filter1d(body_pitch(fk.positions, bank.skeleton) - slope, stride, axis=1)
    error = np.abs(off - rest_pitch(bank))
    return {
        "planted_ground_mm_p95": _round(float(np.percentile(planted, 95)) if planted.size else 0.0, 2),
        "planted_ground_mm_max": _round(float(planted.max()) if planted.size else 0.0, 2),
        "pitch_error_deg_max": _round(float(error.max()), 2),
    }


def _body_speed(root: NDArray[np.float64], fps: float) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The body's ground speed (C, F) m/s, smoothed, and where it stands still."""
    speed = np.linalg.norm(np.gradient(root[..., [0, 2]], axis=1), axis=-1) * fps
    speed = ndimage.uniform_filter1d(speed, size=max(3, int(BODY_SPEED_WINDOW_S * fps)), axis=1)
    # Standing still: slow for a whole second around the frame (a stop, not a stride's low point).
    still = ndimage.uniform_filter1d(speed, size=int(fps), axis=1) < SLOW_BODY
    return speed, still


def stance_frames(ref: LibraryReference, result: Result) -> Floats:
    """``(C, T)``: each frame's gait's longest stance (frames) for its character. The suite plays
    every size at its Froude tempo (synthesis' default: stride frequency ~ 1 / sqrt(h)), so a
    character h times the library's size stands sqrt(h) times as many frames on each step: held
    to the library's frames, a scale-2 dog's own steady canter read 1.1 and a small one's lone
    stances were let run 1.4 times the length its tempo gives."""
    return np.asarray(ref.stance[result.gait] * np.sqrt(result.scales)[:, None])


def edge_figures(bank: Bank, result: Result, reference_path: NDArray[np.floating], frames_in: int,
                 ref: LibraryReference, ground: HeightField | None = None,
                 sent: NDArray[np.floating] | None = None) -> dict[str, Any]:
    """Every edge figure of one synthesized scenario, from world positions after FK.

    ``reference_path (C, F, 3)``: the path the characters were meant to follow, ``frames_in``
    its frame count (the output's time is mapped onto it); ``ground``: the terrain walked on;
    ``sent (C, F, 3)``: the positions the simulator sent, where they are not the path meant (a
    jittery simulator's): ``path_sent_cm_max`` is the root's distance from them."""
    sk, fps = bank.skeleton, bank.fps
    fk = feet_after_fk(bank, result, ref, ground)
    pos, feet, above_ground, heights, down = fk.positions, fk.feet, fk.above_ground, fk.heights, fk.down
    glide = M.near_ground_glide(feet, above_ground, result.root_pos)
    skate = M.foot_skate(feet, down)
    touch = M.touchdown_steps_mm(feet, down)
    jumps = M.one_frame_jumps_mm(feet)
    steps = np.linalg.norm(np.diff(feet, axis=-3), axis=-1) * 1000.0
    flips = M.limb_flips(pos, sk, result.rotations[:, :, 0])
    hinges = M.hinge_joints(sk)
    walk = result.gait == HUBS.index("walk")
    feet_down = down.sum(axis=-1)
    alone = M.single_support_frames(down)
    reach = on_lead(result, ref.reach, ref.mirror_reach)  # (C, 4)
    stretch = (M.limb_reach(pos, sk) / (reach[:, None] * result.scales[:, None, None])).max()
    root = result.root_pos.astype(np.float64)
    speed, still = _body_speed(root, fps)
    nan = float("nan")
    yaw = M.yaw_rates_deg(result.rotations[:, :, 0], fps)
    footfall = footfall_preserved(bank, result, down, ref.clip_plants)
    return {
        "glide_ratio": _round(glide.ratio),
        "glide_mm": _round(glide.foot_mm, 3),
        "strict_skate_mm_mean": _round(skate.mean_mm, 3),
        "strict_skate_mm_p95": _round(skate.p95_mm, 3),
        "touchdown_mm_max": _round(float(touch.max()) if touch.size else 0.0, 2),
        "touchdown_mm_p95": _round(float(np.percentile(touch, 95)) if touch.size else 0.0, 2),
        "jump_cm_max": _round(float(jumps.max()) / 10 if jumps.size else 0.0, 2),
        "foot_step_mm_max": _round(float(steps.max()) if steps.size else 0.0, 1),
        "limb_flips": int(flips.sum()),
        "limb_flips_at": {sk.names[hinges[i, 1]]: int(flips[i]) for i in np.flatnonzero(flips)},
        "walk_support_share": _round(float(np.mean(feet_down[walk] >= 2)) if walk.any() else float("nan")),
        "single_support_ratio_max": _round(float((alone / stance_frames(ref, result)).max()), 3),
        "stretch_pct_max": _round(max(0.0, float(stretch) - 1.0) * 100, 2),
        "hanging_s_max": _round(M.longest_hang(pos, sk, above_ground, result.scales) / fps, 3),
        "floating_cm_max": _round(max(0.0, M.floating_m(heights, speed, SLOW_BODY)) * 100, 2),
        "still_four_down_share": _round(float(np.mean(feet_down[still] == 4)) if still.any() else nan),
        "still_highest_foot_cm": _round(float(heights.max(axis=-1)[still].max(initial=0.0)) * 100, 2),
        "stand_drift_cm_max": _round(float((M.stand_drift_m(root, feet, down, speed < SLOW_BODY)
                                            / result.scales[:, None]).max(initial=0.0)) * 100, 2),
        "penetration_mm": _round(max(0.0, -float(above_ground.min())) * 1000, 2),
        "yaw_deg_s_max": _round(float(yaw.max()) if yaw.size else 0.0, 1),
        "yaw_deg_s_p95": _round(float(np.percentile(yaw, 95)) if yaw.size else 0.0, 1),
        "footfall_preserved": _share(footfall[0]),
        "footfall_across_transitions": _share(footfall[1]),
        "clock_kept": int(result.root_pos.shape[1] == frames_in),
        "resample_rate": round(result.resample_rate, 4),
        "gait_frames": {name: int(n) for name, n in
                        zip(HUBS, np.bincount(result.gait.ravel(), minlength=N_HUBS), strict=False)},
        "nan_count": int(np.isnan(result.rotations).sum() + np.isnan(result.root_pos).sum()),
    } | path_figures(result, reference_path, sent) | ground_figures(bank, result, fk, ground, ref)


def path_figures(result: Result, reference_path: NDArray[np.floating],
                 sent: NDArray[np.floating] | None = None) -> dict[str, Any]:
    """The root's ground point from the path meant (``path_cm_*``) and from the positions sent
    (``path_sent_cm_max``; ``sent`` None: the path meant), :func:`metrics.path_distance_cm`."""
    root = result.root_pos.astype(np.float64)
    path = M.path_distance_cm(root, np.asarray(reference_path)[result.kept])
    from_sent = path if sent is None else M.path_distance_cm(root, np.asarray(sent, np.float64)[result.kept])
    return {"path_cm_max": _round(float(path.max()), 3), "path_cm_mean": _round(float(path.mean()), 3),
            "path_sent_cm_max": _round(float(from_sent.max()), 3)}


def passes(figure: str, value: float | None) -> bool | None:
    """Whether ``value`` meets the issue's target for ``figure`` (None: no target, or no value)."""
    targets = EDGE_TARGETS | TERRAIN_TARGETS
    if figure not in targets or value is None:
        return None
    op, limit = targets[figure]
    return bool(value <= limit if op == "<=" else value >= limit if op == ">=" else value == limit)


def worst(scenarios: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per numeric figure, the worst value over scenarios, which scenario, the target and pass."""
    out: dict[str, dict[str, Any]] = {}
    names = [n for n, s in scenarios.items() if "error" not in s]
    for figure, first in (scenarios[names[0]]["figures"].items() if names else ()):
        if not isinstance(first, int | float) or figure in ("nan_count", "resample_rate"):
            continue
        values = [(scenarios[n]["figures"][figure], n) for n in names
                  if scenarios[n]["figures"][figure] is not None]
        if not values:
            continue
        value, name = (min if figure in HIGHER_IS_BETTER else max)(values)
        out[figure] = {"value": value, "scenario": name}
        if figure in EDGE_TARGETS:
            op, limit = EDGE_TARGETS[figure]
            out[figure] |= {"target": f"{op} {limit:g}", "pass": passes(figure, value)}
    return out


def edge_suite(bank: Bank, seed: int = 0, names: list[str] | None = None, backend: str = "auto",
               keep: dict[str, tuple[edge.Scenario, Result]] | None = None, live: bool = False,
               latency_ms: float | None = None, velocity: bool = False) -> dict[str, Any]:
    """Every edge scenario synthesized for this library and measured (:func:`edge_figures`),
    each figure judged against the issue's targets, and the worst over scenarios. ``keep``:
    filled with each scenario and its result (for previews). ``live``: each scenario played
    through a live session fed a point a tick (:mod:`synth_core.quality.live_run`), in the
    low-latency mode with ``latency_ms`` (None: the exact mode); each scenario's report then has
    the frames its sent poses lagged its points (``lag_frames_max``); ``velocity``: each point
    sent with its velocity (:meth:`edge.Scenario.velocity`)."""
    ref = library_reference(bank)
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    scenarios: dict[str, dict[str, Any]] = {}
    for sc in edge.scenarios(gaits, bank.fps, seed, names):
        entry: dict[str, Any] = {"about": sc.about, "characters": int(sc.positions.shape[0]),
                                 "frames": int(sc.positions.shape[1])}
        try:
            if live:
                sends = sc.velocity(bank.fps) if velocity else None
                run = live_run.play(bank, sc.positions, sc.scales, seed, latency_ms, sc.ground,
                                    backend=backend, velocity=sends)
                result = run.result
                entry |= {"lag_frames_max": int(run.lags.max()), "latency_frames": run.latency_frames}
            else:
                result = synthesize(bank, sc.positions, bank.fps, scales=sc.scales,
                                    options=Options(seed=seed, backend=backend, ground=sc.ground))
        except ValueError as exc:  # a refusal is a figure too: the scenario could not be played
            scenarios[sc.name] = entry | {"error": str(exc), "failed": ["error"]}
            continue
        figures = edge_figures(bank, result, sc.reference, sc.positions.shape[1], ref, sc.ground,
                               sent=sc.positions)
        targets = EDGE_TARGETS | (TERRAIN_TARGETS if sc.ground is not None else {})
        failed = [f for f in targets if passes(f, figures.get(f)) is False]
        # By how much, in the figure's unit (a share: how much of it is missing).
        beyond = {f: round(abs(float(figures[f]) - targets[f][1]), 4) for f in failed}
        verdicts = {f: passes(f, figures.get(f)) for f in targets}  # None: no such frames
        scenarios[sc.name] = entry | {"figures": figures, "pass": verdicts, "failed": failed,
                                      "beyond_target": beyond}
        if keep is not None:
            keep[sc.name] = (sc, result)
    return {
        "seed": seed,
        "mode": ("low_latency" if latency_ms is not None else "exact") if live else "batch",
        **({"latency_ms": latency_ms, "velocity_sent": velocity} if live and latency_ms is not None else {}),
        "targets": {f: f"{op} {limit:g}" for f, (op, limit) in EDGE_TARGETS.items()},
        "scenarios_passed": sum(not s["failed"] for s in scenarios.values()),
        "scenarios": scenarios,
        "worst": worst(scenarios),
        "library": {"soles_cm": {HUBS[k]: [round(float(x) * 100, 2) for x in ref.soles[k]]
                                 for k in range(N_HUBS) if k == STATIC or k in bank.speeds},
                    "reach_m": [round(float(x), 3) for x in ref.reach],
                    "longest_stance_frames": {HUBS[k]: int(ref.stance[k]) for k in range(N_HUBS)
                                              if k == STATIC or k in bank.speeds}},
    }


def severity(entry: dict[str, Any]) -> tuple[float, int]:
    """How badly a scenario fails: its misses summed, each in units of its target (a 30 cm jump
    against 6 cm is 4; a limb flip against none is 1 per flip), then how many targets it misses.
    A refused scenario is the worst."""
    targets = EDGE_TARGETS | TERRAIN_TARGETS  # a terrain scenario misses terrain targets too
    if "error" in entry:
        return (float("inf"), len(targets) + 1)
    excess = sum(value / (abs(targets[f][1]) or 1.0) for f, value in entry["beyond_target"].items())
    return (excess, len(entry["failed"]))


def worst_scenario(suite: dict[str, Any]) -> str:
    """The scenario of a suite's result that misses its targets by the most (:func:`severity`)."""
    return str(max(suite["scenarios"], key=lambda name: severity(suite["scenarios"][name])))
