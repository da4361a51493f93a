"""Motion quality metrics, on FK world positions, vectorized over any leading (character) axes.

Every claim about motion quality in QuadSynth is a number from here (see ENGINEERING.md,
"Measuring motion quality"). Inputs are metres; results carry their unit in the name.

- foot skate: horizontal travel of a planted foot between consecutive frames where it is
  planted at both (mm/frame), mean, p95, and the share of such steps over 2 mm;
- path error: horizontal distance of the root from the target trajectory at the same frame (cm);
- footfall order: the share of strides whose touchdown order matches a gait template;
- pops: the largest joint angular acceleration at given frames over the largest in a reference;
- penetration: the lowest foot below the ground (mm);
- bone-length change: how far world positions stretch the skeleton's bones (mm and %).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from synth_core import FOOT_NAMES, UP_AXIS
from synth_core.build.ik import limb_rigs
from synth_core.motion import quat
from synth_core.motion.contacts import drop_short_runs, touchdowns
from synth_core.motion.skeleton import Skeleton

SKATE_THRESHOLD_MM = 2.0

Floats = NDArray[np.floating]


def _horizontal(x: Floats) -> Floats:
    return np.delete(np.asarray(x, dtype=np.float64), UP_AXIS, axis=-1)


@dataclass(frozen=True)
class SkateStats:
    mean_mm: float
    p95_mm: float
    ratio: float  # share of planted steps moving more than SKATE_THRESHOLD_MM
    steps: int  # planted steps measured

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def planted_steps_mm(foot_pos: Floats, contacts: NDArray[np.bool_]) -> Floats:
    """Horizontal step lengths (mm) of feet planted at both ends of the step, flattened.

    ``foot_pos (..., F, 4, 3)``, ``contacts (..., F, 4)``.
    """
    foot_pos, contacts = np.asarray(foot_pos), np.asarray(contacts, bool)
    if foot_pos.shape[:-1] != contacts.shape or foot_pos.shape[-1] != 3:
        raise ValueError(f"Expected `foot_pos` (..., F, 4, 3) matching `contacts` (..., F, 4), "
                         f"got {foot_pos.shape} and {contacts.shape}")
    step = np.linalg.norm(np.diff(_horizontal(foot_pos), axis=-3), axis=-1) * 1000.0
    both = contacts[..., 1:, :] & contacts[..., :-1, :]
    return np.asarray(step[both])


def foot_skate(foot_pos: Floats, contacts: NDArray[np.bool_]) -> SkateStats:
    """Skate of planted feet over all characters, frames and feet."""
    steps = planted_steps_mm(foot_pos, contacts)
    if steps.size == 0:
        return SkateStats(0.0, 0.0, 0.0, 0)
    return SkateStats(float(steps.mean()), float(np.percentile(steps, 95)),
                      float(np.mean(steps > SKATE_THRESHOLD_MM)), int(steps.size))


@dataclass(frozen=True)
class PathError:
    max_cm: float
    mean_cm: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def path_error(root_pos: Floats, target: Floats) -> PathError:
    """Horizontal distance between root and target at the same frame; ``(..., F, 3)`` each."""
    root_pos, target = np.asarray(root_pos), np.asarray(target)
    if root_pos.shape != target.shape or root_pos.shape[-1] != 3:
        raise ValueError(f"Expected `root_pos` and `target` of equal shape (..., F, 3), "
                         f"got {root_pos.shape} and {target.shape}")
    dist = np.linalg.norm(_horizontal(root_pos) - _horizontal(target), axis=-1) * 100.0
    return PathError(float(dist.max()), float(dist.mean()))


def touchdown_groups(contacts: NDArray[np.bool_], sync_frames: int) -> list[tuple[int, frozenset[str]]]:
    """Touchdowns of one character, time-ordered, grouped when within ``sync_frames`` of the first."""
    events = sorted((int(f), FOOT_NAMES[k]) for k, frames in enumerate(touchdowns(contacts))
                    for f in frames)
    groups: list[tuple[int, frozenset[str]]] = []
    for frame, foot in events:
        if groups and frame - groups[-1][0] <= sync_frames and foot not in groups[-1][1]:
            groups[-1] = (groups[-1][0], groups[-1][1] | {foot})
        else:
            groups.append((frame, frozenset({foot})))
    return groups


def footfall_phases(contacts: NDArray[np.bool_]) -> dict[str, float]:
    """Each foot's touchdown in one stride of a cyclic clip ``contacts (F, 4)``, as a share of the
    stride after LH's (LH: 0). Raises when a foot does not touch down exactly once a stride."""
    contacts = np.asarray(contacts, bool)
    F = len(contacts)
    down = {FOOT_NAMES[k]: frames.tolist() for k, frames in enumerate(touchdowns(contacts, cyclic=True))}
    if any(len(f) != 1 for f in down.values()):
        raise ValueError(f"contacts: each foot must touch down once a stride, got {down}")
    lh = down["LH"][0]
    return {foot: ((f[0] - lh) % F) / F for foot, f in down.items()}


