"""The planner, written once: each character's plan is a state machine stepped frame by frame.

Every frame ``t`` of a character, in this order (Sung 2011 section 6, steps 1-2; see
:mod:`synth_core.runtime.plan` for the why of each rule):

1. a transition under way ends at the first frame after its start where the character has covered
   its distance; its gait starts there, at the clip frame the transition ends in;
2. a character that has stopped (:func:`_settle`) stands at once: the idle takes over, whatever
   played fading out from where it is (a start, the static -> walk transition, once its path has
   moved since it began and stands still again); a transition shown under MIN_TRANSITION_RATE of
   its pace on a crawl gives way to the gait the crawl is in, the same way (:func:`_give_way`);
3. at a decision frame (every ``step`` frames) the gait is chosen on the speed ``lookahead`` ahead
   (:func:`_choose`); a change is *asked*: a character free now changes at once, one whose
   transition ends before the next decision changes as it ends, others not;
4. a change waits for the gait's stride clock to reach the transition's entry phase: the
   transition starts at the first frame where it has;
5. the frame's table rows (:mod:`~synth_core.compiled.row_kernels`): the piece playing at its
   clip frame (the stride clock since it started) and, over ``margin`` frames after a start, the
   piece before it fading out (itself still over the one before it, where it had started within
   the margin: :func:`_start`);
6. every kind's stride clock, the distance walked and how long the path has stood still move on
   to the next frame.

The state a character carries from frame to frame -- so from a live tick to the next -- is two
small rows, ``ints`` and ``floats`` (the fields below). The batch plan is this machine run over
the whole trajectory in one call, a live session runs it block by block: the same code, the same
state, so their frames are the same by construction.

Numba compiles these functions (:func:`synth_core.compiled.jit.jit`); :data:`REFERENCE` is the
same source run by the interpreter (slow: tests, machines without numba), a :class:`Kernels` with
the same signatures (:mod:`synth_core.compiled.backend` picks one); without fastmath, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from synth_core.compiled import heading_kernels, path_kernels, row_kernels
from synth_core.compiled.heading_kernels import headings, turn
from synth_core.compiled.jit import AVAILABLE, interpreted, jit, prange
from synth_core.compiled.path_kernels import points_fine
from synth_core.compiled.row_kernels import fade, frame_rows, interp, local_frame, on_lead, tween
from synth_core.runtime.bank import STATIC

NEVER = np.iinfo(np.int64).max // 4
HELD = np.iinfo(np.int32).max  # a finished transition's clip frame: it stays at its end
LIFTED_FRAMES = 3  # frames after a foot lifts in which a stalled transition does not give way

# A character's state, int64 fields ...
CURRENT = 0  # the hub decided last (being reached, if a change is under way)
STAGE = 1  # FREE, WAITING (a change asked, its transition not started) or MOVING (it plays)
KIND = 2  # the piece playing: its kind (hub 0-4, then transitions), first clip frame, start frame
FIRST = 3
START = 4
PREV_KIND = 5  # the piece before it (fading out over the margin after START)
PREV_FIRST = 6
HAS_PREV = 7
FROM = 8  # a change under way: the hub whose stride clock reaches the entry, the transition,
TRANSITION = 9  # the gait after it and the clip frame that gait resumes at
TO = 10
RESUME = 11
ASKED = 12  # a change asked of a character not free (-1: none), valid before frame ASKED_UNTIL
ASKED_UNTIL = 13
PREV_START = 14  # the frame the piece before started (its own fade over OLD ran from there)
OLD_KIND = 15  # a piece still fading out under the one before, when the one playing started
OLD_FIRST = 16  # within the margin of the one before's start (HAS_OLD): see _start
HAS_OLD = 17
N_INTS = 18
# ... and float64 fields
CLOCK0 = 0  # the piece playing's kind's clock at its start, and the distance travelled there (over h)
TRAV0 = 1
PREV_CLOCK0 = 2
DUE = 3  # the stride clock (of FROM) at which the transition may start
WALKED = 4  # distance along the path (unscaled) at the next frame
STILL = 5  # frames the path has stood still (each step under ``still_step``) by the next frame
OLD_CLOCK0 = 6
STEP = 7  # the distance WALKED grew by into the next frame: what a transition is shown by there
BY_STEP = 8  # 1: a transition's pace and a stop are read from STEP too; 0: not (plan.Planner's by_step)
CLOCKS = 9  # + kind row (hubs, then every transition's: time): stride frames played by the next frame
FREE, WAITING, MOVING = 0, 1, 2


def initial_state(characters: int, hubs: int, by_step: bool = True) -> tuple[Any, Any]:
    """``(ints, floats)`` of characters standing at frame 0 (the idle playing from its frame 0), a
    transition's pace read from the distance walked (``by_step``) or the speed (see BY_STEP)."""
    ints = np.zeros((characters, N_INTS), np.int64)
    ints[:, ASKED] = -1
    floats = np.zeros((characters, CLOCKS + hubs + 1))
    floats[:, BY_STEP] = float(by_step)
    return ints, floats


