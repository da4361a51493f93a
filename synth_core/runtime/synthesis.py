"""Run-time synthesis for crowds (Sung 2011, section 6): trajectories in, joint rotations out.

For a batch of characters at once, all array operations over (characters, frames[, joints]);
the only Python loops run over segments (a dozen) and gaits (four):

1. **Schedule** (per segment, vectorized over characters). Every character starts standing and
   moves through the motion graph one hub at a time. A segment's speed ``s / (h k)`` (scale h,
   stride tempo k: :func:`character_tempo`, Froude similarity by default) picks the gait: the
   current one while its range covers the speed (hysteresis), else one of the gaits covering
   it -- at random where ranges overlap (each character's own counter-based draws,
   :mod:`synth_core.runtime.draws`) -- reached one transition per step. A transition starts when the
   stride reaches the phase the clip starts from (``Bank`` entry), and the next gait picks up at
   the phase the clip ends in: the footfall sequence carries on across it.
2. **Clip interpolation.** Within a gait every speed-map clip has the same frames and contacts,
   so the stride phase just runs on (k clip frames per output frame: :func:`stride_clocks`) and
   the speed only moves the pair of clips blended, ``M = (1 - a) M_i + a M_j`` with the paper's
   ``a``, a continuous function of the speed interpolated between segment centres: no pop where
   segments meet.
3. **Stitch.** Where a piece starts (transition in or out), the piece before it carries on and
   fades out over ``margin`` frames (smoothstep).
4. **Warp.** The root's ground position is the (smoothed) trajectory point of that frame plus
   the clip's own in-stride surge along the heading -- so it keeps time with the trajectory and
   never drifts from it -- and its heading follows the trajectory's tangent; its height is the
   clip's times h. Sideways sway of the clips is dropped: the path is the caller's.
5. **Foot lock** (:mod:`synth_core.runtime.footlock`) pins each planted foot where it lands.

Steps 1-2 make a :class:`Plan` (numpy here, the reference of the compiled
:mod:`synth_core.compiled.plan_kernels`); :func:`render` does 3-5 in numpy, the reference of the compiled
:mod:`synth_core.compiled.kernels`. Synthesis uses the compiled ones when numba is installed.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from synth_core import SIZE_MATCHING, TEMPO_SPREAD, UP_AXIS
from synth_core.compiled import kernels, plan_kernels
from synth_core.compiled.scratch import Scratch
from synth_core.motion import quat
from synth_core.runtime.bank import STATIC, Bank
from synth_core.runtime.draws import (
    SCALE_STREAM,
    SCHEDULE_STREAM,
    TEMPO_STREAM,
    character_keys,
    uniform,
    uniform_streams,
)
from synth_core.runtime.footlock import lock_feet
from synth_core.runtime.terrain import Grounding, HeightField, along_ground, ground_plan
from synth_core.runtime.trajectory import DEFAULT_SIGMA, Prepared, TrajectoryError, prepare

Floats = NDArray[np.float64]
MARGIN = 10  # frames over which a finished piece fades out where the next starts
N_HUBS = 5  # static, walk, trot, canter, gallop
CHUNK = 256  # characters planned and rendered at a time (the working set stays in cache)
BACKENDS = ("auto", "numba", "numpy")
# Below its slowest clip's speed the slowest gait plays that clip's stride slower (its feet keep
# pace with a slow path, as an animal creeping walks with long stances), down to this share of
# its pace; slower still, a character stands. (At 0.5, with the stride at full pace, creeping
# horses stood while their root crept on over the pinned hooves, which lifted 25 cm.)
STAND_SHARE = 0.08
MIN_TURN_SPEED = 0.05  # m/s: slower than this the heading holds (a standing animal does not spin)
LOOKAHEAD = 2  # segments: gaits are chosen on the speed this far ahead, as transitions take time
DECISION_SHARE = 4  # gait decisions this many times a segment
MAX_RATE = 1.6  # a gait asked to go faster than its fastest clip plays its stride up to this fast


@dataclass(frozen=True)
class Options:
    sigma: float = DEFAULT_SIGMA  # trajectory smoothing, frames
    seed: int = 0
    scale_range: tuple[float, float] = (1.0, 1.0)  # scales drawn for characters given none
    margin: int = MARGIN
    foot_lock: bool = True
    skip_invalid: bool = False
    backend: str = "auto"  # "numba" (compiled kernels), "numpy" (the reference), "auto": numba if installed
    first_index: int = 0  # the batch's first character's index in the herd (its draws' counter)
    min_resample_rate: float = 1.0  # resample at least this much (a herd split into batches: the
    # rate of the batch with the fastest character, so every batch keeps the same frames)
    resample: bool = False  # the paper's global resampling where a character is too fast (default:
    # the caller's clock is kept, and a character too fast even at MAX_RATE gets a warning)
    size_matching: str = "froude"  # how a character of scale h uses the library (character_tempo)
    tempo_spread: float = TEMPO_SPREAD  # each character's own stride tempo, +- this share
    max_character_frames: int | None = None  # refuse (FrameLimitError) a batch that would make more
    ground: HeightField | None = None  # the terrain the herd walks on (None: the paths' y is the ground)


@dataclass(frozen=True, eq=False)
class Result:
    root_pos: NDArray[np.float32]  # (C, T, 3) world, metres
    rotations: NDArray[np.float32]  # (C, T, J, 4) local, xyzw
    gait: NDArray[np.int8]  # (C, T) hub index (static 0 ... gallop 4); a transition: the hub it
    # leaves over its first half, the one it reaches over its second
    contacts: NDArray[np.bool_]  # (C, T, 4) planted feet
    stitches: NDArray[np.bool_]  # (C, T) frames where a new piece starts (transitions in/out)
    scales: Floats  # (C,)
    path: Floats  # (C, T, 3) the smoothed trajectory followed
    resample_rate: float
    kept: NDArray[np.int64]  # input characters synthesized
    rejected: dict[int, str] = field(default_factory=dict)
    warnings: dict[int, str] = field(default_factory=dict)  # input index -> what its motion could not keep


@dataclass(frozen=True)
class _Kinds:
    """Per piece kind (hubs 0-4, then transitions): table layout, as arrays for gathering."""

    offset: NDArray[np.int64]
    frames: NDArray[np.int64]
    clips: NDArray[np.int64]
    cyclic: NDArray[np.bool_]
    source: NDArray[np.int64]  # hub left (a hub: itself)
    target: NDArray[np.int64]  # hub reached (a hub: itself)
    tr_kind: NDArray[np.int64]  # (5, 5) kind of the transition between two hubs, -1 none
    entry: NDArray[np.int64]  # (5, 5)
    exit: NDArray[np.int64]  # (5, 5)


@functools.lru_cache(maxsize=8)  # per bank (identity): made once, not per plan
def _kinds(bank: Bank) -> _Kinds:
    pieces = [bank.gaits.get(h, bank.idle) if h else bank.idle for h in range(N_HUBS)]
    trs = sorted(bank.transitions.items())
    pieces += [p for _, p in trs]
    tr_kind = np.full((N_HUBS, N_HUBS), -1)
    entry = np.zeros((N_HUBS, N_HUBS), np.int64)
    exit_ = np.zeros((N_HUBS, N_HUBS), np.int64)
    for k, ((a, b), p) in enumerate(trs):
        tr_kind[a, b], entry[a, b], exit_[a, b] = N_HUBS + k, p.entry, p.exit
    return _Kinds(np.array([p.offset for p in pieces]), np.array([p.frames for p in pieces]),
                  np.array([p.clips for p in pieces]),
                  np.array([True] * N_HUBS + [False] * len(trs)),
                  np.array(list(range(N_HUBS)) + [a for (a, _), _ in trs]),
                  np.array(list(range(N_HUBS)) + [b for (_, b), _ in trs]), tr_kind, entry, exit_)


def coverage(bank: Bank) -> tuple[Floats, Floats]:
    """Per hub, the lowest and highest speed it covers (inf, -inf: none). The slowest gait
    covers down to STAND_SHARE of its slowest clip (its slowest clip, played slower: see
    :func:`stride_clocks`); below that a character stands."""
    low = np.full(N_HUBS, np.inf)
    high = np.full(N_HUBS, -np.inf)
    for h, s in bank.speeds.items():
        low[h], high[h] = s[0], s[-1]
    slowest = min(bank.speeds)
    low[slowest] = STAND_SHARE * low[slowest]
    return low, high


@functools.lru_cache(maxsize=8)
def _plan_tables(bank: Bank) -> plan_kernels.Tables:
    kinds = _kinds(bank)
    return plan_kernels.tables(bank, kinds, transition_distances(bank, kinds), *coverage(bank))


def _choose(bank: Bank, current: NDArray[np.int64], speed: Floats,
            draws: Floats) -> NDArray[np.int64]:
    """Next hub per character for a segment's speed: stay while covered, else one step toward a
    covering gait (a random one where several cover it; ``draws (C, 5)`` uniform)."""
    C = len(current)
    covered = np.zeros((C, 5), bool)
    low, high = coverage(bank)
    slowest = min(bank.speeds)
    covered[:, 1:] = (speed[:, None] >= low[None, 1:] - 1e-9) & (speed[:, None] <= high[None, 1:] + 1e-9)
    covered[:, STATIC] = speed < low[slowest]
    beyond = ~covered.any(axis=1)  # faster than the fastest gait (resampling makes that rare)
    covered[beyond, max(bank.speeds)] = True
    priority = np.where(covered, draws, -1.0)
    target = np.where(covered[np.arange(C), current], current, priority.argmax(axis=1))
    return np.asarray(current + np.sign(target - current))


def distance_since(travelled: Floats, creep: float, begin: NDArray[np.int64], t0: int = 0,
                   at: Floats | None = None) -> Floats:
    """(n, T) distance covered from frame ``begin`` (per row) on, plus the creep; < 0 before it.
    ``travelled`` holds frames ``t0 ...``; ``at (n, 1)``: the distance at ``begin`` (default: read
    from ``travelled``)."""
    T = travelled.shape[1]
    if at is None:
        at = np.take_along_axis(travelled, np.clip(begin - t0, 0, T - 1)[:, None], axis=1)
    return np.asarray(travelled - at + creep * ((t0 + np.arange(T))[None, :] - begin[:, None]))


def transition_distances(bank: Bank, kinds: _Kinds) -> Floats:
    """Per piece kind, the distance a transition covers (0 for the gaits)."""
    total = np.zeros(len(kinds.frames))
    for (a, b), d in bank.progress.items():
        total[kinds.tr_kind[a, b]] = d[-1]
    return total


def stride_clocks(bank: Bank, kinds: _Kinds, speed: Floats, t0: int = 0,
                  at: Floats | None = None, tempo: Floats | None = None) -> Floats:
    """(N_HUBS + 1, C, T+1): per hub, the stride frames played before each frame; the last row
    (every transition's) is plain time. ``speed`` holds frames ``t0 ...``, and ``at (N_HUBS + 1,
    C)`` the clocks at frame t0 (default 0: the clocks start there).

    ``tempo (C,)`` clip frames per output frame (:func:`character_tempo`; default 1) -- times up
    to MAX_RATE where the character is asked for more speed than the gait's fastest clip has (a
    transition still under way, a sprint), so the feet keep pace instead of sliding; and, for
    the slowest gait asked for less than its slowest clip, times down to STAND_SHARE.
    """
    C, T = speed.shape
    clocks = np.broadcast_to(np.arange(t0, t0 + T + 1, dtype=np.float64), (N_HUBS + 1, C, T + 1)).copy()
    k = np.ones(C) if tempo is None else tempo
    for hub in bank.speeds:
        clocks[hub] = _stride_clock(speed, clip_range(bank, hub), np.zeros(C) if at is None else at[hub], k)
    return clocks


def clip_range(bank: Bank, hub: int) -> tuple[float, float]:
    """A hub's (slowest, fastest) clip speed as its stride clock reads them: the slowest gait
    plays slower below its slowest clip; others never (slowest 0)."""
    s = bank.speeds[hub]
    return (float(s[0]) if hub == min(bank.speeds) else 0.0), float(s[-1])


def hub_clocks(bank: Bank, hubs: NDArray[np.int64], speed: Floats, t0: int, at: Floats,
               tempo: Floats) -> Floats:
    """(C, T+1): :func:`stride_clocks`' row of each character's own hub ``hubs (C,)`` only (the
    same numbers; a live decision reads no other: a fifth of the work)."""
    C, T = speed.shape
    clocks = np.broadcast_to(np.arange(t0, t0 + T + 1, dtype=np.float64), (C, T + 1)).copy()
    for hub in bank.speeds:
        who = np.flatnonzero(hubs == hub)
        if len(who):
            clocks[who] = _stride_clock(speed[who], clip_range(bank, hub), at[hub, who], tempo[who])
    return clocks


def _stride_clock(speed: Floats, clips: tuple[float, float], begin: Floats, tempo: Floats) -> Floats:
    """One hub's clock from ``begin (C,)``: ``tempo`` clip frames per frame, up to MAX_RATE faster
    above its fastest clip's speed, down to STAND_SHARE below its slowest's (``clips``: the two
    speeds, the slowest 0 for a gait that never plays slower)."""
    slow, fast = clips
    rate = np.where(speed < slow, np.maximum(speed / max(slow, 1e-12), STAND_SHARE),
                    np.clip(speed / fast, 1.0, MAX_RATE)) * tempo[:, None]
    return np.asarray(np.cumsum(np.concatenate([begin[:, None], rate], axis=1), axis=1))


def character_tempo(keys: NDArray[np.uint64], h: Floats, matching: str = "froude",
                    spread: float = TEMPO_SPREAD) -> Floats:
    """Each character's stride tempo k: clip frames per output frame. A character of scale h
    (its lengths h times the library's) at speed s plays the library's motion of speed
    ``s / (h k)`` -- stride length h times the clip's, frequency k times -- so its feet keep pace.

    ``froude`` (dynamic similarity, the default): k = 1 / sqrt(h), so a character asks for the
    library's motion at the same Froude number v^2 / (g h) -- the same gait, duty factor and
    relative stride -- and steps with frequency ~ 1 / sqrt(h) (Alexander & Jayes 1983;
    Pennycuick 1975: stepping frequency ~ size^-0.5 in walk, trot and canter). ``geometric``
    (the paper's s / h matching): k = 1, every size steps at the library's frequency. Either
    way times ``1 + spread u``, u uniform in [-1, 1) from the character's key."""
    if matching not in SIZE_MATCHING:
        raise TrajectoryError(f"size_matching: must be one of {SIZE_MATCHING}, got {matching!r}")
    if not (np.isfinite(spread) and 0 <= spread <= 0.25):
        raise TrajectoryError(f"tempo_spread: must be within [0, 0.25], got {spread}")
    fine = np.isfinite(h) & (h > 0)  # others are refused with the trajectory checks
    froude = np.where(fine, 1 / np.sqrt(np.where(fine, h, 1.0)), 1.0)
    base = froude if matching == "froude" else np.ones(len(h))
    if spread == 0:
        return np.asarray(base, np.float64)
    u = 2 * uniform(keys, TEMPO_STREAM)[:, 0] - 1
    return np.asarray(base * (1 + spread * u), np.float64)


def switch(kinds: _Kinds, cur: NDArray[np.int64], new: NDArray[np.int64], first: NDArray[np.int64],
           played: Floats) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """A gait change from hub ``cur`` to ``new``, decided where the playing piece (from clip frame
    ``first``) has played ``played`` stride frames: (frames to wait for the transition's entry
    phase, the transition's kind, the clip frame the new gait resumes at)."""
    frames = kinds.frames[cur]
    phase = np.floor(first + played + 0.5).astype(np.int64) % frames
    wait = np.where(cur == STATIC, 0, (kinds.entry[cur, new] - phase) % frames)
    resume = np.where(new == STATIC, 0, (kinds.exit[cur, new] + 1) % kinds.frames[new])
    return wait, kinds.tr_kind[cur, new], resume


def decision_step(m: int) -> int:
    """Frames between gait decisions."""
    return max(1, m // DECISION_SHARE)


def lookahead(m: int) -> int:
    """Frames from a gait decision to the speed it reads."""
    return int(LOOKAHEAD * m)


def entry_frame(clock: Floats, d: NDArray[np.int64], wait: NDArray[np.int64]) -> NDArray[np.int64]:
    """Per row of ``clock (n, F)`` (a gait's stride clock), the first frame from ``d`` on where the
    stride has played ``wait`` more stride frames -- the gait reaches a transition's entry phase
    (it may play faster than a stride frame a frame); ``F`` where that is beyond the clock."""
    n = np.arange(len(d))
    due = clock[n, d] + wait - 1e-9
    reach = (clock >= due[:, None]) & (np.arange(clock.shape[1])[None, :] >= d[:, None])
    return np.asarray(np.where(reach.any(axis=1), reach.argmax(axis=1), clock.shape[1]))


def schedule(bank: Bank, kinds: _Kinds, speed: Floats, m: int, travelled: Floats, clocks: Floats,
             keys: NDArray[np.uint64]) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Per character the pieces played: ``(start frame, kind, first clip frame)``, each (C, E).

    Decisions every quarter segment (``DECISION_SHARE``), on the speed ``LOOKAHEAD`` segments ahead
    (``speed (C, T)``, m/s in the character's unit), for every character free by the next one: one
    whose transition ends before it decides as it ends -- a gait change waits for the stride's
    entry phase, and deciding a few frames late can cost a whole stride. ``travelled (C, T)``:
    distance along the path from frame 0, same unit. ``keys``: each character's random key
    (:mod:`synth_core.runtime.draws`); decision k draws its stream k, so a plan of the first frames only
    decides them as the whole plan does.
    """
    C, T = speed.shape
    step = decision_step(m)
    K = -(-T // step)
    total = transition_distances(bank, kinds)
    E = 1 + 2 * K
    never = np.iinfo(np.int64).max // 4
    start = np.full((C, E), never, np.int64)
    kind = np.zeros((C, E), np.int64)
    first = np.zeros((C, E), np.int64)
    start[:, 0] = 0  # standing: the idle from its first frame
    count = np.ones(C, np.int64)
    current = np.zeros(C, np.int64)
    busy = np.zeros(C, np.int64)
    for k in range(K):
        a = k * step
        # Decided on the speed ahead: transitions take time, so start them early.
        draws = uniform(keys, SCHEDULE_STREAM + k, N_HUBS)
        nxt = _choose(bank, current, speed[:, min(a + lookahead(m), T - 1)], draws)
        go = np.flatnonzero((busy < a + step) & (nxt != current))
        if len(go) == 0:
            continue
        cur, new, last = current[go], nxt[go], count[go] - 1
        d = np.maximum(a, busy[go])  # decided as its transition ends, if that comes first
        n = np.arange(len(go))
        clock = clocks[cur, go]  # (n, T+1): the gait's stride clock of each of these characters
        played = clock[n, d] - clock[n, start[go, last]]
        wait, tr, resume = switch(kinds, cur, new, first[go, last], played)
        begin = entry_frame(clock, d, wait)
        # Played by distance: it ends where the character has covered the clip's distance.
        done = distance_since(travelled[go], bank.creep, begin) >= total[tr][:, None]
        done &= np.arange(T)[None, :] > begin[:, None]
        end = np.where(done.any(axis=1), done.argmax(axis=1), T + kinds.frames[tr])
        start[go, last + 1], kind[go, last + 1], first[go, last + 1] = begin, tr, 0
        start[go, last + 2], kind[go, last + 2], first[go, last + 2] = end, new, resume
        count[go] += 2
        busy[go] = end
        current[go] = new
    return start, kind, first


def _local(clocks: Floats, kind: NDArray[np.int64], first: NDArray[np.int64], start: NDArray[np.int64],
           at: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None) -> NDArray[np.int64]:
    """Clip frame (whole, before wrapping) each piece is at: its first frame plus its clock since
    it started. ``clocks (kinds, C, T+1)`` with ``kind (C, T)``; or, given ``at`` (characters,
    frames), flat (n,)."""
    row = np.minimum(kind, N_HUBS)  # transitions play by time (and distance, in _rows)
    if at is None:
        C, T = kind.shape
        c, t = np.arange(C)[:, None], np.arange(T)[None, :]
        now = clocks[row, c, t]
        then = clocks[row, c, np.clip(start, 0, T)]
    else:
        now = clocks[row, at[0], at[1]]
        then = clocks[row, at[0], np.clip(start, 0, clocks.shape[-1] - 1)]
    return np.floor(first + now - then + 0.5).astype(np.int64)


def _frame_speeds(speeds: Floats, m: int, T: int) -> Floats:
    """(C, T): segment speeds interpolated linearly between segment centres."""
    K = speeds.shape[1]
    pos = (np.arange(T) - (m - 1) / 2) / m
    k0 = np.clip(np.floor(pos).astype(np.int64), 0, K - 1)
    k1 = np.minimum(k0 + 1, K - 1)
    f = np.clip(pos - k0, 0.0, 1.0)
    return np.asarray(speeds[:, k0] * (1 - f) + speeds[:, k1] * f)


def _rows(bank: Bank, kinds: _Kinds, kind: NDArray[np.int64], local: NDArray[np.int64],
          speed: Floats, walked: Floats | None = None) -> tuple[NDArray[np.int64], NDArray[np.int64],
                                                               NDArray[np.float32]]:
    """Table rows of the two clips blended and the second's weight, per (character, frame).

    Gaits: the two speed-map clips around ``speed`` at the stride frame ``local``. Transitions:
    the two clip frames around the one whose progress is ``walked`` (distance since it began;
    None: past its end).
    """
    frames = kinds.frames[kind]
    frame = np.where(kinds.cyclic[kind], local % frames, np.clip(local, 0, frames - 1))
    clip0 = np.zeros(kind.shape, np.int64)
    weight = np.zeros(kind.shape, np.float32)
    for (a, b), d in bank.progress.items():
        on = kind == kinds.tr_kind[a, b]
        if walked is None or not on.any():
            continue
        f = np.interp(walked[on], d, np.arange(len(d), dtype=np.float64))
        whole = np.minimum(np.floor(f).astype(np.int64), len(d) - 1)
        frame[on] = whole
        weight[on] = f - whole
    for hub, s in bank.speeds.items():
        on = kind == hub
        u = np.interp(speed[on], s, np.arange(len(s), dtype=np.float64))
        clip0[on] = np.minimum(np.floor(u).astype(np.int64), len(s) - 2) if len(s) > 1 else 0
        weight[on] = u - clip0[on]
    clip1 = np.minimum(clip0 + 1, kinds.clips[kind] - 1)
    base = kinds.offset[kind] + frame
    # A transition's "second clip" is its next frame.
    step = np.where(kinds.cyclic[kind], clip1 * frames, np.minimum(frame + 1, frames - 1) - frame)
    return base + clip0 * frames, base + step, weight


def blend_rows(bank: Bank, kinds: _Kinds, margin: int, kind: NDArray[np.int64], local: NDArray[np.int64],
               v: Floats, walked: Floats, since: NDArray[np.int64],
               fading: tuple[NDArray[np.int64], NDArray[np.int64]], p_kind: NDArray[np.int64],
               p_local: NDArray[np.int64]) -> tuple[NDArray[np.int32], NDArray[np.float32], NDArray[np.int8]]:
    """A plan's ``rows (C, T, 4)``, ``weights (C, T, 3)`` and ``gait (C, T)``: the piece playing
    (``kind`` at clip frame ``local``; ``since`` frames since it started), and at the frames
    ``fading`` (characters, frames) the piece before it (``p_kind`` at ``p_local``) fading out."""
    C, T = kind.shape
    r0, r1, w = _rows(bank, kinds, kind, local, v, walked)
    rows = np.empty((C, T, 4), np.int32)
    weights = np.zeros((C, T, 3), np.float32)
    rows[..., 0], rows[..., 1], weights[..., 0] = r0, r1, w
    rows[..., 2], rows[..., 3], weights[..., 1] = r0, r1, w
    fc, ft = fading
    if len(fc):
        # A finished transition stays at its end.
        p_local = np.where(kinds.cyclic[p_kind], p_local, np.iinfo(np.int32).max)
        p0, p1, pw = _rows(bank, kinds, p_kind, p_local, v[fc, ft])
        u = (since[fc, ft] + 1) / (margin + 1)
        rows[fc, ft, 2], rows[fc, ft, 3], weights[fc, ft, 1] = p0, p1, pw
        weights[fc, ft, 2] = 1 - u * u * (3 - 2 * u)  # smoothstep out
    first_half = (r0 - kinds.offset[kind]) < kinds.frames[kind] // 2
    gait = np.where(first_half, kinds.source[kind], kinds.target[kind]).astype(np.int8)
    return rows, weights, gait


def headings(path: Floats, fps: float, frames: int | None = None) -> Floats:
    """(C, T) yaw (about +Y, 0 = +Z) of the path's tangent, held where the character moves
    slower than MIN_TURN_SPEED (a standing animal does not spin with its trajectory's jitter);
    before it first moves, the heading it first moves in. ``frames``: the first ``frames`` only
    (the same numbers: the path beyond is read only for characters standing until then)."""
    T_all = path.shape[1]
    n = T_all if frames is None or frames + 1 >= T_all else frames + 1  # + 1: the last one's gradient
    dx, dz = np.gradient(path[:, :n, 0], axis=1), np.gradient(path[:, :n, 2], axis=1)
    if n < T_all:
        dx, dz = dx[:, :-1], dz[:, :-1]
    moving = np.sqrt(dx * dx + dz * dz) * fps >= MIN_TURN_SPEED
    C, T = moving.shape
    idx = np.maximum.accumulate(np.where(moving, np.arange(T), -1), axis=1)
    has = moving.any(axis=1)
    first = np.where(has, moving.argmax(axis=1), 0)
    idx = np.where(idx < 0, first[:, None], idx)
    yaw = np.arctan2(dx, dz)
    out = np.asarray(yaw.ravel()[idx + (np.arange(C) * T)[:, None]])
    if n < T_all and not has.all():
        out[~has] = headings(path[~has], fps)[:, :T]
    return out if frames is None else out[:, :frames]


@dataclass(frozen=True, eq=False)
class Plan:
    """What every (character, frame) shows, before any pose is built: table rows and weights.

    ``rows (C, T, 4)``: the two clip rows blended of the piece playing, then the two of the piece
    fading out (the same rows where none is); ``weights (C, T, 3)``: the second row's weight of
    each pair, then the fading piece's share (0: no fade). The pose is
    ``blend(blend(r0, r1, w), blend(p0, p1, pw), keep)`` -- nlerps -- turned to ``yaw`` and put on
    ``path``; :func:`render` builds it (numpy) and :mod:`synth_core.compiled.kernels` (numba) too.
    """

    rows: NDArray[np.int32]
    weights: NDArray[np.float32]
    yaw: Floats  # (C, T) heading, radians about +Y, 0 = +Z
    path: Floats  # (C, T, 3) smoothed trajectory
    scales: Floats  # (C,)
    contacts: NDArray[np.bool_]  # (C, T, 4)
    stitches: NDArray[np.bool_]  # (C, T)
    gait: NDArray[np.int8]  # (C, T)

    def window(self, start: int, stop: int, step: int = 1) -> Plan:
        """Frames ``[start, stop)`` (every ``step``-th) of every character."""
        t = slice(start, stop, step)
        return Plan(self.rows[:, t], self.weights[:, t], self.yaw[:, t], self.path[:, t], self.scales,
                    self.contacts[:, t], self.stitches[:, t], self.gait[:, t])


def plan(bank: Bank, prep: Prepared, h: Floats, keys: NDArray[np.uint64], margin: int = MARGIN,
         frames: int | None = None, compiled: bool = False) -> Plan:
    """Schedule every character's pieces and find the rows each frame blends (see the module doc).

    ``frames``: plan only the first ``frames`` frames (all, when that is hardly fewer) -- exactly as
    the whole plan has them: every decision looks one segment ahead, so the schedule runs that much
    further, and headings and speeds come from the whole path. (A streamed batch's first window
    needs no more.)

    ``compiled``: made by :mod:`synth_core.compiled.plan_kernels` (the same plan, bit for bit)."""
    path = prep.positions
    C, T = path.shape[:2]
    kinds = _kinds(bank)
    m = prep.segment
    tempo = np.ones(C) if prep.tempo is None else prep.tempo
    # The library motion's speed for each character: at its scale and tempo (character_tempo).
    # Distances stay over h alone: a transition plays by distance, and its clip's planted feet
    # stay planted only if it plays at the path's distance at the character's size.
    speeds = prep.segment_speeds / (h * tempo)[:, None]
    keep = T
    if frames is not None and frames + lookahead(m) + 1 < T:
        keep = max(frames, 1)
        T = keep + lookahead(m) + 1
        path = path[:, :T]
    v = _frame_speeds(speeds, m, T)
    yaw = headings(prep.positions, bank.fps, keep)  # of the frames kept only
    if compiled:
        tb = _plan_tables(bank)
        step = decision_step(m)
        draws = uniform_streams(keys, SCHEDULE_STREAM, -(-T // step), N_HUBS)
        # Rows of the frames kept only (the schedule reads T: a first window's took twice as long).
        rows, weights, gait, contacts, stitches = plan_kernels.plan_frames(
            tb, bank.contacts, min(bank.speeds), max(bank.speeds), MAX_RATE,
            clip_range(bank, min(bank.speeds))[0], STAND_SHARE, margin, step, lookahead(m), bank.creep, v,
            path, h, tempo, draws, keep)
        return Plan(rows, weights, yaw, path[:, :keep], h, contacts, stitches, gait)
    clocks = stride_clocks(bank, kinds, v, tempo=tempo)
    step = np.linalg.norm(np.diff(path[..., [0, 2]], axis=1), axis=-1)
    travelled = np.concatenate([np.zeros((C, 1)), np.cumsum(step, axis=1)], axis=1) / h[:, None]
    start, kind_e, first_e = schedule(bank, kinds, v, m, travelled, clocks, keys)

    # Which piece plays at every frame: the last one started.
    E = start.shape[1]
    stride = T + 2
    keys = (np.minimum(start, T + 1) + (np.arange(C) * stride)[:, None]).ravel()
    query = (np.arange(T)[None, :] + (np.arange(C) * stride)[:, None]).ravel()
    e = (np.searchsorted(keys, query, side="right") - 1).reshape(C, T) - (np.arange(C) * E)[:, None]
    t = np.arange(T)[None, :]
    c = np.arange(C)[:, None]
    kind = kind_e[c, e]
    local = _local(clocks, kind, first_e[c, e], start[c, e])
    began = np.take_along_axis(travelled, np.clip(start[c, e], 0, T - 1), axis=1)
    walked = travelled - began + bank.creep * local
    # Stitch: the piece before fades out over the margin after a new one starts.
    since = t - start[c, e]
    fc, ft = np.nonzero((e >= 1) & (since < margin))
    pe = e[fc, ft] - 1
    p_kind = kind_e[fc, pe]
    p_local = _local(clocks, p_kind, first_e[fc, pe], start[fc, pe], (fc, ft))
    rows, weights, gait = blend_rows(bank, kinds, margin, kind, local, v, walked, since, (fc, ft), p_kind,
                                     p_local)
    stitches = np.zeros((C, T), bool)
    stitches[:, 1:] = e[:, 1:] != e[:, :-1]
    full = Plan(rows, weights, yaw, path, h, bank.contacts[rows[..., 0]], stitches, gait)
    return full if keep == T else full.window(0, keep)


def _nlerp(a: NDArray[np.float32], b: NDArray[np.float32], w: NDArray[np.float32]) -> NDArray[np.float32]:
    """Normalized lerp of quaternions (..., J, 4) by ``w (...)``, b turned to a's side."""
    sign = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0, -1.0, 1.0).astype(np.float32)
    w = w[..., None, None]
    q = a * (1 - w) + b * (w * sign)
    return np.asarray(q / np.linalg.norm(q, axis=-1, keepdims=True), dtype=np.float32)


def render(bank: Bank, p: Plan, foot_lock: bool = True,
           ground: Grounding | None = None) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Root ``(C, T, 3)`` and local rotations ``(C, T, J, 4)`` of a plan: the numpy reference of
    :func:`synth_core.compiled.kernels.render`. ``ground``: the plan stands on a terrain
    (:func:`synth_core.runtime.terrain.ground_plan`)."""
    r, wt = p.rows, p.weights
    rotations = _nlerp(bank.poses[r[..., 0]], bank.poses[r[..., 1]], wt[..., 0])
    height = bank.height[r[..., 0]] * (1 - wt[..., 0]) + bank.height[r[..., 1]] * wt[..., 0]
    surge = bank.surge[r[..., 0]] * (1 - wt[..., 0]) + bank.surge[r[..., 1]] * wt[..., 0]
    fading = wt[..., 2] > 0
    if fading.any():
        fr, fw = r[fading], wt[fading]
        before = _nlerp(bank.poses[fr[:, 2]], bank.poses[fr[:, 3]], fw[:, 1])
        rotations[fading] = _nlerp(rotations[fading], before, fw[:, 2])
        p_height = bank.height[fr[:, 2]] * (1 - fw[:, 1]) + bank.height[fr[:, 3]] * fw[:, 1]
        p_surge = bank.surge[fr[:, 2]] * (1 - fw[:, 1]) + bank.surge[fr[:, 3]] * fw[:, 1]
        height[fading] = height[fading] * (1 - fw[:, 2]) + p_height * fw[:, 2]
        surge[fading] = surge[fading] * (1 - fw[:, 2]) + p_surge * fw[:, 2]
    # Warp onto the path.
    h = p.scales[:, None]
    forward = np.stack([np.sin(p.yaw), np.zeros_like(p.yaw), np.cos(p.yaw)], axis=-1)
    root = p.path + forward * (surge * h)[..., None]
    root[..., UP_AXIS] = p.path[..., UP_AXIS] + height * h
    turn = quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), p.yaw).astype(np.float32)
    rotations[:, :, 0] = quat.mul(turn, rotations[:, :, 0])
    if ground is not None:
        rotations[:, :, 0] = quat.mul(ground.tilt, rotations[:, :, 0].astype(np.float64))
    if not foot_lock:
        return root.astype(np.float32), rotations
    return lock_feet(bank.skeleton, root, rotations, p.contacts, p.scales, ground=p.path[..., UP_AXIS],
                     bends=bank.bends, terrain=ground)


def character_scales(keys: NDArray[np.uint64], scales: ArrayLike | None,
                     scale_range: tuple[float, float]) -> Floats:
    """Each character's scale: given, or (None, NaN) drawn from its key in ``scale_range``."""
    n = len(keys)
    h_min, h_max = scale_range
    if not (0 < h_min <= h_max and np.isfinite(h_max)):
        raise TrajectoryError(f"scale_range: need 0 < min <= max, got {scale_range}")
    drawn = h_min + (h_max - h_min) * uniform(keys, SCALE_STREAM)[:, 0]
    if scales is None:
        return np.asarray(drawn)
    given = np.asarray(scales, dtype=np.float64)
    if given.shape != (n,):
        raise TrajectoryError(f"scales: expected {n} values (one per character), got shape {given.shape}")
    return np.where(np.isnan(given), drawn, given)  # NaN: "draw one for me"


def prepare_batch(bank: Bank, positions: ArrayLike, fps: float | None, scales: ArrayLike | None,
                  options: Options, ids: list[str] | None, seeds: ArrayLike | None = None
                  ) -> tuple[Prepared, Floats, NDArray[np.uint64]]:
    """Checked options, prepared trajectories, and each kept character's scale (given, or
    drawn) and random key (from its own seed, ``-1``: none, else from ``options.seed``)."""
    fps = bank.fps if fps is None else fps
    n = np.shape(positions)[0] if np.ndim(positions) >= 1 else 0
    if seeds is not None and np.shape(seeds) != (n,):
        raise TrajectoryError(f"seeds: expected {n} values (one per character), got shape {np.shape(seeds)}")
    if not (isinstance(options.first_index, int) and 0 <= options.first_index < 2**62):
        raise TrajectoryError(f"first_index: must be an integer >= 0, got {options.first_index}")
    keys = character_keys(options.seed, n, seeds, options.first_index)
    all_scales = character_scales(keys, scales, options.scale_range)
    if not (isinstance(options.margin, int) and 0 <= options.margin <= 60):
        raise TrajectoryError(f"margin: must be an integer within [0, 60] frames, got {options.margin}")
    if options.backend not in BACKENDS:
        raise TrajectoryError(f"backend: must be one of {BACKENDS}, got {options.backend!r}")
    tempo = character_tempo(keys, all_scales, options.size_matching, options.tempo_spread)
    prep = prepare(positions, fps, bank.fps, bank.top_speed, bank.mean_cycle, all_scales,
                   options.sigma, options.skip_invalid, ids, options.min_resample_rate, options.resample,
                   MAX_RATE, tempo, options.max_character_frames)
    return prep, all_scales[prep.kept], keys[prep.kept]


def compiled_backend(options: Options) -> bool:
    """Whether ``options`` render with the numba kernels (else the numpy reference)."""
    return options.backend == "numba" or (options.backend == "auto" and kernels.AVAILABLE)


@dataclass(frozen=True, eq=False)
class Rendered:
    """One chunk of a batch: its characters' motion and plan (:func:`render_chunks`)."""

    characters: slice  # rows of the prepared (kept) characters
    root: NDArray[np.float32]  # (n, T, 3)
    rotations: NDArray[np.float32]  # (n, T, J, 4)
    plan: Plan


def render_chunk(bank: Bank, prep: Prepared, h: Floats, keys: NDArray[np.uint64], options: Options,
                 characters: slice, scratch: Scratch,
                 out: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None) -> Rendered:
    """Plan and render rows ``characters`` of a prepared batch: one chunk of
    :func:`render_chunks` (callers running chunks side by side call it for each). Root and
    rotations go into ``out`` (those characters' rows) or else ``scratch``'s arrays, which then
    hold until it renders again; the render kernel's working sets are kept in ``scratch``."""
    sl = characters
    part = prep.rows(sl)
    if options.ground is not None:
        part = along_ground(part, options.ground, bank.fps)
    compiled = compiled_backend(options)
    p = plan(bank, part, h[sl], keys[sl], options.margin, compiled=compiled)
    ground = None
    if options.ground is not None:
        p, ground = ground_plan(bank, p, options.ground)
    if out is None:
        n, T = p.yaw.shape
        out = (scratch.array("root", (n, T, 3), np.float32),
               scratch.array("rotations", (n, T, bank.skeleton.n_joints, 4), np.float32))
    root, rotations = out
    if compiled:
        kernels.render(bank, p, options.foot_lock, out=(root, rotations), scratch=scratch, ground=ground)
    else:
        root[...], rotations[...] = render(bank, p, options.foot_lock, ground)
    return Rendered(sl, root, rotations, p)


def render_chunks(bank: Bank, prep: Prepared, h: Floats, keys: NDArray[np.uint64], options: Options,
                  chunk: int = CHUNK, out: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
                  fresh: bool = False, scratch: Scratch | None = None) -> Iterator[Rendered]:
    """Plan and render a prepared batch ``chunk`` characters at a time (the working set stays in
    cache, so the cost per character-frame does not grow with the crowd).

    Each chunk's root and rotations go into its rows of ``out`` (``fresh``: just allocated, not
    yet touched) or else into ``scratch`` (a new one if none), reused from chunk to chunk: a
    chunk's arrays then hold until the next is asked for. The render kernel's working sets are
    kept in ``scratch`` either way."""
    C = prep.positions.shape[0]
    scratch = Scratch() if scratch is None else scratch
    for a in range(0, C, chunk):
        sl = slice(a, min(a + chunk, C))
        rows = None
        if out is not None:
            rows = out[0][sl], out[1][sl]
            if fresh and compiled_backend(options):
                # Touch the chunk's output pages here, in one thread, before the kernel's workers
                # write them: first-touch page faults taken by parallel workers contend for the
                # process's memory map and cost as much as the render itself (measured: 0.9 ->
                # 0.48 s per 1,000 characters x 500 frames; the memset is ~5% of that).
                rows[0].fill(0)
                rows[1].fill(0)
        yield render_chunk(bank, prep, h, keys, options, sl, scratch, rows)


def synthesize(bank: Bank, positions: ArrayLike, fps: float | None = None,
               scales: ArrayLike | None = None, options: Options = Options(),
               ids: list[str] | None = None,
               progress: Callable[[int, int], None] | None = None,
               out: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
               seeds: ArrayLike | None = None, scratch: Scratch | None = None) -> Result:
    """Motion for every trajectory ``positions (C, F, 3)`` sampled at ``fps`` (default: the library's).

    ``seeds (C,)``: a character's own seed (``-1``: none, it draws from ``options.seed`` and its
    index); a character's motion depends on its seed, not on the rest of the batch (save for the
    batch's resampling rate, when ``options.resample`` and some character is too fast for the
    library).

    The batch is checked and resampled as a whole, then planned and rendered ``CHUNK`` characters
    at a time (:func:`render_chunks`); ``progress(done, total)`` is called after each chunk.

    ``out``: ``(root (C, T, 3), rotations (C, T, J, 4))`` float32 arrays to write into, e.g. a
    previous result's, as a caller synthesizing batch after batch would keep them (T: the frame
    count after resampling). Fresh memory is dear: its first touch costs up to 1.8 ms per MB on
    a VM (measured here), 5.7 s for 10,000 characters x 500 frames. ``scratch``: the render
    kernel's working sets (a few MB), which such a caller can keep too, as the service's worker
    threads do (default: fresh ones, kept for this call's chunks)."""
    prep, h, keys = prepare_batch(bank, positions, fps, scales, options, ids, seeds)
    C, T = prep.positions.shape[:2]
    J = bank.skeleton.n_joints
    if out is None:
        out = (np.empty((C, T, 3), np.float32), np.empty((C, T, J, 4), np.float32))
        fresh = True
    else:
        for name, given, shape in (("root", out[0], (C, T, 3)), ("rotations", out[1], (C, T, J, 4))):
            if given.shape != shape or given.dtype != np.float32 or not given.flags.c_contiguous:
                raise ValueError(f"out {name}: need a C-contiguous float32 array of shape {shape}, "
                                 f"got {given.dtype} {given.shape}")
        fresh = False
    gait = np.empty((C, T), np.int8)
    contacts = np.empty((C, T, 4), bool)
    stitches = np.empty((C, T), bool)
    for chunk in render_chunks(bank, prep, h, keys, options, out=out, fresh=fresh, scratch=scratch):
        sl, p = chunk.characters, chunk.plan
        gait[sl], contacts[sl], stitches[sl] = p.gait, p.contacts, p.stitches
        if progress:
            progress(sl.stop, C)
    return Result(out[0], out[1], gait, contacts, stitches, h, prep.positions,
                  prep.resample_rate, prep.kept, prep.rejected, prep.warnings)