def stride_in_order(down: Sequence[NDArray[np.int64]], t0: int, t1: int, phases: dict[str, float],
                    tolerance: float) -> bool:
    """Whether the stride from LH's touchdown at ``t0`` to its next at ``t1`` steps as ``phases``
    (:func:`footfall_phases`): each foot touches down once in the stride-long window centred where
    its phase puts it, within ``tolerance`` frames of there. ``down``: each foot's touchdown
    frames (:func:`touchdowns`), feet in FOOT_NAMES order.

    In phase, not in frames or touchdown groups: a character stepping a few per cent faster or
    slower than the clip (its size's tempo, a sprint) shifts each touchdown by a fraction of a
    frame, which moves a pair a frame apart in or out of a fixed frame window, while its order
    and timing within the stride stay the clip's."""
    length = t1 - t0
    for k, foot in enumerate(FOOT_NAMES):
        if foot == "LH":
            continue
        expected = t0 + phases[foot] * length
        frames = down[k][(down[k] >= expected - 0.5 * length) & (down[k] < expected + 0.5 * length)]
        if len(frames) != 1 or abs(frames[0] - expected) > tolerance:
            return False
    return True


def footfall_template(contacts: NDArray[np.bool_], sync_frames: int) -> list[list[str]]:
    """The touchdown groups of one stride of a cyclic clip, starting with LH's group.

    A template for :func:`footfall_order`, taken from a clip's own contacts (a user's mocap has
    no built-in template). Raises when the clip has no complete stride.
    """
    looped = np.tile(np.asarray(contacts, bool), (3, 1))
    groups = [sorted(g) for _, g in touchdown_groups(looped, sync_frames)]
    starts = [i for i, g in enumerate(groups) if "LH" in g]
    if len(starts) < 2:
        raise ValueError("contacts: no complete stride (LH must touch down)")
    return groups[starts[0]:starts[1]]


def footfall_order(contacts: NDArray[np.bool_], template: Sequence[Sequence[str]],
                   sync_frames: int = 3) -> float:
    """Share of strides whose touchdown order matches ``template``.

    ``template`` is the cyclic order of touchdown groups starting with the group holding LH,
    e.g. walk ``[["LH"], ["LF"], ["RH"], ["RF"]]``, trot ``[["LH", "RF"], ["RH", "LF"]]``.
    A stride is the touchdown groups from one LH group up to the next; touchdowns within
    ``sync_frames`` frames count as simultaneous. ``contacts (..., F, 4)``; strides of all
    characters are pooled. Returns NaN when there is no complete stride.
    """
    want = [frozenset(g) for g in template]
    if not any("LH" in g for g in want[:1]):
        raise ValueError("template: the first group must contain LH")
    contacts = np.asarray(contacts, bool)
    flat = contacts.reshape(-1, *contacts.shape[-2:])
    matched = total = 0
    for character in flat:  # per character: event lists are ragged; not a hot path
        groups = [g for _, g in touchdown_groups(character, sync_frames)]
        starts = [i for i, g in enumerate(groups) if "LH" in g]
        for a, b in zip(starts[:-1], starts[1:], strict=False):
            total += 1
            matched += groups[a:b] == want
    return matched / total if total else float("nan")


