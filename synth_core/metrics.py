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

from synth_core import FOOT_NAMES, UP_AXIS, quat
from synth_core.contacts import touchdowns
from synth_core.skeleton import Skeleton

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
