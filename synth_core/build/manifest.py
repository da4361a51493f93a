"""Build a library from a user's own BVH mocap, described by a TOML manifest.

::

    animal = "mann_dog"                 # the library's name
    mocap_dir = "path/to/bvh"           # optional; relative to this file (default: its folder)
    unit = "cm"                         # the BVH files' unit: m, cm, mm, in, ft
    root_offset = "ignore"              # or "add" (see synth_core.motion.bvh)

    [feet]                              # end-effector joints (an End Site is "<parent>_end")
    LF = "LeftHand_end"
    RF = "RightHand_end"
    LH = "LeftFoot_end"
    RH = "RightFoot_end"

    [gaits.walk]                        # walk, trot, canter, gallop: one clean cycle each
    file = "walk.bvh"
    frames = [208, 245]                 # [first, stop): one stride, LH touchdown to the next
    # frames = "auto"; search = [7, 54] # or: the most loop-closed stride inside `search`

    [idle]                              # optional standing clip (default: a still frame)
    file = "stand.bvh"
    frames = [0, 147]

    [transitions.walk2trot]             # optional; static2walk ... gallop2canter
    file = "speed_up.bvh"
    frames = [330, 420]

    [contacts.walk]                     # optional manual planted ranges, frames of the clip
    LF = [[0, 20], [30, 37]]

    [speeds.walk]                       # optional speed-map range (m/s); default: see speed_map
    low = 0.5
    high = 1.2
    count = 60

A missing transition between two gaits is **generated**: the two gaits' speed-map clips at a
speed both ranges cover are cross-faded over a stride, the second time-shifted so its footfalls
agree best with the first's, and the feet are pinned to their plants with the same IK; the graph
marks it ``generated``. A missing ``static2walk``/``walk2static`` is made the same way from the
idle clip. Errors name the manifest field.
"""

from __future__ import annotations

import time
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from synth_core import FOOT_NAMES, UP_AXIS
from synth_core.build import ik
from synth_core.build.artifact import Library
from synth_core.build.motion_graph import HUBS, transition_name
from synth_core.build.speed_map import (
    SpeedMap,
    SpeedRange,
    build_speed_map,
    cycle_displacement,
    default_ranges,
    foot_targets,
    reach_limit,
    sink_for_reach,
)
from synth_core.motion import bvh, quat
from synth_core.motion import contacts as C
from synth_core.motion.clip import Motion

GAITS = HUBS[1:]
TRANSITIONS = [transition_name(a, b) for a, b in zip(HUBS[:-1], HUBS[1:], strict=True)] + \
              [transition_name(b, a) for a, b in zip(HUBS[:-1], HUBS[1:], strict=True)]
UNITS = ("m", "cm", "mm", "in", "ft")


class ManifestError(ValueError):
    """A manifest that cannot be built; the message names the field."""


def _field(doc: Mapping[str, Any], key: str, where: str, kind: type | tuple[type, ...]) -> Any:
    if key not in doc:
        raise ManifestError(f"{where}{key}: missing")
    value = doc[key]
    if not isinstance(value, kind):
        raise ManifestError(f"{where}{key}: expected {getattr(kind, '__name__', kind)}, got {value!r}")
    return value


class _Files:
    """BVH files read once each, with the manifest's unit and feet."""

    def __init__(self, folder: Path, unit: str, feet: dict[str, str], root_offset: str) -> None:
        self.folder, self.unit, self.feet, self.root_offset = folder, unit, feet, root_offset
        self.cache: dict[str, Motion] = {}

    def read(self, name: str, where: str) -> Motion:
        if name not in self.cache:
            path = self.folder / name
            if not path.is_file():
                raise ManifestError(f"{where}file: {path} not found")
            try:
                motion = bvh.read(path, unit=self.unit, feet=None, root_offset=self.root_offset)
                for foot, joint in self.feet.items():
                    if joint not in motion.skeleton.names:
                        raise ManifestError(f"feet.{foot}: no joint {joint!r} in {path.name} "
                                            f"(joints: {', '.join(motion.skeleton.names)})")
                skeleton = motion.skeleton.with_feet(self.feet)
            except bvh.BVHError as exc:
                raise ManifestError(f"{where}file: {exc}") from None
            motion = Motion(skeleton, motion.root_pos, motion.rotations, motion.fps, name=name)
            heights = motion.foot_positions()[..., UP_AXIS]
            planted = C.settle_plants(C.detect_contacts(motion), heights, C.SETTLE * skeleton.leg_length())
            self.cache[name] = motion.with_contacts(planted)
        return self.cache[name]