@jit(inline="always")
def _rate(v: float, hub: int, high: Any, max_rate: float, slowest: int, fastest: int, slow: float,
          share: float) -> float:
    """Clip frames per frame (before the tempo) of hub ``hub`` at speed ``v``: above its fastest
    clip, the fastest gait up to ``max_rate`` faster, a slower one (waiting for its transition:
    capped, a dog's walk kept 1.5 m/s of 3.6 and its paws were swept 22-66 cm) as fast as the
    path; the slowest gait below its slowest clip (``slow``) slower, down to ``share``."""
    if hub == slowest and v < slow:
        return max(v / slow, share)
    rate = max(v / high[hub], 1.0)
    return float(min(rate, max_rate)) if hub == fastest else float(rate)


@jit(inline="always")
def _turning(v: float, spin: float, top: float) -> float:
    """The speed a gait's stride clock keeps pace with at path speed ``v`` while the body turns, its
    feet carried round the root at ``spin`` (the turn's rate times the lever, turn_lever): the
    feet's, ``sqrt(v^2 + spin^2)``, but no faster than ``top`` unless the path is. The root is at the
    hips, so a turn sweeps the forehand round them: a walk kept to the hips' pace in a 0.5 m U-turn
    stood on each forefoot while the body turned 80 deg and the foot hung out of reach at both ends
    of its stance (a horse on one foot, issue 27's walk support). The clock only: the speed-map
    clip stays the path's speed's (a clip pair chosen on this changed in one frame where the body's
    turn jumps: a stutter start's hoof 6.25 cm)."""
    if spin == 0.0 or top <= v:
        return v
    return min(math.sqrt(v * v + spin * spin), top)  # (not hypot: numba's libm call and CPython's differ)


@jit(inline="always")
def _covering(current: int, speed: float, draws: Any, low: Any, high: Any, slowest: int,
              fastest: int) -> tuple[int, bool]:
    """The hub covering ``speed`` (``low``, ``high``: each hub's range; the one with the highest
    draw where several cover it; the fastest above them all) and whether ``current`` covers it."""
    best, pick, any_cover = -1.0, 0, False
    cover_current = False
    for hub in range(len(low)):
        if hub == STATIC:
            covered = speed < low[slowest]
        else:
            covered = speed >= low[hub] - 1e-9 and speed <= high[hub] + 1e-9
        any_cover = any_cover or covered
        if covered and hub == current:
            cover_current = True
        if covered and draws[hub] > best:
            best, pick = draws[hub], hub
    if not any_cover:  # faster than the fastest gait
        return fastest, current == fastest
    return pick, cover_current


