"""Foot plants: automatic detection, manual annotation, and the beat (footfall) pattern.

Detection works on the four foot end effectors' world positions and scales every threshold by
the animal's leg length, so a horse and a dog use the same settings. A foot is planted while it
is low and slow. Two thresholds give hysteresis (a plant starts only where the foot is clearly
low and slow, and lasts while it stays within looser limits), then plants shorter than a minimum
duration are dropped and tiny gaps filled. All of it is array work over frames and feet.

The default thresholds follow the analysis of the real dog in ``../shared/mocap/mann_dog/SOURCE.md``
(paw below 5 cm and slower than 30 cm/s + 0.3 x body speed, for a 0.45 m leg).

The paper annotates plant frames by hand (its f_c, j_c); :func:`apply_annotation` lets manual
ranges override detection per foot. Ranges are half-open ``[start, stop)`` frame intervals.

Beat pattern (:func:`footfall_pattern`): strides run from one LH touchdown to the next; per stride
each foot's touchdown phase relative to LH, its duty factor (planted share of the stride), and
the order in which the feet touch down. :func:`classify_gait` names the gait from those phases.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from synth_core import FOOT_NAMES, UP_AXIS
from synth_core.motion.clip import Motion

FrameRanges = Mapping[str, Sequence[tuple[int, int]]]


@dataclass(frozen=True)
class ContactParams:
    """Thresholds for plant detection, in leg lengths (L) and seconds."""

    height: float = 0.11  # foot below this height above ground (x L) may start a plant
    speed: float = 0.67  # ... and slower than this (x L per second) ...
    speed_body: float = 0.3  # ... plus this share of the body's horizontal speed
    release: float = 1.25  # a plant lasts while height and speed stay below release x the above
    min_plant_s: float = 0.05  # shorter plants are noise
    max_gap_s: float = 0.034  # gaps this short inside a plant are filled


def runs(mask: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Half-open ``[start, stop)`` runs of True in a 1D mask, shape (R, 2)."""
    padded = np.concatenate([[False], np.asarray(mask, bool), [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return edges.reshape(-1, 2)


_VERTICAL = np.array([[0, 1, 0]] * 3, bool)  # label runs along frames, never across feet


def _short_runs(mask: NDArray[np.bool_], shorter_than: int, interior: bool) -> NDArray[np.bool_]:
    """Frames of (F, K) ``mask`` in runs (per column) of fewer than ``shorter_than`` frames.

    ``interior``: only runs that touch neither the first nor the last frame.
    """
    labels, count = ndimage.label(mask, structure=_VERTICAL)
    if count == 0:
        return np.zeros_like(mask)
    small = np.bincount(labels.ravel(), minlength=count + 1) < shorter_than
    if interior:
        small[labels[0]] = False
        small[labels[-1]] = False
    small[0] = False
    return np.asarray(small[labels])


def fill_gaps(mask: NDArray[np.bool_], max_gap: int) -> NDArray[np.bool_]:
    """Per column of a (F, K) mask: fill interior gaps of <= max_gap frames.

    A gap at the clip's start or end is not filled: nothing says the foot was planted outside.
    """
    return np.asarray(mask | _short_runs(~mask, max_gap + 1, interior=True))


def drop_short_runs(mask: NDArray[np.bool_], min_len: int, interior: bool = False) -> NDArray[np.bool_]:
    """Per column of a (F, K) mask: runs of fewer than ``min_len`` True frames dropped (``interior``:
    only those touching neither the first nor the last frame)."""
    return np.asarray(mask & ~_short_runs(mask, min_len, interior=interior))


def _fill_gaps_and_drop_short(mask: NDArray[np.bool_], max_gap: int, min_len: int) -> NDArray[np.bool_]:
    """Per column of a (F, K) mask: fill interior gaps of <= max_gap frames, then drop runs < min_len."""
    return drop_short_runs(fill_gaps(mask, max_gap), min_len)


def ground_height(foot_heights: NDArray[np.floating]) -> float:
    """Ground level estimated from foot heights: a low percentile, robust to a few bad frames."""
    return float(np.percentile(foot_heights, 2.0))


def detect_contacts(motion: Motion, params: ContactParams = ContactParams(),
                    ground: float | None = None) -> NDArray[np.bool_]:
    """Planted flags (F, 4) in FOOT_NAMES order, from foot height and speed.

    ``ground``: the ground's height in metres; estimated from the feet when None.
    """
    return detect_contacts_at(motion.foot_positions(), motion.root_pos, motion.fps,
                              motion.skeleton.leg_length(), params, ground)


def detect_contacts_at(foot_pos: NDArray[np.floating], root_pos: NDArray[np.floating], fps: float,
                       leg: float, params: ContactParams = ContactParams(),
                       ground: float | None = None) -> NDArray[np.bool_]:
    """:func:`detect_contacts` on positions: feet ``(F, 4, 3)``, root ``(F, 3)``, leg length (m).

    For poses a Motion cannot hold, e.g. limbs stretched by IK.
    """
    feet = np.asarray(foot_pos, dtype=np.float64)  # (F, 4, 3)
    height = feet[..., UP_AXIS]
    height = height - (ground_height(height) if ground is None else ground)
    horiz = np.delete(feet, UP_AXIS, axis=-1)
    # Central differences (one-sided at the ends) so speed is centred on each frame.
    foot_speed = np.linalg.norm(np.gradient(horiz, axis=0), axis=-1) * fps
    root = np.delete(np.asarray(root_pos, dtype=np.float64), UP_AXIS, axis=-1)
    body_speed = np.linalg.norm(np.gradient(root, axis=0), axis=-1) * fps
    body_speed = ndimage.uniform_filter1d(body_speed, size=max(3, int(0.25 * fps)))
    speed_limit = params.speed * leg + params.speed_body * body_speed[:, None]
    strong = (height < params.height * leg) & (foot_speed < speed_limit)
    weak = (height < params.release * params.height * leg) & (foot_speed < params.release * speed_limit)
    # Hysteresis as connected components: a weak run counts only if it holds a strong frame.
    labels, count = ndimage.label(weak, structure=_VERTICAL)
    has_strong = np.zeros(count + 1, bool)
    has_strong[labels[strong]] = True
    has_strong[0] = False
    planted = has_strong[labels]
    return _fill_gaps_and_drop_short(planted, max_gap=int(round(params.max_gap_s * fps)),
                                     min_len=max(1, int(round(params.min_plant_s * fps))))


SETTLE = 0.04  # x L: a plant holds while its foot is this close to the plant's lowest point


def settle_plants(contacts: NDArray[np.bool_], foot_heights: NDArray[np.floating],
                  tolerance: float) -> NDArray[np.bool_]:
    """Each plant of ``contacts (F, K)`` trimmed to the frames from the first to the last where
    its foot is within ``tolerance`` (m) of the plant's lowest height ``foot_heights (F, K)``.

    Detection's loose thresholds start a plant while a mocap paw is still coming down (the real
    dog's paws are 4-6 cm up on the first "planted" frame) and end it once the heel has risen.
    A library pins a plant at one height, so those frames would drop the foot several cm in a
    frame at touchdown (and lift it at lift-off); trimmed, the foot comes down as it did.
    """
    labels, count = ndimage.label(contacts, structure=_VERTICAL)
    if count == 0:
        return np.asarray(contacts, bool).copy()
    index = np.arange(1, count + 1)
    lowest = np.asarray(ndimage.minimum(foot_heights, labels, index))
    low = (labels > 0) & (foot_heights <= np.append(np.inf, lowest)[labels] + tolerance)
    t = np.broadcast_to(np.arange(contacts.shape[0])[:, None], contacts.shape)
    first = np.append(0, ndimage.minimum(t, labels * low, index))
    last = np.append(-1, ndimage.maximum(t, labels * low, index))
    return np.asarray((labels > 0) & (t >= first[labels]) & (t <= last[labels]))


def hold_down(contacts: NDArray[np.bool_], least: int, cyclic: bool = True,
              where: NDArray[np.bool_] | None = None) -> NDArray[np.bool_]:
    """``contacts (F, K)`` with at least ``least`` feet down in every frame (of ``where``, default
    all; where that many ever are): a frame with fewer extends the plant that ended last in
    ``contacts`` (the foot lifted most recently stays down until another lands). ``cyclic``: the clip loops (a
    plant over its end counts); else a frame before any lift-off is left as it is.

    The real dog's pace hands over from one lateral pair to the next with a gap: a hind paw
    lifts 1-4 frames before its partner lands, one paw carries the body, and a walk must
    always have two down (issue 27)."""
    source = np.asarray(contacts, bool)
    held = source.copy()
    F, K = held.shape
    if least <= 0 or F == 0 or held.any(axis=0).sum() < least:
        return held
    short = held.sum(axis=1) < least
    for t in np.flatnonzero(short if where is None else short & where):
        # frames since each lifted foot's own plant ended, counted back from t (F: never)
        back = np.arange(1, F if cyclic else t + 1)
        since = [F if held[t, k] else next((int(b) for b in back if source[(t - b) % F, k]), F)
                 for k in range(K)]
        for k in np.argsort(since, kind="stable")[: least - int(held[t].sum())]:
            if since[k] < F:
                held[(t - np.arange(since[k])) % F, k] = True
    return held


def plant_level(contacts: NDArray[np.bool_], foot_heights: NDArray[np.floating]) -> float | None:
    """The height a clip's planted feet stand at: per foot, the median of its plants' lowest
    points; of the feet, the lowest (None: nothing planted). ``contacts``, ``foot_heights (F, K)``.

    A median, as a mocap take's floor is not quite flat and a paw now and then sinks below it (the
    real dog's gallop by 0.8 cm); the lowest foot, as markers sit higher on some paws than others.
    """
    labels, count = ndimage.label(contacts, structure=_VERTICAL)
    if count == 0:
        return None
    index = np.arange(1, count + 1)
    lowest = np.asarray(ndimage.minimum(foot_heights, labels, index))
    foot = np.asarray(ndimage.minimum(np.broadcast_to(np.arange(contacts.shape[1]), contacts.shape),
                                      labels, index)).astype(np.int64)
    return float(min(np.median(lowest[foot == k]) for k in np.unique(foot)))


def ranges_to_contacts(ranges: FrameRanges, n_frames: int) -> NDArray[np.bool_]:
    """(F, 4) planted flags from per-foot ``[start, stop)`` ranges; unknown feet or bad ranges raise."""
    contacts = np.zeros((n_frames, len(FOOT_NAMES)), bool)
    for foot, foot_ranges in ranges.items():
        if foot not in FOOT_NAMES:
            raise ValueError(f"contacts: unknown foot {foot!r}; feet are {list(FOOT_NAMES)}")
        for start, stop in foot_ranges:
            if stop < start:
                raise ValueError(f"contacts.{foot}: range [{start}, {stop}) is reversed: the first frame "
                                 "must come before the stop frame")
            if not 0 <= start < stop <= n_frames:
                raise ValueError(f"contacts.{foot}: range [{start}, {stop}) is outside "
                                 f"[0, {n_frames}) or empty")
            contacts[start:stop, FOOT_NAMES.index(foot)] = True
    return contacts


def contacts_to_ranges(contacts: NDArray[np.bool_]) -> dict[str, list[tuple[int, int]]]:
    """Per-foot half-open planted ranges from (F, 4) flags (the JSON-friendly form)."""
    return {foot: [(int(a), int(b)) for a, b in runs(contacts[:, k])]
            for k, foot in enumerate(FOOT_NAMES)}


def apply_annotation(contacts: NDArray[np.bool_], annotation: FrameRanges) -> NDArray[np.bool_]:
    """Manual ranges override detection: each annotated foot's column is replaced entirely."""
    manual = ranges_to_contacts(annotation, contacts.shape[0])
    out = contacts.copy()
    for foot in annotation:
        k = FOOT_NAMES.index(foot)
        out[:, k] = manual[:, k]
    return out


def touchdowns(contacts: NDArray[np.bool_], cyclic: bool = False) -> list[NDArray[np.int64]]:
    """Per foot, the frames where a plant starts (False -> True).

    ``cyclic``: the clip loops, so a plant running over the last frame into frame 0 starts
    where it really starts. Otherwise a plant already under way at frame 0 started before the
    clip and is no touchdown.
    """
    before = np.roll(contacts, 1, axis=0) if cyclic else np.vstack([contacts[:1], contacts[:-1]])
    starts = contacts & ~before
    return [np.flatnonzero(starts[:, k]) for k in range(contacts.shape[1])]


@dataclass(frozen=True)
class FootfallPattern:
    """The beat pattern of a clip, per stride (LH touchdown to the next LH touchdown)."""

    strides: NDArray[np.int64]  # (S, 2) [start, stop) frames
    phases: NDArray[np.float64]  # (S, 4) touchdown phase of each foot in [0, 1), LH = 0; NaN if none
    duty: NDArray[np.float64]  # (S, 4) planted share of the stride per foot
    sequences: tuple[tuple[str, ...], ...]  # per stride, feet in touchdown order (starting LH)

    @property
    def mean_phases(self) -> NDArray[np.float64]:
        """Circular mean phase per foot over strides, in [0, 1)."""
        angles = 2 * np.pi * self.phases
        mean = np.arctan2(np.nanmean(np.sin(angles), axis=0), np.nanmean(np.cos(angles), axis=0))
        return np.asarray(np.mod(mean / (2 * np.pi), 1.0))

    @property
    def mean_duty(self) -> float:
        return float(np.mean(self.duty)) if self.duty.size else float("nan")


def footfall_pattern(contacts: NDArray[np.bool_], cyclic: bool = False) -> FootfallPattern:
    """Strides, touchdown phases relative to LH, duty factors and touchdown order.

    For a ``cyclic`` clip the single stride wraps around the clip end.
    """
    F = contacts.shape[0]
    downs = touchdowns(contacts, cyclic=cyclic)
    lh = downs[FOOT_NAMES.index("LH")]
    if cyclic and len(lh):
        # One stride per LH touchdown, the last wrapping around to the first.
        strides = np.stack([lh, np.append(lh[1:], lh[0] + F)], axis=1)
    else:
        strides = np.stack([lh[:-1], lh[1:]], axis=1) if len(lh) > 1 else np.zeros((0, 2), np.int64)
    S = len(strides)
    phases = np.full((S, 4), np.nan)
    duty = np.zeros((S, 4))
    sequences = []
    for s, (a, b) in enumerate(strides):
        frames = np.arange(a, b) % F
        length = b - a
        duty[s] = contacts[frames].mean(axis=0)
        for k in range(4):
            d = downs[k]
            d = np.concatenate([d, d + F]) if cyclic else d
            inside = d[(d >= a) & (d < b)]
            if len(inside):
                phases[s, k] = (inside[0] - a) / length
        # By phase; on a tie (trot, pace) LH first, so every sequence starts at LH.
        order = np.lexsort((np.arange(4) != FOOT_NAMES.index("LH"),
                            np.where(np.isnan(phases[s]), np.inf, phases[s])))
        sequences.append(tuple(FOOT_NAMES[k] for k in order if not np.isnan(phases[s, k])))
    return FootfallPattern(strides, phases, duty, tuple(sequences))


def _near(phase: float, target: float, tol: float) -> bool:
    d = abs((phase - target + 0.5) % 1.0 - 0.5)
    return d <= tol


def classify_gait(pattern: FootfallPattern) -> str:
    """Name the gait from mean touchdown phases relative to LH.

    Symmetric gaits (RH half a stride after LH): ``pace`` (LF with LH), ``trot`` (RF with LH),
    ``walk`` (4-beat, lateral sequence: LF 0.1-0.4 after LH) or ``walk-diagonal`` (LF 0.6-0.9).
    Asymmetric gaits: ``canter`` when three beats (a diagonal pair together), else ``gallop``,
    suffixed by its order: ``-rotary`` (leading hind and fore on opposite sides) or
    ``-transverse``.
    """
    if len(pattern.strides) == 0:
        return "unknown"
    ph = dict(zip(FOOT_NAMES, pattern.mean_phases, strict=True))
    if _near(ph["RH"], 0.5, 0.12):
        if _near(ph["LF"], 0.0, 0.1) and _near(ph["RF"], 0.5, 0.12):
            return "pace"
        if _near(ph["RF"], 0.0, 0.1) and _near(ph["LF"], 0.5, 0.12):
            return "trot"
        if 0.1 < ph["LF"] <= 0.4:
            return "walk"
        if 0.6 <= ph["LF"] < 0.9:
            return "walk-diagonal"
        return "unknown"
    # Asymmetric: leading limb of a pair is the one landing second.
    # A limb lands after its partner when it follows within half a stride (phases are cyclic).
    hind_lead = "RH" if ph["RH"] < 0.5 else "LH"
    fore_lead = "RF" if (ph["RF"] - ph["LF"]) % 1.0 < 0.5 else "LF"
    order = "transverse" if hind_lead[0] == fore_lead[0] else "rotary"
    beats = np.sort(np.array(list(ph.values())))
    gaps = np.diff(np.append(beats, beats[0] + 1.0))
    n_beats = int(np.sum(gaps > 0.06))
    return f"canter-{order}" if n_beats <= 3 else f"gallop-{order}"


def contacts_json(contacts: NDArray[np.bool_], fps: float) -> dict[str, object]:
    """The ``<clip>.contacts.json`` document: per foot, planted ``[start, stop)`` frame ranges."""
    return {"fps": fps, "frames": int(contacts.shape[0]), "range_convention": "[start, stop)",
            "feet": {foot: [list(r) for r in rs] for foot, rs in contacts_to_ranges(contacts).items()}}


def contacts_from_json(document: Mapping[str, object], n_frames: int) -> NDArray[np.bool_]:
    """Planted flags (F, 4) from a :func:`contacts_json` document; checks it fits the clip."""
    frames, feet = document.get("frames"), document.get("feet")
    if frames != n_frames:
        raise ValueError(f"contacts.frames: the document is for {frames} frames, the clip has {n_frames}")
    if not isinstance(feet, Mapping):
        raise ValueError("contacts.feet: expected an object mapping each foot to frame ranges")
    ranges = {str(foot): [(int(r[0]), int(r[1])) for r in rs] for foot, rs in feet.items()}
    return ranges_to_contacts(ranges, n_frames)