def _range(entry: Mapping[str, Any], where: str, motion: Motion) -> tuple[int, int]:
    frames = _field(entry, "frames", where, (list, str))
    if isinstance(frames, str):
        if frames != "auto":
            raise ManifestError(f'{where}frames: expected [first, stop] or "auto", got {frames!r}')
        search = entry.get("search", [0, motion.n_frames])
        first, stop = _pair(search, f"{where}search", motion.n_frames)
        return auto_cycle(motion, first, stop, f"{where}frames")
    return _pair(frames, f"{where}frames", motion.n_frames)


def _pair(value: Any, where: str, n_frames: int) -> tuple[int, int]:
    if not (isinstance(value, list) and len(value) == 2 and all(isinstance(v, int) for v in value)):
        raise ManifestError(f"{where}: expected [first, stop] (integers), got {value!r}")
    first, stop = value
    if 0 <= stop < first <= n_frames:
        raise ManifestError(f"{where}: [{first}, {stop}] is reversed: the first frame must come "
                            "before the stop frame")
    if not 0 <= first < stop <= n_frames:
        raise ManifestError(f"{where}: [{first}, {stop}] is out of bounds: the file has {n_frames} frames "
                            f"(0 <= first < stop <= {n_frames})")
    return first, stop


def auto_cycle(motion: Motion, first: int, stop: int, where: str) -> tuple[int, int]:
    """The stride (LH touchdown to the next) within [first, stop] that loops best."""
    downs = C.touchdowns(motion.contacts)[FOOT_NAMES.index("LH")]
    downs = downs[(downs >= first) & (downs <= stop)]
    if len(downs) < 2:
        raise ManifestError(f"{where}: no whole stride (two LH touchdowns) in frames [{first}, {stop}]")
    pos = motion.positions().astype(np.float64)
    body = pos - pos[:, :1]
    error = [np.linalg.norm(body[b] - body[a], axis=-1).mean() for a, b in zip(downs[:-1], downs[1:],
                                                                             strict=True)]
    k = int(np.argmin(error))
    return int(downs[k]), int(downs[k + 1])


def _clip(files: _Files, entry: Any, where: str, name: str, contacts: Mapping[str, Any] | None,
          notes: list[str] | None = None, spans: dict[str, str] | None = None) -> Motion:
    """A clip of the manifest, on the ground; a gait's cycle also made to loop where it nearly
    does (else ``notes`` gets a warning saying why not). ``spans[name]``: its file and frames."""
    if not isinstance(entry, Mapping):
        raise ManifestError(f"{where[:-1]}: expected a table with file and frames")
    motion = files.read(_field(entry, "file", where, str), where)
    first, stop = _range(entry, where, motion)
    span = f"{entry['file']} frames [{first}, {stop}]"
    if spans is not None:
        spans[name] = span
    clip = motion.slice(first, stop)
    clip = Motion(clip.skeleton, clip.root_pos, clip.rotations, clip.fps, clip.contacts, name,
                  name if name in GAITS else None)
    if name in GAITS and stop < motion.n_frames:
        following = motion.slice(stop, stop + 1)
        joint, turn = loop_error(clip, following)
        if turn <= LOOP_CLOSE_MAX_DEG:
            clip = close_loop(clip, following)
        elif notes is not None:
            notes.append(f"{where[:-1]}: {span} does not loop: {joint} turns {turn:.0f} deg "
                         f"from its first frame to the next stride's (more than {LOOP_CLOSE_MAX_DEG:.0f}); "
                         "its speed maps jump where they loop. A stride that repeats closes better")
    if contacts:
        try:
            clip = clip.with_contacts(C.apply_annotation(clip.contacts, contacts))
        except ValueError as exc:
            raise ManifestError(f"contacts.{name}: {exc}") from None
    return on_the_ground(clip)


LOOP_CLOSE_MAX_DEG = 30.0  # a leg joint turning more than this over the seam: not a repeating stride
# (the real dog's clean strides: 5-28 deg; a braking gallop's last stride: 78)


