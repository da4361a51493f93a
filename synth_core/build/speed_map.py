"""Speed maps (Sung 2011, section 3): one cyclic clip made into dozens of speeds, frame count fixed.

For each target speed ``s' = s + k * delta`` the source clip is changed in the paper's order:

1. **Root.** Every frame's ground displacement is scaled by ``l' / l`` (``l`` the root path
   length), so the path is ``l' = (s'/s) l`` long over the same frames; ``P'0(0) = P0(0)``;
   heights are kept.
2. **Foot plants.** Each plant moves from the source's average planted position ``P̄`` by a
   vector ``V`` along the stride of the same foot (the direction between its adjacent
   footprints), of magnitude ``d_c = |P'0(f_c) - P0(f_c)|`` at the plant's middle frame ``f_c``.
   The paper leaves V's sense implicit; we point it with the root's shift (back for slower
   speeds). The clip loops, so a plant running over the clip's end is one plant, and the
   footprint after the last is the first one a cycle on.
3. **IK** (:mod:`synth_core.build.ik`). The paper solves plant by plant in time order so the beat
   order holds; our targets for every frame are fixed before solving (each plant's, then the
   swings' between them), so all frames and all speeds are solved at once, and every foot is
   pinned to its new plant for the plant's whole duration (the contact annotation is the
   source's, unchanged: the footfall order cannot change). Between two plants the swinging
   foot follows its source path plus a correction blended from the previous plant's shift to
   the next one's - the paper is silent on swings. Along the ground the blend follows the
   source foot's own progress where the step shortens (:func:`swing_progress`: near the ground
   the foot then moves at the source's share of the body's speed), and time (smoothstep) where
   it lengthens (the extra ground is covered mid-swing, foot high); heights take the plants'
   offsets only near lift-off and touchdown, the source's lift and descent in between.

Speeds are in m/s here (the paper's ``s = l / n`` is per frame).

Beyond the paper: where a sped-up stride would straighten a leg past 98% of its reach (or past
the source's own straightest), the root sinks just enough, eased in and out over a quarter
cycle, as running animals do at full stride. Legs then never lock straight (where no hinge axis
is defined) and stretch only if a target is out of reach horizontally; the map records that.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from synth_core import UP_AXIS
from synth_core.build import ik
from synth_core.build.straight_crossings import solve_eased
from synth_core.motion.clip import Motion
from synth_core.motion.contacts import hold_down, runs
from synth_core.motion.skeleton import Skeleton

Floats = NDArray[np.float64]
DEFAULT_CLIPS = 60  # per gait: the paper builds "roughly around 60" (Table 1: 55)
_HORIZONTAL = [0, 2]


@dataclass(frozen=True)
class SpeedRange:
    """Speeds of one gait's map, m/s: ``count`` clips from ``low`` to ``high`` (delta apart)."""

    low: float
    high: float
    count: int = DEFAULT_CLIPS

    def __post_init__(self) -> None:
        if not (0 < self.low <= self.high and np.isfinite(self.high)):
            raise ValueError(f"speed range: need 0 < low <= high, got ({self.low}, {self.high})")
        if self.count < 2 and self.low != self.high:
            raise ValueError(f"speed range: count must be >= 2, got {self.count}")

    @property
    def delta(self) -> float:
        return (self.high - self.low) / max(self.count - 1, 1)

    def speeds(self) -> Floats:
        return np.linspace(self.low, self.high, self.count)


# Default range around each gait's source speed: down to half (the walk to 40%), up by 8%.
# Slowing a clip shortens its strides, which any leg can do; speeding it up lengthens them,
# which the legs' reach soon stops (the stretch figures say where).
SLOWEST, FASTEST, SLOWEST_WALK, OVERLAP = 0.5, 1.08, 0.4, 0.9