def angular_acceleration(rotations: Floats, fps: float) -> Floats:
    """Magnitude of each joint's angular acceleration (rad/s^2), ``(..., F-2, J)``.

    Frame f of the result is centred on input frame f + 1.
    """
    q = quat.make_continuous(np.asarray(rotations, dtype=np.float64), axis=-3)
    omega = quat.to_rotvec(quat.mul(quat.inv(q[..., :-1, :, :]), q[..., 1:, :, :])) * fps
    return np.asarray(np.linalg.norm(np.diff(omega, axis=-3), axis=-1) * fps)


def pop_ratio(rotations: Floats, at_frames: Sequence[int] | NDArray[np.integer],
              reference: Floats, fps: float) -> float:
    """Max angular acceleration at ``at_frames`` (e.g. stitch frames) / max within ``reference``.

    ``rotations (..., F, J, 4)`` local rotations of the synthesized motion; ``reference``
    rotations of the source clips, any leading shape. A ratio near 1 means no pop.
    """
    acc = angular_acceleration(rotations, fps)
    frames = np.asarray(at_frames, dtype=np.int64) - 1  # acc frame f is centred on f + 1
    frames = frames[(frames >= 0) & (frames < acc.shape[-2])]
    if frames.size == 0:
        return 0.0
    ref = float(angular_acceleration(reference, fps).max())
    return float(acc[..., frames, :].max()) / max(ref, 1e-9)


def penetration_mm(foot_pos: Floats, ground: float = 0.0) -> float:
    """How far the lowest foot goes below the ground (mm, 0 when never below)."""
    lowest = float(np.asarray(foot_pos)[..., UP_AXIS].min())
    return max(0.0, (ground - lowest) * 1000.0)


@dataclass(frozen=True)
class BoneChange:
    max_mm: float
    max_pct: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def bone_length_change(positions: Floats, skeleton: Skeleton) -> BoneChange:
    """Largest change of a bone's length in world positions ``(..., J, 3)`` vs the rest offsets."""
    positions = np.asarray(positions, dtype=np.float64)
    rest = np.linalg.norm(skeleton.offsets.astype(np.float64), axis=-1)[1:]
    bones = positions[..., 1:, :] - positions[..., skeleton.parents[1:], :]
    change = np.abs(np.linalg.norm(bones, axis=-1) - rest)
    pct = np.where(rest > 1e-9, change / np.maximum(rest, 1e-9) * 100.0, 0.0)
    return BoneChange(float(change.max() * 1000.0), float(pct.max()))


# --- Figures from foot heights alone, on exported motion (ENGINEERING.md, issue 27) -------------
# Annotated plants can hide what a viewer sees, so these read only world positions after FK.

GLIDE_HEIGHT_M = 0.025  # H of the near-ground glide weight 2 - 2^(h/H) (motion-generation papers)
STRICT_PLANT_M = 0.01  # a foot this close to the ground ...
STRICT_PLANT_FRAMES = 3  # ... for this many frames in a row is planted, whatever the annotation
FLIP_MIN_BEND_DEG = 15.0  # a joint bent less than this has no bend direction to flip (a dog's toe
# swings 10 deg one way to 10 the other in one frame at a gallop's paw strike: not a flip)


def foot_heights(foot_pos: Floats, ground: Floats | float = 0.0) -> Floats:
    """Height of each foot above the ground, ``(..., F, 4)``; ``ground`` broadcasts to ``(..., F)``."""
    return np.asarray(np.asarray(foot_pos, np.float64)[..., UP_AXIS] - np.asarray(ground)[..., None])