@jit(inline="always")
def _choose(current: int, speed: float, draws: Any, low: Any, high: Any, slowest: int, fastest: int) -> int:
    """The next hub for ``speed``: stay while covered, else one step toward the covering gait."""
    pick, cover_current = _covering(current, speed, draws, low, high, slowest, fastest)
    return current if cover_current else current + (1 if pick > current else (-1 if pick < current else 0))


@jit(inline="always")
def _moving_start(s: Any, f: Any, speed: float, pts: Any, still: float, draws: Any, low: Any, high: Any,
                  slowest: int, fastest: int, slow: float, frames_of: Any) -> None:
    """A path moving at frame 0 (spawned at speed: first step over ``still``, speed at least the
    slowest clip's, ``slow``; a creep or a noisy stand starts standing) starts in the gait covering
    its speed at a drawn phase, not from standing through every transition (a horse at 5 m/s
    shuffled on the spot 1.3 s). The draw is standing's, which a moving speed never reads."""
    dx, dz = pts[1, 0] - pts[0, 0], pts[1, 2] - pts[0, 2]
    if speed < max(low[slowest], slow) or dx * dx + dz * dz < still * still:
        return
    hub = _covering(STATIC, speed, draws, low, high, slowest, fastest)[0]
    s[CURRENT], s[KIND], s[START] = hub, hub, 0
    s[FIRST] = min(int(draws[STATIC] * frames_of[hub]), frames_of[hub] - 1)
    f[CLOCK0], f[TRAV0] = f[CLOCKS + hub], 0.0


@jit(inline="always")
def _start(s: Any, f: Any, kind: int, first: int, t: int, clock0: float, travelled: float,
           margin: int) -> None:
    """Piece ``kind`` starts at frame t at clip frame ``first``: the one playing fades out.

    If the one playing started less than ``margin`` frames ago, the one before it still shows
    (fading out under it): it is not dropped, or it would vanish in one frame (a piece that
    lasts a few frames between two transitions: hooves jumped 25-38 cm). Of those two, the one
    showing more keeps fading out (OLD) under the one playing, which fades out in turn: the pose
    fading out is their blend, as it was shown (see row_kernels.frame_rows)."""
    fading = s[HAS_PREV] == 1 and t - s[START] < margin
    if fading and not (s[HAS_OLD] == 1 and fade(t - s[PREV_START], margin) > 0.5):
        s[OLD_KIND], s[OLD_FIRST], f[OLD_CLOCK0] = s[PREV_KIND], s[PREV_FIRST], f[PREV_CLOCK0]
    s[HAS_OLD] = 1 if fading else 0
    s[PREV_KIND], s[PREV_FIRST], f[PREV_CLOCK0] = s[KIND], s[FIRST], f[CLOCK0]
    s[HAS_PREV], s[PREV_START] = 1, s[START]
    s[KIND], s[FIRST], s[START] = kind, first, t
    f[CLOCK0], f[TRAV0] = clock0, travelled


@jit(inline="always")
def _change(s: Any, f: Any, new: int, frames_of: Any, tr_kind: Any, entry: Any, exit_: Any) -> None:
    """A change from the gait playing (hub CURRENT, started at its clip frame FIRST) to hub ``new``,
    now: the transition waits for the stride to reach its entry phase, the gait after it picks up
    at the phase the transition ends in (the footfall sequence carries on across it)."""
    cur = s[CURRENT]
    clock = f[CLOCKS + cur]
    frames = frames_of[cur]
    phase = int(math.floor(s[FIRST] + (clock - f[CLOCK0]) + 0.5)) % frames
    wait = 0 if cur == STATIC else (entry[cur, new] - phase) % frames
    s[FROM], s[TRANSITION], s[TO] = cur, tr_kind[cur, new], new
    s[RESUME] = 0 if new == STATIC else (exit_[cur, new] + 1) % frames_of[new]
    f[DUE] = clock + wait - 1e-9
    s[STAGE], s[CURRENT], s[ASKED] = WAITING, new, -1