def default_ranges(source_speeds: Mapping[str, float], count: int = DEFAULT_CLIPS) -> dict[str, SpeedRange]:
    """Ranges for gaits given slow to fast; each starts low enough to overlap the one before."""
    ranges: dict[str, SpeedRange] = {}
    previous: SpeedRange | None = None
    for gait, speed in source_speeds.items():
        low = speed * (SLOWEST_WALK if previous is None else SLOWEST)
        if previous is not None:
            low = min(low, OVERLAP * previous.high)
        previous = ranges[gait] = SpeedRange(low, FASTEST * speed, count)
    return ranges


@dataclass(frozen=True, eq=False)
class SpeedMap:
    """One gait's clips at ``speeds``: same frames, same contacts as the source."""

    gait: str
    skeleton: Skeleton
    fps: float
    speeds: Floats  # (N,) m/s, ascending
    root_pos: NDArray[np.float32]  # (N, F, 3)
    rotations: NDArray[np.float32]  # (N, F, J, 4) local
    contacts: NDArray[np.bool_]  # (F, 4), shared by every clip
    stretch: NDArray[np.float32]  # (N, F, 4) limb length factor (1: no stretch)
    source_speed: float  # m/s

    @property
    def n_clips(self) -> int:
        return len(self.speeds)

    @property
    def n_frames(self) -> int:
        return int(self.rotations.shape[1])

    def clip(self, i: int) -> Motion:
        return Motion(self.skeleton, self.root_pos[i], self.rotations[i], self.fps, self.contacts,
                      f"{self.gait}_{self.speeds[i]:.2f}", self.gait)

    def bracket(self, speed: float) -> tuple[int, int, float]:
        """The two clips around ``speed`` and the blend weight of the second (clamped at the ends)."""
        s = self.speeds
        j = int(np.clip(np.searchsorted(s, speed), 1, len(s) - 1)) if len(s) > 1 else 0
        i = max(j - 1, 0)
        if i == j:
            return i, j, 0.0
        return i, j, float(np.clip((speed - s[i]) / (s[j] - s[i]), 0.0, 1.0))


def cycle_displacement(root_pos: NDArray[np.floating]) -> Floats:
    """Horizontal root advance over one loop of a cyclic clip, ``(..., F, 3) -> (..., 3)``: its
    mean step times its frames."""
    root = np.asarray(root_pos, dtype=np.float64)
    F = root.shape[-2]
    step = (root[..., -1, :] - root[..., 0, :]) / max(F - 1, 1)
    step[..., UP_AXIS] = 0.0
    return np.asarray(step * F)


def relocate_root(root_pos: NDArray[np.floating], ratio: Floats) -> Floats:
    """Step 1: every frame's ground displacement scaled by ``ratio (N,)``; (N, F, 3)."""
    root = np.asarray(root_pos, dtype=np.float64)
    steps = np.diff(root, axis=0)
    scaled = np.broadcast_to(steps, (len(ratio), *steps.shape)).copy()
    scaled[..., _HORIZONTAL] *= np.asarray(ratio)[:, None, None]
    start = np.broadcast_to(root[0], (len(ratio), 1, 3))
    return np.concatenate([start, start + np.cumsum(scaled, axis=1)], axis=1)


def _tile(x: Floats, shift: Floats, copies: int = 3) -> Floats:
    """A cyclic clip's (..., F, ...) frames repeated ``copies`` times, each copy ``shift`` further.

    ``x (N, F, ..., 3)`` and ``shift (N, 3)``; the middle copy is the original (for copies=3).
    """
    middle = copies // 2
    parts = [x + (k - middle) * shift.reshape(shift.shape[0], 1, *([1] * (x.ndim - 3)), 3)
             for k in range(copies)]
    return np.concatenate(parts, axis=1)


HEIGHT_EDGE = 0.3  # of a swing: its first and last such share carry the plants' height offsets
# A foot off its plant is this far above it through the first half of its swing (the strict
# plants of issue 27 are feet within 1 cm of the ground): the real dog's paw end sites stay within
# 1 cm for 2-3 frames after lift-off while the paw rolls forward 2-4 cm a frame, a drag the
# synthesis then shows on every stride (strict skate p95 12-35 mm in every real-dog scenario).
LIFT_CLEAR = 0.012  # m