def loop_error(cycle: Motion, following: Motion) -> tuple[str, float]:
    """The leg joint whose rotation differs most (deg) between a cycle's first frame and the
    frame ``following`` it, and that angle."""
    legs = sorted({j for foot in cycle.skeleton.feet for j in foot.chain[:-1]})
    delta = quat.mul(cycle.rotations[0, legs], quat.inv(following.rotations[0, legs]))
    turn = np.degrees(2 * np.arccos(np.clip(np.abs(delta[:, 3]), 0.0, 1.0)))
    k = int(np.argmax(turn))
    return cycle.skeleton.names[legs[k]], float(turn[k])


def close_loop(cycle: Motion, following: Motion) -> Motion:
    """A mocap stride made to loop: the pose of the frame ``following`` it in the take (the next
    stride's first) is brought onto its own first pose, the difference spread evenly over it.

    A stride cut from a take never quite closes (the real dog's: 0.6-0.9 cm per joint on
    average, the swinging paw several cm), and a speed map plays it as a loop: the paw then
    jumped at every stride's seam -- 5-8 cm in one frame where the take itself moves 2-4 cm.
    """
    F, J = cycle.n_frames, cycle.skeleton.n_joints
    share = np.arange(F, dtype=np.float64) / F
    delta = quat.mul(cycle.rotations[0], quat.inv(following.rotations[0]))
    fix = quat.slerp(quat.identity((F, J), np.float64), np.broadcast_to(delta, (F, J, 4)), share[:, None])
    root = cycle.root_pos.astype(np.float64)
    root[:, UP_AXIS] += share * float(cycle.root_pos[0, UP_AXIS] - following.root_pos[0, UP_AXIS])
    return Motion(cycle.skeleton, root.astype(np.float32), quat.mul(fix, cycle.rotations).astype(np.float32),
                  cycle.fps, cycle.contacts, cycle.name, cycle.gait)


def on_the_ground(clip: Motion) -> Motion:
    """The clip raised or lowered so its planted feet stand at height 0 (:func:`C.plant_level`).

    Each take's floor and paw markers sit a little differently (the real dog's planted paws at
    -0.8 to +2.7 cm); a library puts every clip on one ground, so one clip's paws would float
    (2 cm while the dog stands) where another's sink into the floor.
    """
    level = C.plant_level(clip.contacts, clip.foot_positions()[..., UP_AXIS])
    if level is None:
        return clip
    root = clip.root_pos.copy()
    root[:, UP_AXIS] -= level
    return Motion(clip.skeleton, root, clip.rotations, clip.fps, clip.contacts, clip.name, clip.gait)


def _open(path: Path) -> tuple[dict[str, Any], _Files]:
    """The manifest's document and its BVH files (read when first asked for)."""
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ManifestError(f"{path}: no such manifest") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ManifestError(f"{path}: not valid TOML: {exc}") from None
    _field(doc, "animal", "", str)
    unit = doc.get("unit", "cm")
    if unit not in UNITS:
        raise ManifestError(f"unit: expected one of {list(UNITS)}, got {unit!r}")
    feet = _field(doc, "feet", "", dict)
    missing = [f for f in FOOT_NAMES if f not in feet]
    if missing:
        raise ManifestError(f"feet: missing {missing}; "
                            f"name the end-effector joint of all of {list(FOOT_NAMES)}")
    folder = (path.parent / doc.get("mocap_dir", ".")).resolve()
    return doc, _Files(folder, unit, {f: str(feet[f]) for f in FOOT_NAMES}, doc.get("root_offset", "ignore"))


def _cycles(doc: Mapping[str, Any], files: _Files) -> tuple[dict[str, Motion], list[str]]:
    """Each gait's cycle, checked (:func:`check_cycles`), and the warnings about them."""
    gaits_doc = _field(doc, "gaits", "", dict)
    for g in gaits_doc:  # an unknown name first: "missing" would hide the misspelt one
        _known_gait(g, "gaits")
    missing = [g for g in GAITS if g not in gaits_doc]
    if missing:
        raise ManifestError(f"gaits: missing {missing}; "
                            f"the motion graph needs a cycle of each of {list(GAITS)}")
    manual = doc.get("contacts", {})
    notes: list[str] = []
    spans: dict[str, str] = {}
    cycles = {g: _clip(files, gaits_doc[g], f"gaits.{g}.", g, manual.get(g), notes, spans) for g in GAITS}
    return cycles, check_cycles(cycles, spans) + notes