@jit(inline="always")
def _shown(s: Any, f: Any, t: int, travelled: float, curve_at: Any, curves: Any, creep: float) -> float:
    """The clip frame (fractional) the transition playing shows at frame t: the one whose progress
    is the distance covered since it began (plus the creep)."""
    at, n = curve_at[s[KIND], 0], curve_at[s[KIND], 1]
    return interp((travelled - f[TRAV0]) + creep * float(t - s[START]), curves, at, n)


@jit(inline="always")
def _settle(s: Any, f: Any, t: int, travelled: float, hub: int, first: int, cyclic: Any, curve_at: Any,
            curves: Any, creep: float, margin: int) -> None:
    """Hub ``hub`` (the idle, or a gait at clip frame ``first``) takes over at frame t, now, the
    piece playing (a gait, or a transition) fading out from where it is -- a transition from the
    frame it shows, held. A stopped character settles so into the idle: slower than the slowest
    gait goes, or its path still for ``still_frames`` (the segment speeds see a stop a segment
    late). Transitions play by distance, so on a stopped path the chain down to standing (trot ->
    walk -> static) took hundreds of frames, the animal frozen mid-stride on two legs; one
    stalled on a crawl (:func:`_give_way`) gives way so to the gait the crawl is in."""
    held = -1
    if not cyclic[s[KIND]]:
        shown = _shown(s, f, t, travelled, curve_at, curves, creep)
        held = min(int(math.floor(shown)), curve_at[s[KIND], 1] - 1)
    _start(s, f, hub, first, t, f[CLOCKS + hub], travelled, margin)
    if held >= 0:
        s[PREV_FIRST] = held
    s[STAGE], s[CURRENT], s[ASKED] = FREE, hub, -1


@jit(inline="always")
def _pace(s: Any, f: Any, t: int, step: float, travelled: float, cyclic: Any, source: Any, target: Any,
          curve_at: Any, curves: Any, creep: float) -> float:
    """The clip frames a frame the transition playing shows at frame t over the character's tempo,
    walked ``step`` (over the tempo too) into it (inf: a gait, a start or a stop -- they slow with
    their path, and a path stopping is settled by :func:`_stopped` -- or its first frame). Played by
    distance, a canter -> trot on a path braking to a crawl (0.2-0.5 m/s) crept over a second or more
    at a tenth of its pace, a horse on one foreleg, the others folded (issue 27: a lone foot 2.7-6.6
    times the longest stance)."""
    kind = s[KIND]
    if cyclic[kind] or source[kind] == STATIC or target[kind] == STATIC or t == s[START]:
        return np.inf
    at, n = curve_at[kind, 0], curve_at[kind, 1]
    u = min(int(math.floor(_shown(s, f, t, travelled, curve_at, curves, creep))), n - 2)
    return float((step + creep) / max(curves[at + u + 1] - curves[at + u], 1e-12))


@jit(inline="always")
def _slower(v: float, low: Any, slowest: int) -> int:
    """The fastest gait whose range reaches down to speed ``v`` (its slowest clip at or under it;
    the slowest gait below all of them), where a stalled transition gives way."""
    hub = slowest
    for h in range(len(low)):
        if h != STATIC and low[h] <= v:  # (a hub with no clips: low inf)
            hub = max(hub, h)
    return hub


@jit(inline="always")
def _stopped(s: Any, f: Any, t: int, slow: bool, still: bool, source: Any, cyclic: Any) -> bool:
    """Rule 2: whether the character settles at frame t, its path (or the distance it walks a frame)
    slower than the slowest gait (``slow``) or standing still STILL_S (``still``). A start (static ->
    walk), which waits for the path to move, settles only where the path has moved since it began and
    stands still again: played by distance, it crept on over the stop with a paw up (the real dog's
    start, 2.3 s of its mocap, outlasts a short walk to a stop)."""
    if source[s[KIND]] != STATIC:
        return slow or still
    return still and f[STILL] < t - s[START] and s[KIND] != STATIC and not cyclic[s[KIND]]