def _smoothstep(x: Floats) -> Floats:
    x = np.clip(x, 0.0, 1.0)
    return np.asarray(x * x * (3 - 2 * x))


PROGRESS_STEP_M = 0.01, 0.03  # a source swing shorter than the first (m) is eased in time, longer
# than the second by its own progress, blended between


def swing_progress(feet: Floats, lo: NDArray[np.int64], hi: NDArray[np.int64],
                   t: NDArray[np.int64]) -> Floats:
    """How far each frame ``t`` is through its swing, 0 at lift-off (frame ``lo``: the plant's
    last) to 1 at touchdown (``hi``), as the source foot ``feet (N, T, 3)`` covers the ground
    between them (its horizontal progress along lo -> hi, never going back) -> ``(T,)``.

    A shortened swing's correction is blended by this, not by time: the new foot then covers
    each frame the source's share of the step, so its ground speed scales with the new step.
    Eased by time (smoothstep), a slowed stride kept the source's full ground speed while the foot is still
    low after lift-off and again before touchdown, where the smoothstep hardly moves: the real
    dog's slowest pace clips slid along the ground at 0.27 of the body's speed (its source,
    0.09). A source swing that hardly covers ground (a foot lifted in place) has no progress to
    read and keeps the smoothstep."""
    ground = np.asarray(feet[0], np.float64)[:, _HORIZONTAL]
    step = ground[hi] - ground[lo]
    length2 = np.sum(step * step, axis=-1)
    along = np.sum((ground[t] - ground[lo]) * step, axis=-1) / np.maximum(length2, 1e-12)
    along = np.where(t > lo, np.clip(along, 0.0, 1.0), 0.0)
    # Never back: a running max within each swing (swings are told apart by their lift-off).
    along = np.maximum.accumulate(along + 2.0 * lo) - 2.0 * lo
    along = np.clip(along, 0.0, 1.0)
    timed = _smoothstep((t - lo) / np.maximum(hi - lo, 1))
    a, b = PROGRESS_STEP_M
    trust = np.clip((np.sqrt(length2) - a) / (b - a), 0.0, 1.0)
    return np.asarray(trust * along + (1 - trust) * timed)


def _moved_plants(feet: Floats, plants: NDArray[np.int64], shift3: Floats, D: Floats) -> Floats:
    """Step 2 for one foot: each plant's place ``(N, P, 3)``, its source average moved by V (see
    :func:`_foot_track` for the arguments)."""
    start, stop = plants[:, 0], plants[:, 1]
    mid = (start + stop - 1) // 2
    average = np.stack([feet[:, a:b].mean(axis=1) for a, b in plants], axis=1)  # (N, P, 3)
    # V: along this foot's stride (to its next footprint; the last looks back), sense and
    # size from the root's shift at the plant's middle frame.
    footprints = average[0]  # the source's: the same for every speed
    if len(plants) > 1:
        ahead = np.diff(footprints, axis=0, append=2 * footprints[-1:] - footprints[-2:-1])
    else:  # one plant over all three loops: a foot that never lifts
        ahead = D[None]
    ahead[:, UP_AXIS] = 0.0
    direction = ahead / np.maximum(np.linalg.norm(ahead, axis=-1, keepdims=True), 1e-9)  # (P, 3)
    root_shift = shift3[:, mid]  # (N, P, 3)
    d_c = np.linalg.norm(root_shift[..., _HORIZONTAL], axis=-1)
    sense = np.sign(np.sum(root_shift * direction, axis=-1))
    return np.asarray(average + (sense * d_c)[..., None] * direction)


