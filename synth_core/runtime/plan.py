"""The plan (Sung 2011, section 6, steps 1-2): which clips every frame of every character blends.

One planner serves the batch and the live mode. Its design:

- **One state machine, written once** (:mod:`synth_core.compiled.plan_kernels`): each character's
  plan is stepped frame by frame -- transition ends, gait decisions, transition entries, the
  frame's table rows, the stride clocks -- carrying a small state (:class:`Planner`).
- **The batch plan is the live plan run over the whole trajectory**: :func:`plan` makes a
  :class:`Planner` and advances it over every frame in one call; a live session
  (:mod:`synth_core.runtime.live`) advances its own block by block as points arrive. Same code,
  same state, so live frames are the batch's by construction; what differs is only the input
  (the batch knows the whole path: its end, and where a standing character will first go).
- **One source, two backends**: numba compiles the machine, and the interpreter runs the same
  source as the reference (:func:`synth_core.compiled.jit.interpreted`), behind one interface
  (:class:`synth_core.compiled.plan_kernels.Kernels`) that
  :func:`synth_core.compiled.backend.planner` picks from a backend name.
- Around it, in numpy: the library's tables (:func:`tables`), each frame's speed
  (:func:`frame_speeds`) and each decision's random draws (:mod:`synth_core.runtime.draws`).

The rules the machine follows. Every character starts standing and moves through the motion graph
one hub at a time. A segment's speed ``s / (h k)`` (scale h, stride tempo k) picks the gait: the
current one while its range covers the speed (hysteresis), else one of the gaits covering it -- at
random where ranges overlap -- reached one transition per step; gaits are chosen ``DECISION_SHARE``
times a segment on the speed ``LOOKAHEAD`` segments ahead, as transitions take time. A transition
starts when the stride reaches the phase the clip starts from and plays by distance; the next gait
picks up at the phase the transition ends in, so the footfall sequence carries on across it. Within
a gait every speed-map clip has the same frames and contacts, so the stride phase runs on (k clip
frames per output frame; above its fastest clip, the fastest gait up to ``MAX_RATE`` faster, a
slower one waiting for its transition as fast as the path; down to ``STAND_SHARE`` below the
slowest gait's slowest) and the speed only moves the pair of clips blended, ``M = (1 - a) M_i + a
M_j``. Where a piece starts, the piece before it fades out over ``margin`` frames; where it starts
within the margin of the one before's start, what fades out is the blend shown (the one before over
the one before that, each by its nearer row), so no piece vanishes in one frame (issue 27: 25-38 cm
hoof jumps between two transitions). A character whose path stops (its segment's speed or, in a
batch, the distance it walks a frame -- not a walk's, which slows with it -- slower than a standing
one's, or still for ``STILL_S``) stands at once: the idle fades in over the margin, from whatever
gait or transition played (issue 27: transitions play by distance, so the chain trot -> walk ->
static on a stopped path took hundreds of frames, the animal frozen mid-stride); it leaves standing
by the static -> walk transition, as from the start, once its path moves (chosen on the speed
ahead, the transition crept on the spot with a hoof up for as long as the path still stood). A
transition on a path braking to a crawl -- no stop, or one shorter than the segments see -- is
shown slower and slower: under ``MIN_TRANSITION_RATE`` of its pace (read from the distance walked,
which it plays by) it gives way to the gait the crawl is in the same way, at its nearest frame (a
horse stood on one foreleg 1.5 s inside canter -> trot).

The heading follows the path's direction (:class:`Headings`) where it moves (a slow path only
while it drags an anchor ``HOLD_RADIUS`` behind it: a simulator's jitter round a standing agent
does not turn it), turning no faster than ``MAX_YAW_RATE``, and at speed than ``MAX_LATERAL / v``:
the root stays on the path, the body lags where the path turns faster.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from synth_core.compiled import plan_kernels as pk
from synth_core.compiled.backend import planner
from synth_core.compiled.heading_kernels import CHORD_FRAMES
from synth_core.runtime.bank import Bank, nearest_poses, turn_lever
from synth_core.runtime.draws import LEAD_STREAM, SCHEDULE_STREAM, uniform, uniform_streams
from synth_core.runtime.trajectory import GROUND_AXES, Prepared

Floats = NDArray[np.float64]
MARGIN = 10  # frames over which a finished piece fades out where the next starts
N_HUBS = 5  # static, walk, trot, canter, gallop
# Below its slowest clip's speed the slowest gait plays that clip's stride slower (its feet keep
# pace with a slow path, as an animal creeping walks with long stances), down to this share of
# its pace; slower still, a character stands. (At 0.5, with the stride at full pace, creeping
# horses stood while their root crept on over the pinned hooves, which lifted 25 cm; at 0.08 a
# horse at 0.05 m/s stood for 12 s while its root slid 57 cm on over its hooves: the edge suite's
# stand_drift. The root stays on the path, so only a stride kept in pace with it keeps the feet.)
STAND_SHARE = 0.05
# A path whose every step for this long is slower than a standing character's (STAND_SHARE of the
# slowest clip) has stopped: the character settles into the idle at once (see plan_kernels). The
# segment speeds alone see a stop a segment late; longer than a 10 Hz simulator's tick (0.1 s),
# or its held points would read as stops.
STILL_S = 0.2
# A transition (not a start, nor one to standing) shown slower than this share of its pace --
# played by distance on a path braking to a crawl -- gives way at once to the gait the path is
# in, from the frame it shows, as a stop settles (plan_kernels._give_way). At a tenth of its pace
# a dog's trot -> walk crept on 4 s into a crawl. At 0.5 the standard herd's ordinary slowing
# gave way too, each a fade between two poses (its pops 1.39 -> 1.58 of a frame's own; a
# real-dog herd's paw jumped 6.2 cm): at 0.35 only crawls do.
MIN_TRANSITION_RATE = 0.35
MIN_TURN_SPEED = 0.05  # m/s: slower than this the heading holds (a standing animal does not spin)
# ... and slower than FREE_TURN_SPEED it holds unless the path drags an anchor HOLD_RADIUS (metres)
# behind it, the anchor drawn toward the path at HOLD_PULL (m/s), or leaves a stop (STILL_S still):
# a 10 Hz simulator's 2 cm jitter, smoothed, moves 0.3-0.4 m/s back and forth round a standing
# agent, and the body swung after it at the yaw rate's limit, its planted feet carried 50-79 cm
# (edge suite, jitter_10hz: a standing horse turned 121 -> 162 -> 3 deg in 70 frames).
FREE_TURN_SPEED = 1.5
START_TURN_SPEED = 0.5  # ... and a path this fast at its first point starts as from a stop
HOLD_RADIUS = 0.05
HOLD_PULL = 0.04
# The body turns toward the path's heading at most MAX_YAW_RATE (pivoting, and at a walk: a horse
# turns on its haunches through 180 deg in about a second, quicker when hurried) and, faster,
# no faster than MAX_LATERAL allows (v omega, the grip's lateral acceleration: 2.5 g, between a
# horse's and a greyhound's hardest turns) -- 270 deg/s up to 5 m/s, 175 deg/s at 8 m/s. The
# root stays on the path; where it turns faster the body lags (issue 27: it swung round at up to
# 10,000 deg/s, the whole body in one frame as a standing animal moved off in a new direction).
MAX_YAW_RATE = float(np.radians(270.0))  # rad/s
MAX_LATERAL = 2.5 * 9.81  # m/s^2
# Turning, the body leans into the turn: rolled by atan(v omega / g) (the centripetal acceleration
# over gravity, as a runner or a bike leans), at most MAX_LEAN (a galloping horse's tightest turns
# lean about 20 deg), reached at most LEAN_RATE (a body rolls over in a few strides, not a frame).
# Gentle curves lean none: the lean is atan(v omega / g) less GENTLE_LEAN (so it grows from 0 as a
# turn tightens; a herd's meandering paths leant a degree, which changed nothing a viewer sees
# but the plants' IK).
MAX_LEAN = float(np.radians(20.0))  # rad
LEAN_RATE = float(np.radians(90.0))  # rad/s
GENTLE_LEAN = float(np.radians(3.0))  # rad
# A clip's surge goes along the path the root follows (heading_kernels.turn's ``way``), but a path
# slower than this has no way of its own worth reading (standing: none; creeping: its noise): its
# way is topped up along the heading.
WAY_SPEED = 0.06  # m/s
# A walk's stride quickens with the body's turn (plan_kernels._turning). The low-latency mode reads
# the turn averaged over TURN_S (a first-order low-pass of the turn a frame): its causal fit of a
# 10 Hz simulator's held points swings the body +-11 deg at the hold's rate, and a walk read from
# each frame's turn hurried and slowed with it (jitter_10hz: a hoof's jump 7.8 -> 11.9 cm). The
# batch reads each frame's: averaged over 0.1 s, the turn came late for the horse's walking
# U-turns, a hoof hanging alone at their start. Nor does it read a transition's pace from the
# distance walked a frame, as the batch does (plan_kernels.BY_STEP), but from the speed: its fit
# walks nothing on five frames of a held tick's six, and a trot's walk -> trot read as stalled there
# gave way to the walk (the dog's jitter_10hz with the simulator's velocity: trotting 23% of the
# time, not 95%); averaged over 0.2 s, the distance lagged a brake and a real dog's canter ->
# trot stood over its flight, every paw 7-20 cm up for 15 frames (accel_brake).
TURN_S = 0.2  # s
LOOKAHEAD = 2  # segments: gaits are chosen on the speed this far ahead, as transitions take time
DECISION_SHARE = 4  # gait decisions this many times a segment
MAX_RATE = 1.6  # the fastest gait asked to go faster than its fastest clip plays its stride up to this fast


@dataclass(frozen=True, eq=False)
class Plan:
    """What every (character, frame) shows, before any pose is built: table rows and weights.

    ``rows (C, T, 4)``: the two clip rows blended of the piece playing, then the two of the piece
    fading out (the same rows where none is); ``weights (C, T, 3)``: the second row's weight of
    each pair, then the fading piece's share (0: no fade). The pose is
    ``blend(blend(r0, r1, w), blend(p0, p1, pw), keep)`` -- nlerps -- turned to ``yaw`` and put on
    ``path`` (the clip's surge along ``way``); :func:`synth_core.runtime.synthesis.render` builds
    it (numpy) and :mod:`synth_core.compiled.kernels` (numba) too.
    """

    rows: NDArray[np.int32]
    weights: NDArray[np.float32]
    yaw: Floats  # (C, T) heading, radians about +Y, 0 = +Z
    path: Floats  # (C, T, 3) the path followed: the points sent, their timing smoothed
    scales: Floats  # (C,)
    contacts: NDArray[np.bool_]  # (C, T, 4)
    stitches: NDArray[np.bool_]  # (C, T)
    gait: NDArray[np.int8]  # (C, T)
    lean: Floats  # (C, T) roll into the turn, radians about the body's forward axis (+: top to its right)
    way: Floats  # (C, T, 2) the ground direction (x, z) of the root's path, its surge's: unit, but
    # shorter where a path creeping under WAY_SPEED steps against the heading (heading_kernels.turn)

    def window(self, start: int, stop: int, step: int = 1) -> Plan:
        """Frames ``[start, stop)`` (every ``step``-th) of every character."""
        t = slice(start, stop, step)
        return Plan(self.rows[:, t], self.weights[:, t], self.yaw[:, t], self.path[:, t], self.scales,
                    self.contacts[:, t], self.stitches[:, t], self.gait[:, t], self.lean[:, t],
                    self.way[:, t])


def empty_plan(characters: int, frames: int, scales: Floats) -> Plan:
    """A plan's arrays for ``frames`` frames, to be filled."""
    C, T = characters, frames
    return Plan(np.empty((C, T, 4), np.int32), np.empty((C, T, 3), np.float32), np.empty((C, T)),
                np.empty((C, T, 3)), scales, np.empty((C, T, 4), bool), np.empty((C, T), bool),
                np.empty((C, T), np.int8), np.empty((C, T)), np.empty((C, T, 2)))


@dataclass(frozen=True)
class Tables:
    """What the planner reads of a library: per piece kind (hubs 0-4, then the transitions) its
    place in the bank's table and its curve, per pair of hubs their transition, and the scalars."""

    offset: NDArray[np.int64]  # first table row
    frames: NDArray[np.int64]
    clips: NDArray[np.int64]
    cyclic: NDArray[np.bool_]  # a gait (a hub), not a transition
    source: NDArray[np.int64]  # hub left (a hub: itself)
    target: NDArray[np.int64]  # hub reached (a hub: itself)
    tr_kind: NDArray[np.int64]  # (5, 5) kind of the transition between two hubs, -1 none
    entry: NDArray[np.int64]  # (5, 5) its first clip frame's phase in the gait left
    exit: NDArray[np.int64]  # (5, 5) its last's in the gait reached
    total: Floats  # a transition's distance (0: a gait)
    low: Floats  # per hub: lowest speed it covers (inf: none; see coverage)
    high: Floats  # per hub: highest speed it covers (-inf: none)
    curve_at: NDArray[np.int64]  # (kinds, 2): where a kind's curve sits in ``curves``, its length
    curves: Floats  # hubs: clip speeds; transitions: their frames' progress (distance)
    contacts: NDArray[np.bool_]  # (rows, 4) the bank's
    resume: NDArray[np.int64]  # (rows, 5): a transition row's nearest frame of each gait (give_way_phases)
    slowest: int  # slowest and fastest hub with clips
    fastest: int
    slow: float  # the slowest gait's slowest clip speed (it plays slower below)
    creep: float  # the bank's
    still_step: float  # m per frame (the library's): a path's step slower than this stands still
    still_frames: float  # frames of such steps that make a stop
    fps: float  # the library's
    lever: float  # how far a turn sweeps the feet (bank.turn_lever)
    quick: float  # the speed a turn may quicken the slowest gait's stride to (turn_speed)

    def args(self) -> tuple[Any, ...]:
        """The kernel's arguments from ``offset`` to ``quick`` (see plan_kernels.advance)."""
        return (self.offset, self.frames, self.clips, self.cyclic, self.source, self.target, self.tr_kind,
                self.entry, self.exit, self.total, self.low, self.high, self.curve_at, self.curves,
                self.contacts, self.resume, self.slowest, self.fastest, MAX_RATE, self.slow, STAND_SHARE,
                self.still_step, self.still_frames, self.fps, MIN_TRANSITION_RATE, self.lever, self.quick)


@functools.lru_cache(maxsize=8)  # per bank (identity): made once, not per plan
def tables(bank: Bank) -> Tables:
    """The planner's :class:`Tables` of ``bank``."""
    pieces = [bank.gaits.get(h, bank.idle) if h else bank.idle for h in range(N_HUBS)]
    trs = sorted(bank.transitions.items())
    pieces += [p for _, p in trs]
    tr_kind = np.full((N_HUBS, N_HUBS), -1)
    entry = np.zeros((N_HUBS, N_HUBS), np.int64)
    exit_ = np.zeros((N_HUBS, N_HUBS), np.int64)
    for k, ((a, b), p) in enumerate(trs):
        tr_kind[a, b], entry[a, b], exit_[a, b] = N_HUBS + k, p.entry, p.exit
    total = np.zeros(len(pieces))
    curve_at = np.zeros((len(pieces), 2), np.int64)
    curves: list[Floats] = []
    kind_curves = [*bank.speeds.items(), *((int(tr_kind[a, b]), d) for (a, b), d in bank.progress.items())]
    for kind, curve in kind_curves:
        curve_at[kind] = sum(len(c) for c in curves), len(curve)
        curves.append(np.asarray(curve, np.float64))
        total[kind] = 0.0 if kind < N_HUBS else curve[-1]
    low, high = coverage(bank)
    slow = clip_range(bank, min(bank.speeds))[0]
    return Tables(np.array([p.offset for p in pieces]), np.array([p.frames for p in pieces]),
                  np.array([p.clips for p in pieces]), np.array([True] * N_HUBS + [False] * len(trs)),
                  np.array(list(range(N_HUBS)) + [a for (a, _), _ in trs]),
                  np.array(list(range(N_HUBS)) + [b for (_, b), _ in trs]), tr_kind, entry, exit_, total,
                  low, high, curve_at, np.concatenate(curves) if curves else np.zeros(0), bank.contacts,
                  give_way_phases(bank),
                  min(bank.speeds), max(bank.speeds), slow, bank.creep, STAND_SHARE * slow / bank.fps,
                  float(round(STILL_S * bank.fps)), float(bank.fps), turn_lever(bank),
                  turn_speed(bank))


def turn_speed(bank: Bank) -> float:
    """The speed a turn may quicken the slowest gait's stride clock to (plan_kernels._turning): its
    fastest clip's times its cycle over the library's shortest -- as quick as the quickest stride (a
    horse's walk twice as quick). No other gait quickens: the body's turn sweeps the forehand round
    the hips, and a trot quickened so in a 0.5 m U-turn swung a forefoot 40 cm a frame (low-latency
    horse, uturn_trot)."""
    walk = min(bank.gaits)
    return float(bank.speeds[walk][-1]) * bank.gaits[walk].frames / min(p.frames for p in bank.gaits.values())


def give_way_phases(bank: Bank) -> NDArray[np.int64]:
    """``(rows, N_HUBS)``: for each transition row of the table (before the mirror rows; others
    0), the clip frame of each gait's middle clip a stalled transition gives way to there
    (plan_kernels._give_way): its feet down agreeing first, then its pose nearest -- as a
    transition's entry and exit are found (``bank.nearest_poses``). By contacts alone the walk
    picked was a stride away in pose: the standard herd's pops 1.39 -> 1.82 of a frame's own."""
    out = np.zeros((len(bank.poses), N_HUBS), np.int64)
    if not bank.transitions:
        return out
    tr = np.concatenate([np.arange(p.offset, p.offset + p.frames) for p in bank.transitions.values()])
    tr = tr[tr < (bank.mirror or len(bank.poses))]
    for hub, g in bank.gaits.items():
        rows = slice(g.offset + (g.clips // 2) * g.frames, g.offset + (g.clips // 2 + 1) * g.frames)
        out[tr, hub] = nearest_poses(bank.poses[rows], bank.contacts[rows], bank.poses[tr], bank.contacts[tr])
    return out


def coverage(bank: Bank) -> tuple[Floats, Floats]:
    """Per hub, the lowest and highest speed it covers (inf, -inf: none). The slowest gait
    covers down to STAND_SHARE of its slowest clip (played slower); below that a character stands."""
    low = np.full(N_HUBS, np.inf)
    high = np.full(N_HUBS, -np.inf)
    for h, s in bank.speeds.items():
        low[h], high[h] = s[0], s[-1]
    slowest = min(bank.speeds)
    low[slowest] = STAND_SHARE * low[slowest]
    return low, high


def clip_range(bank: Bank, hub: int) -> tuple[float, float]:
    """A hub's (slowest, fastest) clip speed as its stride clock reads them: the slowest gait
    plays slower below its slowest clip; others never (slowest 0)."""
    s = bank.speeds[hub]
    return (float(s[0]) if hub == min(bank.speeds) else 0.0), float(s[-1])


def decision_step(m: int) -> int:
    """Frames between gait decisions."""
    return max(1, m // DECISION_SHARE)


def lookahead(m: int) -> int:
    """Frames from a gait decision to the speed it reads."""
    return int(LOOKAHEAD * m)


def frame_speeds(speeds: Floats, m: int, T: int) -> Floats:
    """(C, T): segment speeds interpolated linearly between segment centres."""
    K = speeds.shape[1]
    pos = (np.arange(T) - (m - 1) / 2) / m
    k0 = np.clip(np.floor(pos).astype(np.int64), 0, K - 1)
    k1 = np.minimum(k0 + 1, K - 1)
    f = np.clip(pos - k0, 0.0, 1.0)
    return np.asarray(speeds[:, k0] * (1 - f) + speeds[:, k1] * f)


@dataclass(frozen=True)
class Decisions:
    """Gait decisions ``first, first + 1, ...`` (decision k at frame ``k * step``): the speed each
    reads ``(C, K)`` and its draws ``(C, K, N_HUBS)``."""

    first: int
    speed: Floats
    draws: Floats


class Headings:
    """The headings of ``characters`` characters, frame block by frame block: the heading held
    and whether each has moved yet, carried between blocks."""

    def __init__(self, characters: int, backend: str = "auto", chord_frames: int = CHORD_FRAMES) -> None:
        self.kernels = planner(backend)
        self.chord_frames = chord_frames  # the path's way read across so many frames each side, at most
        self.last_dir = np.zeros((characters, 2))  # the heading held, as a ground direction
        self.moved = np.zeros(characters, bool)  # moved yet (else it faces where it will first go)
        self.last_yaw = np.full(characters, np.nan)  # the yaw of the frame before (NaN: none yet)
        self.last_lean = np.zeros(characters)  # the lean of the frame before
        self.anchor = np.full((characters, 3), np.nan)  # drawn after the path (heading_kernels._moving)

    def advance(self, ground: Floats, off: int, n: int, fps: float, facing: Floats, ends: bool = False,
                ahead: Callable[[NDArray[np.int64]], Floats] | None = None,
                moving: Floats | None = None) -> tuple[Floats, Floats, Floats, Floats]:
        """(C, n) yaw (about +Y, 0 = +Z) of frames ``[t0, t0 + n)``: the tangent of the path's
        ground points ``ground (C, m, 2)`` (frame t0 at ``off``; read across up to ``chord_frames``
        either side, heading_kernels._way), held where the character moves
        slower than MIN_TURN_SPEED (a standing animal does not spin with its trajectory's jitter),
        reached no faster than MAX_YAW_RATE and MAX_LATERAL allow, (C, n) the lean into the
        turn and (C, n, 2) the way of the path the root follows (:func:`heading_kernels.turn`);
        before it first moves, the way it first moves -- searched on in ``ground`` (to its end if
        ``ends``: the path's end), or in ``ahead(characters)``, their ground from the same point
        on as far as known -- else ``facing (C,)``. ``moving``: the ground points of the path the
        root follows, if not ``ground`` (its speed caps the turn: a smoothed path cutting a corner
        is slower through it than the body); and (C, n) the turn into each frame from the one
        before (radians)."""
        held = np.empty((ground.shape[0], n, 2))
        hold = (MIN_TURN_SPEED, FREE_TURN_SPEED, HOLD_RADIUS, HOLD_PULL / fps, STILL_S * fps,
                START_TURN_SPEED, self.chord_frames)
        anchor = self.anchor.copy()  # as it was, for the ones asked again
        self.kernels.headings(ground, off, ends, fps, *hold, self.last_dir, self.moved, self.anchor, held)
        unknown = np.flatnonzero(np.isnan(held[:, 0, 0]))  # NaN over every frame before a first move
        if len(unknown) and ahead is not None:  # standing so far: where will they go? (their state
            # is as it was: no move in these frames, so they are asked again, on the longer path)
            again = held[unknown]
            self.kernels.headings(ahead(unknown), off, ends, fps, *hold, self.last_dir[unknown],
                                  self.moved[unknown], anchor[unknown], again)
            held[unknown] = again
        yaw = np.arctan2(held[..., 0], held[..., 1])
        if len(unknown):
            yaw = np.asarray(np.where(np.isnan(yaw[:, :1]), facing[:, None], yaw))
        yaw = np.ascontiguousarray(yaw)
        lean, way, turned = np.empty_like(yaw), np.empty((*yaw.shape, 2)), np.empty_like(yaw)
        speed_from = ground if moving is None else moving
        self.kernels.turn(yaw, speed_from, off, fps, MAX_YAW_RATE, MAX_LATERAL, MAX_LEAN, LEAN_RATE,
                          GENTLE_LEAN, WAY_SPEED / fps, self.last_yaw, self.last_lean, lean, way, turned)
        return yaw, lean, way, turned


def headings(path: Floats, fps: float, frames: int | None = None, backend: str = "auto") -> Floats:
    """(C, T) yaw of a whole path ``(C, T, 3)`` (:func:`turning`)."""
    return turning(path, fps, frames, backend)[0]


def turning(path: Floats, fps: float, frames: int | None = None, backend: str = "auto",
            facing_path: Floats | None = None) -> tuple[Floats, Floats, Floats, Floats]:
    """(C, T) yaw, lean, way and turn of a whole path ``(C, T, 3)`` (:meth:`Headings.advance`); a character
    that never moves faces its path's first step. ``frames``: the first ``frames`` only (the same
    numbers). ``facing_path``: the path whose way the body faces, if not ``path``."""
    moving = np.ascontiguousarray(path[..., GROUND_AXES])
    ground = moving if facing_path is None else np.ascontiguousarray(facing_path[..., GROUND_AXES])
    T = ground.shape[1]
    n = T if frames is None else min(frames, T)
    first_step = ground[:, min(1, T - 1)] - ground[:, 0]
    facing = np.arctan2(first_step[:, 0], first_step[:, 1])
    return Headings(len(ground), backend).advance(ground, 0, n, fps, facing, ends=True, moving=moving)


def character_leads(bank: Bank, keys: NDArray[np.uint64]) -> NDArray[np.int64]:
    """(C,) each character's lead, as the rows its plan adds to the table's: 0 (the library's
    clips) or, for half the characters (drawn from each one's key), the bank's mirror (their mirror
    images, left and right swapped). A herd leaving standing by the one start transition stepped as
    one, every horse the same foot first (issue 28); real herds lead on either side."""
    return np.where(uniform(keys, LEAD_STREAM)[:, 0] < 0.5, bank.mirror, 0).astype(np.int64)


class Planner:
    """The plans of ``len(scales)`` characters, advanced frame block by frame block (the state of
    :mod:`synth_core.compiled.plan_kernels`' machine carried between blocks). ``tempo (C,)``: clip
    frames per output frame (synthesis.character_tempo); ``leads (C,)``: :func:`character_leads`;
    ``turn_s``, ``by_step``: a low-latency session's (see TURN_S)."""

    def __init__(self, bank: Bank, scales: Floats, tempo: Floats, leads: NDArray[np.int64],
                 margin: int = MARGIN, backend: str = "auto", turn_s: float = 0.0,
                 by_step: bool = True) -> None:
        self.tables, self.kernels = tables(bank), planner(backend)
        self.scales, self.tempo, self.leads, self.margin = scales, tempo, leads, margin
        self.step = decision_step(bank.mean_cycle)
        self.ints, self.floats = pk.initial_state(len(scales), N_HUBS, by_step)
        # The body's turn a frame averaged over ``turn_s`` (0: each frame's), at the last frame planned.
        self.turning = np.zeros(len(scales))
        self.keep_turn = 1.0 - float(np.exp(-1.0 / (turn_s * bank.fps))) if turn_s > 0 else 1.0

    def averaged(self, turned: Floats) -> Floats:
        """``turned (C, n)`` averaged over the planner's ``turn_s`` (a first-order low-pass, its state
        carried on from the block before: the same in blocks as in one); as it is where that is 0."""
        a = self.keep_turn
        if a == 1.0 or turned.shape[1] == 0:
            return turned
        zi = ((1.0 - a) * self.turning)[:, None]
        mean = np.asarray(lfilter([a], [1.0, a - 1.0], turned, axis=1, zi=zi)[0])
        self.turning = mean[:, -1]  # (lfilter's own state is (1 - a) times it)
        return mean

    def advance(self, t0: int, v: Floats, pts: Floats, turned: Floats, decisions: Decisions, out: Plan,
                out_step: int = 1) -> None:
        """Frames ``[t0, t0 + n)`` of speeds ``v (C, n)`` (the library's: over scale and tempo) and
        path ``pts (C, >= n, 3)`` from frame t0 on (its frame t0 + n, if given, carries the distance
        walked on, and the step into it the next block's first frame reads), the body turning
        ``turned (C, n)`` (Headings.advance), with ``decisions`` made there; the rows, weights, gait,
        contacts and stitches of frames a multiple of ``out_step`` into ``out``'s arrays (one per
        frame)."""
        tb, turned = self.tables, self.averaged(turned)
        self.kernels.advance(t0, v, pts, turned, self.scales, self.tempo, self.leads, decisions.speed,
                             decisions.draws, decisions.first, self.step, self.ints, self.floats, *tb.args(),
                             self.margin, tb.creep, out_step, out.rows, out.weights, out.gait,
                             out.contacts, out.stitches)


def plan(bank: Bank, prep: Prepared, h: Floats, keys: NDArray[np.uint64], margin: int = MARGIN,
         frames: int | None = None, compiled: bool = False) -> Plan:
    """The batch plan: a :class:`Planner` advanced over the whole trajectory.

    ``frames``: plan only the first ``frames`` frames (all, when that is hardly fewer) -- exactly as
    the whole plan has them (the planner is causal but for its decisions' look-ahead; a streamed
    batch's first window needs no more). ``compiled``: by the compiled kernels (else the reference:
    the same numbers, bit for bit)."""
    path = prep.positions
    C, T = path.shape[:2]
    m = prep.segment
    tempo = np.ones(C) if prep.tempo is None else prep.tempo
    keep = T if frames is None or frames + lookahead(m) + 1 >= T else max(frames, 1)
    read = T if keep == T else keep + lookahead(m) + 1  # the speeds its decisions read
    # The library motion's speed for each character: at its scale and tempo (character_tempo).
    # Distances stay over h alone: a transition plays by distance, and its clip's planted feet
    # stay planted only if it plays at the path's distance at the character's size.
    v = frame_speeds(prep.segment_speeds / (h * tempo)[:, None], m, read)
    step = decision_step(m)
    at = np.arange(-(-keep // step)) * step
    decisions = Decisions(0, np.ascontiguousarray(v[:, np.minimum(at + lookahead(m), read - 1)]),
                          uniform_streams(keys, SCHEDULE_STREAM, len(at), N_HUBS))
    backend = "numba" if compiled else "numpy"
    out = empty_plan(C, keep, h)
    # The body faces the way of the smoothed positions (a simulator's jitter does not swing it).
    out.yaw[...], out.lean[...], out.way[...], turned = turning(path, bank.fps, keep, backend, prep.facing)
    planner = Planner(bank, h, tempo, character_leads(bank, keys), margin, backend)
    planner.advance(0, np.ascontiguousarray(v[:, :keep]), path, turned, decisions, out)
    out.path[...] = path[:, :keep]
    return out