@jit(inline="always")
def _just_lifted(contacts_of: Any, first: int, shown: float, row: int, pace: float) -> bool:
    """Whether table row ``row`` sets down a foot the transition (from table row ``first``, shown at
    clip frame ``shown``, ``pace`` clip frames a frame) lifted under LIFTED_FRAMES frames ago:
    given way to there, the foot was planted again a frame after it left (a real dog twice the
    size: a 20 cm one-frame swing out and back)."""
    u = int(math.floor(shown))
    back = int(math.ceil(LIFTED_FRAMES * pace))  # clip frames shown over LIFTED_FRAMES frames
    for foot in range(4):
        if contacts_of[first + u, foot] or not contacts_of[row, foot]:
            continue
        for d in range(1, back + 1):
            if u - d >= 0 and contacts_of[first + u - d, foot]:
                return True
    return False


@jit(inline="always")
def _give_way(s: Any, f: Any, t: int, speeds: Any, travelled: float, rates: Any, tables: Any, cyclic: Any,
              source: Any, target: Any, low: Any, slowest: int, curve_at: Any, curves: Any, creep: float,
              margin: int) -> bool:
    """Rule 2 at frame t (``speeds``: the speed now, the decisions' look-ahead speeds and the next
    one's index, and the speed walked into frame t, as the speed now reads: STEP's, if BY_STEP; a
    stop shorter than a segment is one, the trot on the spot over it, its flight 1.8 cm up;
    ``rates``: the frames still that make a stop, fps and MIN_TRANSITION_RATE; ``tables``: offset,
    frames_of, contacts_of and resume; all as _character has them): a stopped character settles into
    the idle (:func:`_stopped`), a transition stalled on a crawl (its :func:`_pace` under
    MIN_TRANSITION_RATE of its own -- over the tempo, as the speeds are; read with the tempo a
    half-size dog's canter -> trot played on at half its pace, its lone paw 2.8 times the longest
    stance -- read from the distance it plays by: a segment's speed averaged a stop shorter than it
    away, and a trot -> walk stood over its flight, every hoof 3.6 cm up) gives way to the gait of
    the slowest of the speed now, ahead and walked (the slowest gait if a stop is coming: it slows
    with the path, then settles; the idle at once stood a body still moving, and a gait too fast for
    the crawl -- a trot at its own pace, which never slows -- floated it over a flight), at the clip
    frame nearest the one shown (``resume``: plan.give_way_phases), not while a foot it sets down has
    just lifted (:func:`_just_lifted`). Whether one did."""
    v, asked, k, walked = speeds
    offset, frames_of, contacts_of, resume = tables
    still_frames, fps, stall = rates
    ahead = asked[k] if 0 <= k < asked.shape[0] else v
    # (A walk slows with its path down to a stand, and a transition to standing is a stop under way.)
    stop = walked if s[KIND] != slowest and target[s[KIND]] != STATIC else v
    if _stopped(s, f, t, min(v, stop) < low[slowest], f[STILL] >= still_frames, source, cyclic):
        _settle(s, f, t, travelled, STATIC, 0, cyclic, curve_at, curves, creep, margin)
        return True
    pace = _pace(s, f, t, walked / fps, travelled, cyclic, source, target, curve_at, curves, creep)
    if pace < stall:
        hub = _slower(min(v, ahead, walked), low, slowest)
        shown = min(_shown(s, f, t, travelled, curve_at, curves, creep), frames_of[s[KIND]] - 1.0)
        first = resume[offset[s[KIND]] + int(math.floor(shown)), hub]
        if _just_lifted(contacts_of, offset[s[KIND]], shown, offset[hub] + first, pace):
            return False
        _settle(s, f, t, travelled, hub, first, cyclic, curve_at, curves, creep, margin)
        return True
    return False