def over_standing(heights: Floats, standing: Floats, labels: NDArray[np.integer], started: NDArray[np.bool_],
                  fade: int) -> Floats:
    """``heights (C, F, 4)`` over each foot's standing height ``standing (C, L, 4)`` of the label
    shown (``labels (C, F)``: a gait per frame), or, for ``fade`` frames after a piece starts
    (``started (C, F)``: Result.stitches), of the label before it, whichever the foot stands nearest:
    the new piece fades in over the one before for that long (plan.MARGIN), so a frame's pose is
    still mostly the one before's -- a real dog's paw planted at its trot's 3.1 cm read 1.4 cm up
    the frame the label became the walk's (1.7 cm), unmoved. (A label changing with no piece
    starting -- halfway through a transition -- fades nothing.)"""
    rows, frames = np.arange(len(heights))[:, None], np.arange(heights.shape[1])
    last = np.maximum.accumulate(np.where(started, frames, -fade - 1), axis=1)  # the latest start so far
    before = labels[rows, np.maximum(last - 1, 0)]
    fading = ((frames - last) < fade) & (last >= 1)
    own, prior = heights - standing[rows, labels], heights - standing[rows, before]
    return np.asarray(np.where((fading[..., None]) & (np.abs(prior) < np.abs(own)), prior, own))


@dataclass(frozen=True)
class Glide:
    ratio: float  # foot_mm / body_mm
    foot_mm: float  # mean weighted horizontal foot speed over near-ground frames, mm/frame
    body_mm: float  # the body's mean horizontal speed, mm/frame (floored, see near_ground_glide)
    frames: int  # near-ground foot frames measured


def near_ground_glide(foot_pos: Floats, heights: Floats, body_pos: Floats,
                      height: float = GLIDE_HEIGHT_M, min_body_mm: float = 1.0) -> Glide:
    """Near-ground glide: a foot's horizontal speed weighted by ``2 - 2^(h/H)`` over the frame
    steps where it is below ``H`` (its mean height ``h`` over the step), divided by the body's
    mean horizontal speed. ``foot_pos (..., F, 4, 3)``, ``heights (..., F, 4)`` above the ground
    (:func:`foot_heights`), ``body_pos (..., F, 3)`` (the root), pooled over every leading axis.
    The body speed is floored at ``min_body_mm`` per frame (0.06 m/s at 60 fps): an animal
    turning on the spot has no speed to divide by, and its gliding feet must still count."""
    h = np.asarray(heights, np.float64)
    mid = 0.5 * (h[..., 1:, :] + h[..., :-1, :])
    speed = np.linalg.norm(np.diff(_horizontal(foot_pos), axis=-3), axis=-1) * 1000.0
    low = mid < height
    weighted = speed * (2.0 - np.exp2(np.clip(mid, 0.0, None) / height))
    body = np.linalg.norm(np.diff(_horizontal(body_pos), axis=-2), axis=-1) * 1000.0
    body_mm = max(float(body.mean()) if body.size else 0.0, min_body_mm)
    foot_mm = float(weighted[low].mean()) if low.any() else 0.0
    return Glide(foot_mm / body_mm, foot_mm, body_mm, int(low.sum()))


def strict_plants(heights: Floats, height: float = STRICT_PLANT_M, min_frames: int = STRICT_PLANT_FRAMES,
                  open_ends: bool = False) -> NDArray[np.bool_]:
    """Feet within ``height`` of the ground for ``min_frames`` frames or more, ``(..., F, 4)``.
    ``open_ends``: the frames are a stretch of a motion going on before and after them (a
    synthesized run, which stops mid-stride): a run at the first or last frame is a plant whatever
    its length, as nothing says it ends there (a foot set down on a run's second-last frame read as
    in the air, the animal on one foot)."""
    low = np.moveaxis(np.asarray(heights) < height, -2, 0)  # frames first, every foot a column
    kept = drop_short_runs(low.reshape(len(low), -1), min_frames, interior=open_ends).reshape(low.shape)
    return np.asarray(np.moveaxis(kept, 0, -2))