def gait_cycles(path: Path) -> dict[str, Motion]:
    """A manifest's gait cycles as a library build takes them (plants settled, on the ground),
    before any speed map: the source a library's clips are measured against."""
    doc, files = _open(path)
    return _cycles(doc, files)[0]


def build_from_manifest(path: Path) -> Library:
    started = time.perf_counter()
    doc, files = _open(path)
    animal = doc["animal"]
    manual = doc.get("contacts", {})
    cycles, doubts = _cycles(doc, files)
    sources = {g: c.speed_mps() for g, c in cycles.items()}
    ranges = default_ranges(sources)
    for g, spec in doc.get("speeds", {}).items():
        _known_gait(g, "speeds")
        try:
            ranges[g] = SpeedRange(float(spec.get("low", ranges[g].low)),
                                   float(spec.get("high", ranges[g].high)),
                                   int(spec.get("count", ranges[g].count)))
        except (ValueError, TypeError, AttributeError) as exc:
            raise ManifestError(f"speeds.{g}: {exc}") from None
    maps = {}
    for g in GAITS:
        try:
            maps[g] = build_speed_map(cycles[g], ranges[g].speeds())
        except ValueError as exc:
            raise ManifestError(f"gaits.{g}: {exc}") from None
    idle = (_clip(files, doc["idle"], "idle.", "idle", manual.get("idle")) if "idle" in doc
            else still_clip(cycles["walk"]))
    idle = Motion(idle.skeleton, idle.root_pos, idle.rotations, idle.fps, np.ones_like(idle.contacts),
                  "idle", "static")
    given = doc.get("transitions", {})
    unknown = [t for t in given if t not in TRANSITIONS]
    if unknown:
        raise ManifestError(f"transitions: unknown {unknown}; transitions are {TRANSITIONS}")
    transitions, generated = {}, set()
    for name in TRANSITIONS:
        if name in given:
            # Mocap feet roll and slide a little in every plant; the library's feet do not.
            clip = _clip(files, given[name], f"transitions.{name}.", name, manual.get(name))
            if name.startswith("static") or name.endswith("static"):
                clip = stand_as(clip, idle, at_start=name.startswith("static"))
            transitions[name] = _hold_plants(clip)
        else:
            source, target = name.split("2")
            transitions[name] = generate_transition(maps.get(source), maps.get(target), idle, name)
            generated.add(name)
    return Library(animal, cycles["walk"].skeleton, cycles["walk"].fps, maps, idle, transitions,
                   frozenset(generated), source=str(path),
                   extra={"ranges": {g: [r.low, r.high, r.count] for g, r in ranges.items()},
                          "build_seconds": round(time.perf_counter() - started, 3),
                          **({"warnings": doubts} if doubts else {})})


def _known_gait(name: str, where: str) -> None:
    if name not in GAITS:
        raise ManifestError(f"{where}.{name}: unknown gait {name!r}; known: {', '.join(GAITS)}")


MIN_CYCLE_SPEED = 0.25  # leg lengths per second: slower than this, a "gait cycle" is someone standing
# The footfall families a gait tier takes (contacts.classify_gait's names, before any "-"): the
# slow tiers are symmetric gaits (the real dog's usual walk is a pace), the fast ones asymmetric.
TIER_FOOTFALLS = {"walk": ("walk", "walk-diagonal", "pace"), "trot": ("trot", "pace"),
                  "canter": ("canter", "gallop"), "gallop": ("gallop", "canter")}