@jit(inline="always")
def _walk_on(f: Any, pts: Any, i: int, still: float, swept: float, top: float, max_rate: float) -> None:
    """The distance walked (and into point i + 1: STEP) and the frames stood still (steps under
    ``still``) by point i + 1: a transition plays by distance, the feet's as the body turns (``swept``, the
    lever's arc over the turn into frame i; :func:`_turning`), up to ``top`` a frame (the slowest
    clip's pace) or ``max_rate`` times the path's step, the faster. Kept to the path's step alone
    past the slowest pace, a real dog's walk -> trot through a trotting corner (1.5 m/s, the body
    turning 170 deg/s) stood on a forepaw the turn swept 43 cm under it, out of reach at both ends
    of its stance: a walk on one paw as it ended. Up to the slowest pace alone is what a body
    turning on the spot (no step) gets; ``max_rate`` (plan.MAX_RATE) is as much faster as a gait's
    stride plays past its fastest clip (unbounded, a horse's turn on the spot hopped 5.6 cm and
    stood on a foot longer)."""
    dx, dz = pts[i + 1, 0] - pts[i, 0], pts[i + 1, 2] - pts[i, 2]
    step = math.sqrt(dx * dx + dz * dz)
    walked = _turning(step, swept, max(top, max_rate * step))
    f[STEP] = walked
    f[WALKED] += walked
    f[STILL] = f[STILL] + 1.0 if step < still else 0.0


@jit(inline="always")
def _tick(f: Any, t: int, v: float, spin: float, quick: float, tempo: float, high: Any, max_rate: float,
          slowest: int, fastest: int, slow: float, share: float) -> None:
    """Every stride clock on to frame t + 1: the gaits' at their rate for ``v``, the slowest's
    turning at ``spin`` up to ``quick`` (:func:`_turning`); the others' time."""
    n_hubs = len(high)
    for hub in range(n_hubs + 1):
        if hub < n_hubs and hub != STATIC and high[hub] > -np.inf:
            pace = _turning(v, spin, quick) if hub == slowest else v
            f[CLOCKS + hub] += _rate(pace, hub, high, max_rate, slowest, fastest, slow, share) * tempo
        else:
            f[CLOCKS + hub] = float(t + 1)


@jit(inline="always")
def _arrive(s: Any, f: Any, t: int, travelled: float, total: Any, n_hubs: int, creep: float, margin: int,
            frames_of: Any, tr_kind: Any, entry: Any, exit_: Any) -> bool:
    """Rule 1: a transition under way ends at frame t if the character has covered its distance;
    its gait starts there (and a change asked while it played is made). Whether it ended."""
    if not (s[STAGE] == MOVING and t > s[START]
            and (travelled - f[TRAV0]) + creep * float(t - s[START]) >= total[s[KIND]]):
        return False
    to = s[TO]
    _start(s, f, to, s[RESUME], t, f[CLOCKS + min(to, n_hubs)], travelled, margin)
    s[PREV_FIRST] = HELD  # the finished transition fades out from its last frame
    s[STAGE] = FREE
    if s[ASKED] >= 0 and t < s[ASKED_UNTIL]:  # asked before, for as it ends
        _change(s, f, s[ASKED], frames_of, tr_kind, entry, exit_)
    return True


@jit(inline="always")
def _decide(s: Any, f: Any, t: int, speed: float, draws: Any, low: Any, high: Any, slowest: int,
            fastest: int, step: int, frames_of: Any, tr_kind: Any, entry: Any, exit_: Any) -> None:
    """Rule 3: the gait chosen on ``speed`` at decision frame t; a change made at once by a free
    character, asked of a busy one until the next decision."""
    nxt = _choose(s[CURRENT], speed, draws, low, high, slowest, fastest)
    s[ASKED] = -1
    if nxt != s[CURRENT] and s[STAGE] == FREE:
        _change(s, f, nxt, frames_of, tr_kind, entry, exit_)
    elif nxt != s[CURRENT]:
        s[ASKED], s[ASKED_UNTIL] = nxt, t + step