def touchdown_steps_mm(foot_pos: Floats, plants: NDArray[np.bool_]) -> Floats:
    """How far (3D, mm) each foot moved in the frame before each of its plants starts, flattened:
    the speed it lands at (a plant already under way at frame 0 has no touchdown)."""
    plants = np.asarray(plants, bool)
    step = np.linalg.norm(np.diff(np.asarray(foot_pos, np.float64), axis=-3), axis=-1) * 1000.0
    starts = plants[..., 1:, :] & ~plants[..., :-1, :]
    return np.asarray(step[starts])


def one_frame_jumps_mm(foot_pos: Floats) -> Floats:
    """``(..., F-3, 4)``: how much longer each foot's step (3D, mm) over one frame is than the
    mean of its steps just before and after. A foot moving steadily at any speed scores 0, one
    that jumps d in one frame and goes on as before scores d (a limb flip shows here). Frame f
    of the result is the step from input frame f + 1 to f + 2.

    Not the second difference: a paw stopping at touchdown scores its whole speed there, and the
    real dog's own canter reads 6-8 cm by it (0.8-2.4 cm by this one, ../shared/mocap)."""
    p = np.asarray(foot_pos, np.float64)
    step = np.linalg.norm(np.diff(p, axis=-3), axis=-1) * 1000.0
    return np.asarray(step[..., 1:-1, :] - 0.5 * (step[..., :-2, :] + step[..., 2:, :]))


def hinge_joints(skeleton: Skeleton) -> NDArray[np.int64]:
    """``(H, 3)`` (parent, joint, child) along every limb chain, for each joint with both."""
    triples = [(c[i - 1], c[i], c[i + 1]) for f in skeleton.feet for c in [f.chain]
               for i in range(1, len(c) - 1)]
    return np.array(triples, np.int64).reshape(-1, 3)


def limb_flips(positions: Floats, skeleton: Skeleton, root_rotations: Floats | None = None,
               min_bend_deg: float = FLIP_MIN_BEND_DEG) -> NDArray[np.int64]:
    """Per hinge of :func:`hinge_joints`, the frames where its bend direction reverses in one
    frame: the axis of the bend (parent bone x child bone) turns by more than 90 degrees between
    two frames where the joint is bent at least ``min_bend_deg`` (a straight joint has no
    direction; passing through straight takes frames). ``positions (..., F, J, 3)``; returns the
    count per hinge ``(H,)``, summed over leading axes. ``root_rotations (..., F, 4)``: the root's
    world rotations, to take the axes in the body's frame -- a body snapping round in one frame
    is no limb flip (it shows in the yaw rate)."""
    triples = hinge_joints(skeleton)
    p = np.asarray(positions, np.float64)
    upper = p[..., triples[:, 1], :] - p[..., triples[:, 0], :]
    lower = p[..., triples[:, 2], :] - p[..., triples[:, 1], :]
    axis = np.cross(upper, lower)
    norm = np.linalg.norm(axis, axis=-1)
    bent = np.degrees(np.arctan2(norm, np.sum(upper * lower, axis=-1))) >= min_bend_deg
    unit = axis / np.maximum(norm, 1e-12)[..., None]
    if root_rotations is not None:
        body = quat.inv(np.asarray(root_rotations, np.float64))[..., None, :]
        unit = quat.rotate(body, unit)
    turned = np.sum(unit[..., 1:, :, :] * unit[..., :-1, :, :], axis=-1) < 0
    flips = turned & bent[..., 1:, :] & bent[..., :-1, :]
    return np.asarray(flips.reshape(-1, len(triples)).sum(axis=0), np.int64)


def limb_reach(positions: Floats, skeleton: Skeleton) -> Floats:
    """``(..., 4)``: distance from each limb's root (hip, shoulder) to its foot, metres."""
    p = np.asarray(positions, np.float64)
    top = np.array([f.chain[0] for f in skeleton.feet])
    return np.asarray(np.linalg.norm(p[..., skeleton.foot_joints, :] - p[..., top, :], axis=-1))


HANG_UP = 0.05  # metres over the ground (times the character's scale) ...
HANG_STRAIGHT = 0.995  # ... with the leg's upper joint this share of thigh and shin from its ankle