def check_cycles(cycles: Mapping[str, Motion], where: Mapping[str, str]) -> list[str]:
    """Refuse gait cycles that cannot make a library; return warnings about doubtful ones.

    Refused (:class:`ManifestError`, naming the gait, its file and frames and what was found):
    a cycle that does not move (a standing segment declared as a gait would build a map whose
    every clip stands) and gaits out of speed order (a walk declared as the gallop would make a
    gallop slower than the canter, and the graph would pick it for the wrong speeds). Warned:
    a cycle whose footfall is not its tier's, e.g. a trot declared as the canter.
    """
    speeds = {g: c.speed_mps() for g, c in cycles.items()}
    for g, clip in cycles.items():
        least = MIN_CYCLE_SPEED * clip.skeleton.leg_length()
        if speeds[g] < least:
            raise ManifestError(f"gaits.{g}: {where[g]} moves at {speeds[g]:.2f} m/s: a gait cycle "
                                f"must move (at least {least:.2f} m/s, {MIN_CYCLE_SPEED} leg lengths "
                                "per second); is it a standing segment?")
    order = [g for g in GAITS if g in cycles]
    for slow, fast in zip(order[:-1], order[1:], strict=False):
        if speeds[fast] <= speeds[slow]:
            raise ManifestError(f"gaits.{fast}: {where[fast]} moves at {speeds[fast]:.2f} m/s, no "
                                f"faster than the {slow} ({where[slow]}, {speeds[slow]:.2f} m/s); "
                                f"gaits go {', '.join(GAITS)} from slow to fast")
    warnings = []
    for g, clip in cycles.items():
        found = C.classify_gait(C.footfall_pattern(clip.contacts, cyclic=True))
        if found.split("-")[0] not in TIER_FOOTFALLS[g] and found not in TIER_FOOTFALLS[g]:
            warnings.append(f"gaits.{g}: {where[g]} has the footfall of a {found}, not of a {g} "
                            f"(expected one of {', '.join(TIER_FOOTFALLS[g])})")
    return warnings


def still_clip(like: Motion, seconds: float = 2.0) -> Motion:
    """Standing still: the cycle's frame with the most feet down (ties: the lowest feet), held."""
    feet_y = like.foot_positions()[..., UP_AXIS]
    score = like.contacts.sum(axis=1) - feet_y.sum(axis=1)
    f = int(np.argmax(score))
    n = int(round(seconds * like.fps))
    root = np.repeat(like.root_pos[f:f + 1], n, axis=0)
    return Motion(like.skeleton, root, np.repeat(like.rotations[f:f + 1], n, axis=0), like.fps,
                  np.ones((n, 4), bool), "idle", "static")


def _heading(motion: Motion) -> float:
    travel = motion.root_pos[-1] - motion.root_pos[0]
    return float(np.arctan2(travel[0], travel[2])) if np.hypot(travel[0], travel[2]) > 1e-6 else 0.0


def _turned(motion: Motion, yaw: float, start: np.ndarray) -> Motion:
    """The motion turned by ``yaw`` about +Y around its first root position, moved to ``start``."""
    q = quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), yaw)
    root = quat.rotate(q, motion.root_pos - motion.root_pos[0]) + start
    rotations = motion.rotations.copy()
    rotations[:, 0] = quat.mul(q, rotations[:, 0])
    return Motion(motion.skeleton, root.astype(np.float32), rotations, motion.fps, motion.contacts,
                  motion.name, motion.gait)


def _loops(clip: Motion, times: int) -> Motion:
    advance = cycle_displacement(clip.root_pos)
    root = np.concatenate([clip.root_pos + k * advance for k in range(times)])
    return Motion(clip.skeleton, root, np.tile(clip.rotations, (times, 1, 1)), clip.fps,
                  np.tile(clip.contacts, (times, 1)), clip.name, clip.gait)


def _nearest(speed_map: SpeedMap, speed: float) -> Motion:
    return speed_map.clip(int(np.abs(speed_map.speeds - speed).argmin()))


def generate_transition(a: SpeedMap | None, b: SpeedMap | None, idle: Motion, name: str) -> Motion:
    """A transition the data lacks: a's clip cross-faded into b's at a speed both can do."""
    if a is not None and b is not None:
        low = max(a.speeds[0], b.speeds[0])
        high = min(a.speeds[-1], b.speeds[-1])
        speed = 0.5 * (low + high) if low <= high else 0.5 * (a.speeds[-1] + b.speeds[0])
        first, second = _loops(_nearest(a, speed), 2), _loops(_nearest(b, speed), 2)
    elif a is not None:  # gait -> static: slow to the slowest clip, then stand
        first, second = _loops(a.clip(0), 2), idle
    elif b is not None:  # static -> gait
        first, second = idle, _loops(b.clip(0), 2)
    else:
        raise ValueError(f"{name}: neither side has clips")
    second = _turned(second, _heading(first) - _heading(second) if second.speed_mps() > 0.01 else 0.0,
                     first.root_pos[-1])
    return _crossfade(first, second, name)