def _foot_track(feet: Floats, plants: NDArray[np.int64], shift3: Floats, D: Floats,
                t: NDArray[np.int64], alone: NDArray[np.bool_], stand: Floats | None = None) -> Floats:
    """One foot's targets (N, 3F, 3) over the three loops: each plant (``plants`` (P, 2), its
    ``[start, stop)``) moved along the stride by the root's shift, the swings corrected between.
    ``feet (N, 3F, 3)``: the source foot's positions, ``shift3 (N, 3F, 3)`` the root's shift,
    ``D`` the source's cycle displacement; ``alone (3F,)``: where lifting this foot leaves one foot
    down (no lift clearance there: see :func:`_lift_clear`); ``stand (3F,)``: the height each
    frame's plant stands at (None: its source average's)."""
    start, stop = plants[:, 0], plants[:, 1]
    plant = _moved_plants(feet, plants, shift3, D)
    if stand is not None:
        plant[..., UP_AXIS] = stand[(start + stop - 1) // 2]
    # The swing's correction runs from where the foot left its last plant to where it meets
    # the next one (a foot sliding or settling in its source plant would otherwise jump at
    # lift-off and drop at touchdown: the real dog's paws by 1-5 cm in a frame).
    lift_off = plant - feet[:, stop - 1]  # (N, P, 3)
    touch_down = plant - feet[:, start]
    # Per frame: the plant it is in, or the plants either side of its swing. A clip that does
    # not loop (a transition) has a swing before its first plant and one after its last, each
    # with one plant only: ``before`` heads for the first, ``after`` leaves the last.
    k = np.searchsorted(start, t, side="right") - 1
    prev = np.clip(k, 0, len(plants) - 1)
    nxt = np.where(k < 0, 0, np.clip(k + 1, 0, len(plants) - 1))
    before, after = k < 0, (k == len(plants) - 1) & (t >= stop[-1])
    inside = (t >= start[prev]) & (t < stop[prev])
    lo, hi = stop[prev] - 1, start[nxt]
    # A shortened step is eased by the source's progress (its ground speed scaled down
    # evenly); a lengthened one in time, the extra ground covered mid-swing, foot high.
    shorter = (np.linalg.norm((plant[:, nxt] - plant[:, prev])[..., _HORIZONTAL], axis=-1)
               < np.linalg.norm((feet[:, hi] - feet[:, lo])[..., _HORIZONTAL], axis=-1))
    u = np.where(shorter, swing_progress(feet, lo, hi, t)[None],
                 _smoothstep((t - lo) / np.maximum(hi - lo, 1))[None])
    u = np.where(before, 1.0, np.where(after, 0.0, u))  # heading for the first plant, leaving the last
    blend = (1 - u)[..., None] * lift_off[:, prev] + u[..., None] * touch_down[:, nxt]
    # Heights: the plant's offset fades out soon after lift-off and in just before touchdown,
    # the source's own lift and descent in between. A mocap paw's end site rises 0.5-2 cm as
    # it rolls through late stance; pinned at the plant's average, the whole swing sank by
    # that much and skimmed the ground (the real dog's hind paws came in 1 cm lower).
    # (From the swing's first frame to its last: each rises from, and lands on, its plant
    # as the source's does, so touchdowns drop no further than the source's.)
    s = np.clip((t - lo - 1) / np.maximum(hi - lo - 2, 1), 0.0, 1.0)
    w_lo = 1.0 - _smoothstep(s / HEIGHT_EDGE)
    w_hi = _smoothstep((s - 1.0 + HEIGHT_EDGE) / HEIGHT_EDGE)
    w_lo = np.where(before, 0.0, np.where(after, 1.0, w_lo))
    w_hi = np.where(before, 1.0, np.where(after, 0.0, w_hi))
    blend[..., UP_AXIS] = (w_lo[None] * lift_off[:, prev, UP_AXIS]
                           + w_hi[None] * touch_down[:, nxt, UP_AXIS])
    swing = feet + blend
    swing[..., UP_AXIS] = _lift_clear(swing[..., UP_AXIS], plant[:, prev, UP_AXIS], t, lo, hi,
                                      (t >= start[0]) & ~alone)
    track = np.where(inside[None, :, None], plant[:, prev], swing)
    track = _touch_clear(track, plant[:, nxt, UP_AXIS], t, lo, hi, t >= start[0])
    return _ends_clear(track, plant[:, prev, UP_AXIS], before | after)


def _lift_clear(height: Floats, plant: Floats, t: NDArray[np.int64], lo: NDArray[np.int64],
                hi: NDArray[np.int64], may: NDArray[np.bool_]) -> Floats:
    """Swing heights ``(N, T)`` at least ``LIFT_CLEAR`` over the plant left (``plant (N, T)``)
    through the first half of each swing (``lo``, ``hi``: its plants' last and first frames),
    where ``may``. Not where the foot lifting leaves one foot alone carrying the body: the real
    dog's pace hands over from one lateral pair to the next with the lifting paw still low, and
    cleared, its walk had one paw down for 2-3 frames each half stride."""
    return _over_plant(height, plant, (t > lo) & (t - lo <= 0.5 * (hi - lo)) & may)


def _over_plant(height: Floats, plant: Floats, where: NDArray[np.bool_]) -> Floats:
    """``height (N, T)`` at least ``LIFT_CLEAR`` over ``plant (N, T)`` on the frames ``where``."""
    return np.asarray(np.where(where, np.maximum(height, plant + LIFT_CLEAR), height))


TOUCH_STEP = 0.002  # m a frame: a paw moving further over the ground than this is not standing


def _touch_clear(track: Floats, plant: Floats, t: NDArray[np.int64], lo: NDArray[np.int64],
                 hi: NDArray[np.int64], may: NDArray[np.bool_]) -> Floats:
    """A foot's ``track (N, T, 3)`` landing from above: through the second half of each swing,
    where ``may`` and the foot still moves over the ground more than :data:`TOUCH_STEP` to its
    next frame, at least ``LIFT_CLEAR`` over the plant it goes to (``plant (N, T)``), where ``may``
    (every swing after the clip's first plant). Every gait's: a landing paw that is the second
    support was once left low (the pace's handover, before the walk kept two down); in the
    trot and on slopes it then slid in along the ground (strict skate uturn_trot 7.2 -> 3.1 mm).

    The real dog's paw sweeps in low before touchdown (at a gallop 3-4 cm a frame within 1 cm of
    its plant, some at the plant's height a frame before it is planted): played as is, every
    stride dragged a paw along the ground for a frame or two (issue 27's strict plant skate: the
    speed-map clips' p95 3-31 mm). Landing from ``LIFT_CLEAR`` drops less in the last frame than
    the source's largest (1.6-4.6 cm, issue 28)."""
    ground = track[..., _HORIZONTAL]
    step = np.linalg.norm(np.diff(ground, axis=1, append=ground[:, -1:]), axis=-1)
    late = (t < hi) & (t - lo > 0.5 * (hi - lo)) & may & (step > TOUCH_STEP)
    out = np.array(track)
    out[..., UP_AXIS] = _over_plant(out[..., UP_AXIS], plant, late)
    return out


def _ends_clear(track: Floats, plant: Floats, ends: NDArray[np.bool_]) -> Floats:
    """A clip's swings before its first plant and after its last (``ends``: a transition's;
    ``plant (N, T)`` the one plant each has) kept :data:`LIFT_CLEAR` over that plant where the
    foot moves over the ground more than :data:`TOUCH_STEP`. The rules above clear a swing
    between two plants; these, cut by the clip's ends, were left as the mocap had them: the real
    dog's paw in walk2trot lifted 6-9 mm off its last plant while moving 3-5 cm a frame, and
    static2walk's last swings skimmed at 1-4 mm into the walk, the strict plants of issue 27
    sliding 2-9 cm a frame (the edge suite's cruise_straight, 10 mm p95)."""
    ground = track[..., _HORIZONTAL]
    step = np.linalg.norm(np.diff(ground, axis=1, append=ground[:, -1:]), axis=-1)
    out = np.array(track)
    out[..., UP_AXIS] = _over_plant(out[..., UP_AXIS], plant, ends & (step > TOUCH_STEP))
    return out


def foot_targets(source_feet: NDArray[np.floating], source_root: NDArray[np.floating],
                 new_root: Floats, contacts: NDArray[np.bool_], cyclic: bool = True,
                 stand: Floats | None = None) -> Floats:
    """Steps 2 and the swing rule: toe targets (N, F, 4, 3) for every frame of every speed.

    ``cyclic=False`` treats the clip as one piece (plants at its ends are cut there): with
    ``new_root`` the source root, that pins each plant at its average place (a foot lock).
    ``stand (F, 4)``: the height each foot's plant on each frame stands at instead (a plant
    takes its middle frame's), else its source average's.
    """
    feet = np.asarray(source_feet, dtype=np.float64)
    root = np.asarray(source_root, dtype=np.float64)
    N, F = new_root.shape[:2]
    copies = 3 if cyclic else 1
    D = cycle_displacement(root) if cyclic else np.zeros(3)
    D_new = cycle_displacement(new_root) if cyclic else np.zeros((N, 3))
    # Three loops back to back: plants over the clip's ends are whole, neighbours exist.
    feet3 = _tile(np.broadcast_to(feet, (N, *feet.shape)), np.broadcast_to(D, (N, 3)), copies)
    shift3 = _tile(new_root, D_new, copies) - _tile(np.broadcast_to(root, (N, F, 3)),
                                                    np.broadcast_to(D, (N, 3)), copies)
    contacts3 = np.tile(contacts, (copies, 1))
    stand3 = None if stand is None else np.tile(np.asarray(stand, np.float64), (copies, 1))
    targets = feet3.copy()
    t = np.arange(copies * F)
    for k in range(contacts.shape[1]):
        plants = runs(contacts3[:, k])
        if len(plants) == 0:
            continue
        alone = contacts3.sum(axis=1) - contacts3[:, k] == 1
        targets[:, :, k] = _foot_track(feet3[:, :, k], plants, shift3, D, t, alone,
                                       None if stand3 is None else stand3[:, k])
    first = F * (copies // 2)
    return np.asarray(targets[:, first:first + F])


REACH_EASE = 0.25  # of the cycle: a sink is spread over this much around where it is needed
STRAIGHT = 0.98, 0.999  # legs may straighten to 98% of their reach (more if the source does), never 100%


def reach_limit(source: Motion, rigs: tuple[ik.LimbRig, ...] | None) -> Floats:
    """(4,) how straight each leg may be: ``STRAIGHT``, or the source's own straightest."""
    source_max = ik.extension(source.skeleton, source.root_pos, source.rotations, rigs).max(axis=0)
    return np.asarray(np.clip(source_max, *STRAIGHT))


def sink_for_reach(source: Motion, new_root: Floats, rotations: NDArray[np.floating], targets: Floats,
                   rigs: tuple[ik.LimbRig, ...] | None, ease: int | None = None,
                   most: float | None = None) -> Floats:
    """Lower the root where a relocated plant would straighten a leg beyond ``STRAIGHT`` (sped-up
    strides reach further fore and aft), eased in and out around the loop: no leg stretches,
    no leg locks fully straight (where the hinge axis is undefined), the body does not bob.

    ``ease``: frames to spread a sink over in a clip that does not loop (default: a cyclic clip,
    ``REACH_EASE`` of it, around the loop). ``most``: the deepest sink (m; default: none)."""
    limit = reach_limit(source, rigs)
    sink = ik.sink_to_reach(source.skeleton, new_root, rotations, targets, limit, rigs)
    if most is not None:
        sink = np.minimum(sink, most)
    frames = max(3, round(REACH_EASE * sink.shape[-1]) if ease is None else ease)
    mode = "wrap" if ease is None else "nearest"
    sink = gaussian_filter1d(maximum_filter1d(sink, frames, axis=-1, mode=mode),
                             frames / 6, axis=-1, mode=mode)  # keeps >99% of a peak
    lowered = new_root.copy()
    lowered[..., UP_AXIS] -= sink
    return lowered


# Feet a gait keeps down in every frame: a walk always has two (issue 27), where its source hands
# over with one (the real dog's pace: :func:`synth_core.motion.contacts.hold_down`).
LEAST_DOWN = {"walk": 2}


def held_feet(feet: NDArray[np.floating], contacts: NDArray[np.bool_], held: NDArray[np.bool_],
              advance: Floats | None = None) -> Floats:
    """``feet (F, K, 3)`` where ``held`` extends plants of ``contacts``: each held frame at its
    plant's last frame (the foot stays where it stood), and the swing after it the source's,
    catching up from the plant over as many frames as the foot was held. Starting where the
    source was, 1-4 frames into its swing, the real dog's held hind paw jumped off (2.7 cm a
    frame^2 at the walk's loop, paw jumps 9.9 -> 11.6 cm in the scaled herd, trot2walk's wrists
    flipped); played from the plant to the touchdown slower, the leg reached 2 % further back.
    ``advance``: a cyclic clip's cycle displacement (None: the clip does not loop)."""
    cyclic = advance is not None
    copies = 3 if cyclic else 1
    shift = np.zeros(3) if advance is None else np.asarray(advance, np.float64)
    F = len(feet)
    tiled = np.concatenate([np.asarray(feet, np.float64) + (c - copies // 2) * shift
                            for c in range(copies)])  # (copies F, K, 3), a loop each
    out = tiled.copy()
    for k in np.flatnonzero((held & ~contacts).any(axis=0)):
        down, kept = np.tile(held[:, k], copies), np.tile(contacts[:, k], copies)
        plants = runs(down)
        for (a, b), nxt in zip(plants, np.append(plants[1:, 0], -1), strict=True):
            lifted = a + int(np.flatnonzero(kept[a:b]).max()) + 1  # the source's lift-off
            out[lifted:b, k] = tiled[lifted - 1, k]
            if lifted == b or nxt < 0:  # not held, or no touchdown after it in the clip
                continue
            # The swing catches up with the source's over as many frames as it was held.
            u = np.arange(b, min(b + (b - lifted), nxt))
            lag = _smoothstep(1.0 - (u - b + 1) / (b - lifted + 1))
            out[u, k] += lag[:, None] * (tiled[lifted - 1, k] - tiled[b - 1, k])
    first = F * (copies // 2)
    return np.asarray(out[first:first + F])


def build_speed_map(source: Motion, speeds: Sequence[float] | Floats,
                    rigs: tuple[ik.LimbRig, ...] | None = None) -> SpeedMap:
    """A cyclic clip (with its contact annotation) at every speed in ``speeds`` (m/s)."""
    speeds = np.sort(np.asarray(speeds, dtype=np.float64))
    if source.speed_mps() <= 1e-6:
        raise ValueError(f"{source.name}: the clip does not move; a speed map needs a moving cycle")
    if not source.contacts.any(axis=0).all():
        raise ValueError(f"{source.name}: every foot must be planted somewhere in the cycle")
    ratio = speeds / source.speed_mps()
    new_root = relocate_root(source.root_pos, ratio)
    contacts = hold_down(source.contacts, LEAST_DOWN.get(source.gait or "", 0))
    feet = held_feet(source.foot_positions(), source.contacts, contacts,
                     cycle_displacement(source.root_pos))
    source = source.with_contacts(contacts)
    targets = foot_targets(feet, source.root_pos, new_root, contacts)
    ground = float(source.foot_positions()[..., UP_AXIS].min())
    rotations = np.broadcast_to(source.rotations, (len(speeds), *source.rotations.shape))
    # Each frame's hinge side from the source's own pose, kept continuous around the loop.
    rigs = ik.limb_rigs(source.skeleton) if rigs is None else rigs
    axes = ik.hinge_axes_over_time(source.skeleton, source.rotations, rigs, cyclic=True)

    def place(pose: NDArray[np.floating]) -> tuple[NDArray[np.floating], NDArray[np.floating]]:
        return sink_for_reach(source, new_root, pose, targets, rigs), targets

    # The paws' ankles through straight no faster than a stride rate can play them (issue 28).
    solved, result, sunk = solve_eased(source.skeleton, rotations, place, rigs, ground, axes, cyclic=True,
                                       contacts=source.contacts)
    return SpeedMap(source.gait or source.name, source.skeleton, source.fps, speeds,
                    sunk.astype(np.float32), solved, source.contacts.copy(),
                    result.stretch.astype(np.float32), source.speed_mps())