def longest_hang(positions: Floats, skeleton: Skeleton, heights: Floats, scales: Floats) -> int:
    """The most frames in a row a foot hangs -- off the ground by more than HANG_UP with its leg
    straight (thigh and shin, the foot lock's IK chain), pointing at a target it cannot reach.
    A gallop's foreleg reaching forward is straight for a few frames; a foot left behind by a
    turning body hangs for a second (the horse's turn on the spot: a forefoot 45 cm up for 28)."""
    p = np.asarray(positions, np.float64)
    legs = np.array([(r.upper, r.hinge, r.ankle) for r in limb_rigs(skeleton)])
    upper, hinge, ankle = p[..., legs[:, 0], :], p[..., legs[:, 1], :], p[..., legs[:, 2], :]
    chain = np.linalg.norm(hinge - upper, axis=-1) + np.linalg.norm(ankle - hinge, axis=-1)
    straight = np.linalg.norm(ankle - upper, axis=-1) >= HANG_STRAIGHT * chain
    up = np.asarray(heights) > HANG_UP * np.asarray(scales, np.float64)[..., None, None]
    return int(run_lengths(np.moveaxis(straight & up, -1, -2)).max(initial=0))


def run_lengths(mask: NDArray[np.bool_]) -> NDArray[np.int64]:
    """``(..., F)``: at each True frame of ``mask``, how many True frames its run has had so far
    (1 at a run's first frame); 0 where False."""
    mask = np.asarray(mask, bool)
    t = np.arange(mask.shape[-1])
    last_false = np.maximum.accumulate(np.where(mask, -1, t), axis=-1)
    return np.asarray(np.where(mask, t - last_false, 0), np.int64)


def single_support_frames(down: NDArray[np.bool_]) -> NDArray[np.int64]:
    """``(..., F)``: frames a lone foot has carried the body so far (0: not alone), from ``down
    (..., F, 4)``; a run ends when another foot lands or the lone foot changes."""
    down = np.asarray(down, bool)
    alone = down & (down.sum(axis=-1, keepdims=True) == 1)
    return np.asarray(np.moveaxis(run_lengths(np.moveaxis(alone, -1, -2)), -2, -1).max(axis=-1))


def floating_m(heights: Floats, body_speed: Floats, slow: float = 0.1) -> float:
    """The lowest foot's largest height over frames where the body moves slower than ``slow``
    (m/s): ``heights (..., F, 4)``, ``body_speed (..., F)``. 0 when the body is never slow."""
    lowest = np.asarray(heights).min(axis=-1)
    still = np.asarray(body_speed) < slow
    return float(lowest[still].max()) if still.any() else 0.0


def stand_drift_m(root: Floats, feet: Floats, down: NDArray[np.bool_], slow: NDArray[np.bool_]) -> Floats:
    """``(..., F)``: over each run of frames with all four feet down while the body is slow
    (``slow (..., F)``), how far the root has moved over its feet (horizontally) since the run
    began -- its offset from the four feet's centre against that offset on the run's first
    frame; 0 elsewhere. ``root (..., F, 3)``, ``feet (..., F, 4, 3)``, ``down (..., F, 4)``. A
    standing animal shifts its weight a few cm; a body sliding on over pinned feet (a path
    creeping on below the slowest walk) reads as its whole slide."""
    offset = (np.asarray(root, np.float64) - np.asarray(feet, np.float64).mean(axis=-2))[..., [0, 2]]
    standing = np.asarray(down, bool).all(axis=-1) & np.asarray(slow, bool)
    F = standing.shape[-1]
    runs = standing.reshape(-1, F)
    before = np.zeros_like(runs)
    before[:, 1:] = runs[:, :-1]
    first = np.maximum.accumulate(np.where(runs & ~before, np.arange(F), 0), axis=1)
    off = offset.reshape(-1, F, 2)
    drift = np.linalg.norm(off - np.take_along_axis(off, first[..., None], axis=1), axis=-1) * runs
    return np.asarray(drift.reshape(standing.shape))