def _best_shift(first: NDArray[np.bool_], second: NDArray[np.bool_], W: int, strides: int) -> int:
    """The cyclic shift of ``second`` whose footfalls carry on best from ``first``'s.

    Scored on the contacts the blend will have (first's, then second's from the blend's middle):
    first by how many frames steps come too soon (a doubled step: shorter than 0.6 of the shorter
    stride) or too late (a skipped one: longer than 1.5 of the longer stride), then by how well
    the two agree over the blend. Between gaits of different footfall (a trot's diagonal pairs,
    a canter's lead) one quick step may be unavoidable; this makes it the least quick.
    """
    Fa, Fb = len(first), len(second)
    stride_a, stride_b = Fa / strides, Fb / strides
    cut = Fa - W // 2  # where the blend's contacts switch over
    best: tuple[float, int, int] | None = None
    for s in range(Fb):  # offline, a few dozen candidates
        rolled = np.roll(second, -s, axis=0)
        played = np.concatenate([first[:cut], rolled[W - W // 2:]])
        gaps = np.concatenate([np.diff(downs) for downs in C.touchdowns(played)])
        short, long = 0.6 * min(stride_a, stride_b), 1.5 * max(stride_a, stride_b)
        odd = np.maximum(short - gaps, 0) + np.maximum(gaps - long, 0)
        score = (float(odd.sum()), -int((rolled[:W] == first[-W:]).sum()), s)
        best = score if best is None or score < best else best
    assert best is not None
    return best[2]


REACH_EASE_FRAMES = 9  # a transition's sink eases in and out over this many frames (as the foot lock's)
MAX_SINK = 0.15  # of the leg length, the most a transition's root is lowered: a plant joined over
# a blend's switch lies between the two clips' footprints, and reaching it crouched the real
# dog's generated canter2gallop 15 cm (a third of its leg) for 8 frames
SWITCH_GAP = 2  # frames: a gap this short where a blend switches contacts joins the plants


def _crossfade(first: Motion, second: Motion, name: str, strides: int = 2) -> Motion:
    """first, then second, blended over the frames where they overlap; feet pinned by IK.

    Both hold ``strides`` strides (a still clip: any length). ``second`` is time-shifted
    (cyclically, by up to its own length) so that footfalls carry on across the blend instead of
    doubling or skipping a step (:func:`_best_shift`).
    """
    Fa, Fb = first.n_frames, second.n_frames
    W = min(Fa, Fb) // 2
    s = _best_shift(first.contacts, second.contacts, W, strides)
    rot_b = np.roll(second.rotations, -s, axis=0)
    con_b = np.roll(second.contacts, -s, axis=0)
    # Steps into each frame, the loop's own seam step included, then shifted: rolling positions
    # instead would put the whole loop's advance, backwards, into one step.
    seam = second.root_pos[-1:] - cycle_displacement(second.root_pos)
    step_b = np.roll(np.diff(second.root_pos, axis=0, prepend=seam), -s, axis=0)
    T = Fa + Fb - W
    w = np.zeros(T)
    w[Fa - W:Fa] = np.linspace(0.0, 1.0, W)
    w[Fa:] = 1.0
    w = w * w * (3 - 2 * w)
    rot_a = np.concatenate([first.rotations, np.repeat(first.rotations[-1:], Fb - W, axis=0)])
    rot_bb = np.concatenate([np.repeat(rot_b[:1], Fa - W, axis=0), rot_b])
    rotations = quat.slerp(rot_a, rot_bb, w[:, None])
    step_a = np.diff(first.root_pos, axis=0, prepend=first.root_pos[:1])
    step_a[0] = step_a[1]
    steps = (1 - w)[:, None] * np.concatenate([step_a, np.repeat(step_a[-1:], Fb - W, axis=0)]) \
        + w[:, None] * np.concatenate([np.repeat(step_b[:1], Fa - W, axis=0), step_b])
    root = first.root_pos[0] + np.cumsum(steps, axis=0) - steps[0]
    height_a = np.concatenate([first.root_pos[:, UP_AXIS], np.full(Fb - W, first.root_pos[-1, UP_AXIS])])
    height_b = np.concatenate([np.full(Fa - W, second.root_pos[0, UP_AXIS]),
                               np.roll(second.root_pos, -s, axis=0)[:, UP_AXIS]])
    heights = (1 - w) * height_a + w * height_b
    root[:, UP_AXIS] = heights
    contacts = np.where((w < 0.5)[:, None],
                        np.concatenate([first.contacts, np.repeat(first.contacts[-1:], Fb - W, axis=0)]),
                        np.concatenate([np.repeat(con_b[:1], Fa - W, axis=0), con_b]))
    # A foot planted in both clips around the switch but lifted for a frame or two there (one
    # plant ends just before the other starts) stands in one plant: two would be pinned apart,
    # and the foot would jump between them (11 cm in the real dog's canter2gallop).
    contacts = C.fill_gaps(contacts, SWITCH_GAP)
    return _hold_plants(Motion(first.skeleton, root, rotations, first.fps, contacts, name, None))


def stand_as(clip: Motion, idle: Motion, at_start: bool) -> Motion:
    """A start (``at_start``) or a stop whose standing frames stand as the idle does: raised or
    lowered there by the difference of their feet's heights, easing back to the clip's own level
    (:func:`on_the_ground`, set by its walking plants) over its first step out of (or last into)
    the stance.

    Each clip is put on the ground by its own plants: a start's are mostly walking ones, where the
    real dog's paw end sites stand about 1 cm lower than standing, so its standing frames (the same
    frames of the same take as the idle's last ones) stood 0.8-0.9 cm above the idle's and every
    real-dog character started floating that high (issue 27: floating <= 1 cm)."""
    contacts = clip.contacts if at_start else clip.contacts[::-1]
    moving = np.flatnonzero(~contacts.all(axis=1))
    if len(moving) == 0:
        return clip
    still = int(moving[0])  # frames standing at the static end
    if still == 0:
        return clip
    lifted = int(np.flatnonzero(~contacts[still])[0])  # the first foot to step
    down = np.flatnonzero(contacts[still:, lifted])
    step = int(down[0]) if len(down) else len(contacts) - still  # its swing, frames
    heights = clip.foot_positions()[:, :, UP_AXIS]
    heights = heights if at_start else heights[::-1]
    offset = float(np.median(np.median(idle.foot_positions()[:, :, UP_AXIS], axis=0) - heights[:still]))
    u = np.clip((np.arange(len(contacts)) - still + 1) / max(step + 1, 1), 0.0, 1.0)
    weight = 1.0 - u * u * (3 - 2 * u)
    root = clip.root_pos.astype(np.float64)
    root[:, UP_AXIS] += offset * (weight if at_start else weight[::-1])
    return Motion(clip.skeleton, root.astype(np.float32), clip.rotations, clip.fps, clip.contacts,
                  clip.name, clip.gait)


def _hold_plants(motion: Motion) -> Motion:
    """Every plant held at its average place, swings eased between (as in the speed map), by IK."""
    feet = motion.foot_positions()
    root = np.asarray(motion.root_pos, np.float64)
    targets = foot_targets(feet, root, root[None], motion.contacts, cyclic=False)[0]
    rigs = ik.limb_rigs(motion.skeleton)
    # As in the speed maps, the root sinks where a plant would lock a leg straight (a straight
    # leg has no bend side; the synthesis's foot lock would then pick one frame by frame).
    root = sink_for_reach(motion, root, motion.rotations, targets, rigs, ease=REACH_EASE_FRAMES,
                          most=MAX_SINK * motion.skeleton.leg_length())
    # Deeper than that, the foot falls short of its plant (slides a little) instead.
    targets = ik.within_reach(motion.skeleton, root, motion.rotations, targets,
                              reach_limit(motion, rigs), rigs)
    axes = ik.hinge_axes_over_time(motion.skeleton, motion.rotations, rigs)
    solved = ik.solve(motion.skeleton, root, motion.rotations, targets, rigs,
                      ground=float(feet[..., UP_AXIS].min()), axes=axes)
    rotations = ik.mend_flips(solved.rotations, solved.wrong_side, rigs)
    return Motion(motion.skeleton, root.astype(np.float32), rotations, motion.fps, motion.contacts,
                  motion.name, motion.gait)
