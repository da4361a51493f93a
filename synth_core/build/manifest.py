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

from synth_core import FOOT_NAMES, UP_AXIS
from synth_core.build.artifact import Library
from synth_core.build.generated_transitions import (
    generate_transition,
    halves,
    hold_plants,
    standing,
    walk_frames,
)
from synth_core.build.mocap_clips import (
    LOOP_CLOSE_MAX_DEG,
    close_loop,
    loop_error,
    on_the_ground,
    stand_as,
    still_clip,
)
from synth_core.build.motion_graph import HUBS, transition_name
from synth_core.build.speed_map import SpeedRange, build_speed_map, default_ranges
from synth_core.motion import bvh
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
            ends = [maps[g].clip(0) if g in maps else idle for g in name.split("2")]
            transitions[name] = hold_plants(clip, walk_frames(name, clip.n_frames),
                                            halves(clip.n_frames, *(standing(e) for e in ends)))
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