def yaw_rates_deg(root_rotations: Floats, fps: float) -> Floats:
    """``(..., F-1)``: the body's turning rate about the vertical (deg/s) from root rotations
    ``(..., F, 4)``: the heading of its forward axis (+Z) frame to frame."""
    forward = quat.rotate(np.asarray(root_rotations, np.float64), np.array([0.0, 0.0, 1.0]))
    yaw = np.unwrap(np.arctan2(forward[..., 0], forward[..., 2]), axis=-1)
    return np.asarray(np.abs(np.diff(yaw, axis=-1)) * fps * 180.0 / np.pi)


def mapped_frames(output_frames: int, input_frames: int) -> Floats:
    """Input time (fractional frame) of each output frame when the output covers the input's
    duration in another number of frames (a resampled clock), ``(output_frames,)``."""
    return np.linspace(0.0, input_frames - 1.0, output_frames)


def path_distance_cm(root_pos: Floats, target: Floats, window: int = 30) -> Floats:
    """``(..., T)``: horizontal distance (cm) of the root from the target path, after mapping
    output time to input time (:func:`mapped_frames`): from the nearest point of the target's
    segments within ``window`` input frames of that time -- so a root running a little ahead or
    behind along its path (a stride's surge) is on it, while a cut corner is not. The target goes
    on ``window`` frames past each end at its end's own pace (its first and last step): a surge
    ahead at the last frame is the same lead as anywhere else (the real dog's 2.5 cm surge read
    1.7 cm off a path ending at a canter), while a root past a path that stops is off it.
    ``root_pos (..., T, 3)``, ``target (..., F, 3)``."""
    root, path = _horizontal(root_pos), _horizontal(target)
    T, F = root.shape[-2], path.shape[-2]
    if F < 2:
        return np.asarray(np.linalg.norm(root - path, axis=-1) * 100.0)
    pad = window
    k = np.arange(1, pad + 1)[:, None]
    head = path[..., :1, :] - k[::-1] * (path[..., 1:2, :] - path[..., :1, :])
    tail = path[..., -1:, :] + k * (path[..., -1:, :] - path[..., -2:-1, :])
    path = np.concatenate([head, path, tail], axis=-2)
    u = mapped_frames(T, F) + pad
    seg = np.clip(np.floor(u).astype(np.int64)[:, None] + np.arange(-window, window + 1)[None, :], 0,
                  F + 2 * pad - 2)
    a, b = path[..., seg, :], path[..., seg + 1, :]  # (..., T, W, 2)
    d = b - a
    rel = root[..., :, None, :] - a
    s = np.clip(np.sum(rel * d, axis=-1) / np.maximum(np.sum(d * d, axis=-1), 1e-18), 0.0, 1.0)
    gap = np.linalg.norm(rel - s[..., None] * d, axis=-1)
    return np.asarray(gap.min(axis=-1) * 100.0)


def same_pattern_share(down: NDArray[np.bool_]) -> float:
    """How much a herd steps as one: over every pair of characters, the share of frames both show
    the same 4-foot contact pattern, averaged over the pairs (issue 28). ``down (C, F, 4)``: feet
    down after FK (e.g. :func:`strict_plants`). Characters with random stride phases score the
    gait's chance level (the sum of its patterns' squared shares: ~0.13 in a walk, ~0.34 in a
    trot); a herd in lock-step, 1."""
    down = np.asarray(down, bool)
    C, F = down.shape[:2]
    if C < 2:
        raise ValueError(f"same_pattern_share: need at least 2 characters, got {C}")
    code = down @ (1 << np.arange(down.shape[-1]))  # (C, F) pattern number
    counts = np.zeros((F, 1 << down.shape[-1]), np.int64)
    np.add.at(counts, (np.broadcast_to(np.arange(F), (C, F)), code), 1)
    same_pairs = (counts * (counts - 1) // 2).sum(axis=1)  # per frame: pairs showing one pattern
    return float(same_pairs.sum() / (F * C * (C - 1) / 2))