@jit()
def _character(t0: int, v: Any, pts: Any, turned: Any, h: float, tempo: float, lead: int, asked_speed: Any,
               draws: Any, k0: int, step: int, s: Any, f: Any, offset: Any, frames_of: Any, clips: Any,
               cyclic: Any, source: Any, target: Any, tr_kind: Any, entry: Any, exit_: Any, total: Any,
               low: Any, high: Any, curve_at: Any, curves: Any, contacts_of: Any, resume: Any, slowest: int,
               fastest: int, max_rate: float, slow: float, share: float, still_step: float,
               still_frames: float, fps: float, stall: float, lever: float, quick: float, margin: int,
               creep: float, out_step: int, rows: Any, weights: Any, gait: Any, contacts: Any,
               stitches: Any) -> None:
    """Frames ``[t0, t0 + len(v))`` of one character (speeds ``v``, path ``pts`` from t0 on, turning
    ``turned`` radians a frame: :func:`_turning`; rows ``lead`` on: on_lead), state ``s``, ``f`` carried
    on; the outputs' row i is frame ``t`` = the i-th multiple of ``out_step`` from t0 on. Decision
    ``k0 + k`` (at frame ``(k0 + k) step``) reads ``asked_speed[k]`` and ``draws[k]``."""
    n_hubs = len(low)
    ask = -(-t0 // step) * step  # the next decision's frame (counted on: no division a frame)
    k = ask // step - k0
    sent, o = t0 + (-t0) % out_step, 0  # the next frame sent, its row in the outputs
    if t0 == 0 and k0 == 0 and pts.shape[0] > 1 and draws.shape[0] > 0:
        _moving_start(s, f, v[0], pts, still_step * h, draws[0], low, high, slowest, fastest, slow, frames_of)
    for i in range(v.shape[0]):
        t, spin = t0 + i, abs(turned[i]) * lever * fps / tempo  # spin: the feet's round the root, as v reads
        travelled = f[WALKED] / h  # in the library's unit
        started = _arrive(s, f, t, travelled, total, n_hubs, creep, margin, frames_of, tr_kind, entry, exit_)
        walked = f[STEP] * fps / (h * tempo) if t > 0 and f[BY_STEP] > 0.0 else v[i]  # as v reads
        if not cyclic[s[KIND]] or min(v[i], walked) < low[slowest] or f[STILL] >= still_frames:
            started |= _give_way(s, f, t, (v[i], asked_speed, k, walked), travelled,
                                 (still_frames, fps, stall), (offset, frames_of, contacts_of, resume),
                                 cyclic, source, target, low, slowest, curve_at, curves, creep, margin)
        if t == ask:
            if 0 <= k < asked_speed.shape[0]:
                _decide(s, f, t, asked_speed[k], draws[k], low, high, slowest, fastest, step, frames_of,
                        tr_kind, entry, exit_)
            ask, k = ask + step, k + 1
        # Leaving a stand waits for the path to move (turn_on_spot: a hoof 32 cm up on the spot before).
        if s[STAGE] == WAITING and f[CLOCKS + s[FROM]] >= f[DUE] and not (s[FROM] == STATIC and f[STILL] > 0):
            _start(s, f, s[TRANSITION], 0, t, float(t), travelled, margin)  # a transition's clock is time
            s[STAGE], started = MOVING, True
        if t == sent:
            kind, pk, since = s[KIND], s[PREV_KIND], t - s[START]
            local = int(math.floor(s[FIRST] + f[CLOCKS + min(kind, n_hubs)] - f[CLOCK0] + 0.5))
            p_local, o_local, o_keep = -1, -1, 0.0  # the pieces before, fading out (-1: none)
            if s[HAS_PREV] and since < margin:
                p_local = local_frame(s[PREV_FIRST], pk, f[CLOCKS + min(pk, n_hubs)], f[PREV_CLOCK0], cyclic)
                o_keep = fade(t - s[PREV_START], margin) if s[HAS_OLD] else 0.0
                if o_keep > 0:
                    o_local = local_frame(s[OLD_FIRST], s[OLD_KIND], f[CLOCKS + min(s[OLD_KIND], n_hubs)],
                                          f[OLD_CLOCK0], cyclic)
            walked_since = (travelled - f[TRAV0]) + creep * local
            gait[o] = frame_rows(kind, local, walked_since, since, pk, p_local, s[OLD_KIND], o_local, o_keep,
                                  v[i], offset, frames_of, clips, cyclic, source,
                                  target, curve_at, curves, margin, o, rows, weights)
            if p_local < 0 and cyclic[kind]:  # the stride clock between two clip frames
                tween(kind, s[FIRST] + f[CLOCKS + min(kind, n_hubs)] - f[CLOCK0] - local, local, frames_of,
                       contacts_of, o, rows, weights)
            on_lead(lead, contacts_of, o, rows, contacts)
            stitches[o] = started and t >= 1
            sent, o = sent + out_step, o + 1
        _tick(f, t, v[i], spin, quick, tempo, high, max_rate, slowest, fastest, slow, share)
        if i + 1 < pts.shape[0]:
            _walk_on(f, pts, i, still_step * h, abs(turned[i]) * lever * h, slow * h * tempo / fps, max_rate)


@jit(parallel=True)
def advance(t0: int, v: Any, pts: Any, turned: Any, h: Any, tempo: Any, lead: Any, asked_speed: Any,
            draws: Any, k0: int, step: int, ints: Any, floats: Any, offset: Any, frames_of: Any, clips: Any,
            cyclic: Any, source: Any, target: Any, tr_kind: Any, entry: Any, exit_: Any, total: Any, low: Any,
            high: Any, curve_at: Any, curves: Any, contacts_of: Any, resume: Any, slowest: int, fastest: int,
            max_rate: float, slow: float, share: float, still_step: float, still_frames: float, fps: float,
            stall: float, lever: float, quick: float, margin: int, creep: float, out_step: int, rows: Any,
            weights: Any, gait: Any, contacts: Any, stitches: Any) -> None:
    """:func:`_character` for every character ``c`` (row c of every array but the tables),
    characters in parallel on numba's threads, each taking the next ones as it is free: split in
    fixed shares, the thread done first (its characters' plans shorter, or the other's core busy
    with another process) spun in the join until the other finished."""
    for c in prange(v.shape[0]):
        _character(t0, v[c], pts[c], turned[c], h[c], tempo[c], lead[c], asked_speed[c], draws[c], k0, step,
                   ints[c], floats[c], offset, frames_of, clips, cyclic, source, target, tr_kind, entry,
                   exit_, total, low, high, curve_at, curves, contacts_of, resume, slowest, fastest, max_rate,
                   slow, share, still_step, still_frames, fps, stall, lever, quick, margin, creep, out_step,
                   rows[c], weights[c], gait[c], contacts[c], stitches[c])


@dataclass(frozen=True)
class Kernels:
    """The planner's entry points; :data:`COMPILED` and :data:`REFERENCE` have the same signatures."""

    name: str
    advance: Any  # see advance()
    headings: Any  # see headings()
    turn: Any  # see turn()
    points_fine: Any  # see path_kernels.points_fine()


_PLAIN = {**interpreted(vars(heading_kernels)), **interpreted(vars(path_kernels)),
          **interpreted(globals(), vars(row_kernels))}
# (Without numba each is its own source already.)
REFERENCE = Kernels("numpy", *(_PLAIN.get(name, globals()[name])
                              for name in ("advance", "headings", "turn", "points_fine")))
COMPILED = Kernels("numba", advance, headings, turn, points_fine) if AVAILABLE else REFERENCE
