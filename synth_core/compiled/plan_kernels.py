"""Compiled (numba) planning: each character's schedule and every frame's table rows, characters
in parallel.

The numpy reference is :func:`synth_core.runtime.synthesis.plan` (``schedule``, ``_local``,
``blend_rows``): vectorized over characters, it loops in Python over the gait decisions (four a
segment), and that overhead, not the arithmetic, dominated small batches (10 characters ran at
40% of the speed per character-frame of 1,000). Here one character's whole plan is a few loops
over its frames. The same float64 operations in the same order as the reference, without
fastmath: the plans are equal bit for bit (tested), and so are the live mode's blocks made here
and by its numpy reference (``live_block``, tested).

A batch's per-frame headings and speeds stay in numpy (shared with the live mode, whose
blocks' headings are compiled here as well: ``live_headings``); the random draws are made
beforehand (:func:`synth_core.runtime.draws.uniform`, one stream per decision).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar, cast

import numpy as np
from numpy.typing import NDArray

from synth_core.compiled.kernels import AVAILABLE
from synth_core.runtime.bank import STATIC

if TYPE_CHECKING:
    from synth_core.runtime.bank import Bank
    from synth_core.runtime.synthesis import _Kinds

if AVAILABLE:
    import numba

F = TypeVar("F", bound=Callable[..., Any])
_NEVER = np.iinfo(np.int64).max // 4


def _jit(parallel: bool = False) -> Callable[[F], F]:
    # No fastmath: the plan must equal the numpy reference's bit for bit (a rounding apart can
    # move a floor() -- a stride frame, a clip -- and so a contact flag).
    def wrap(f: F) -> F:
        if not AVAILABLE:
            return f
        return cast(F, numba.njit(cache=True, parallel=parallel, nogil=True)(f))
    return wrap


_prange: Any = numba.prange if AVAILABLE else range


@dataclass(frozen=True)
class Tables:
    """What the compiled plan reads of the bank: the piece kinds, and as flat arrays per kind
    what the reference finds in the bank's dicts."""

    kinds: _Kinds
    total: NDArray[np.float64]  # per kind: a transition's distance
    low: NDArray[np.float64]  # per hub: lowest speed it covers (inf: none)
    high: NDArray[np.float64]  # per hub: highest speed it covers (-inf: none)
    curve_at: NDArray[np.int64]  # (kinds, 2): per kind, where its curve sits in ``curves`` and its length
    curves: NDArray[np.float64]  # hubs: clip speeds; transitions: their frames' progress


def tables(bank: Bank, kinds: _Kinds, total: NDArray[np.float64], low: NDArray[np.float64],
           high: NDArray[np.float64]) -> Tables:
    n = len(kinds.frames)
    curve_at = np.zeros((n, 2), np.int64)
    parts: list[NDArray[np.float64]] = []
    at = 0
    sources = [(hub, s) for hub, s in bank.speeds.items()]
    sources += [(int(kinds.tr_kind[a, b]), d) for (a, b), d in bank.progress.items()]
    for k, curve in sources:
        curve_at[k] = at, len(curve)
        parts.append(np.asarray(curve, np.float64))
        at += len(curve)
    flat = np.concatenate(parts) if parts else np.zeros(0)
    return Tables(kinds, total, low, high, curve_at, flat)


@_jit()
def _interp(x: float, xp: Any) -> float:
    """np.interp(x, xp, arange(len(xp))) for one x, as numpy computes it (same branches, same
    operations): the last j with xp[j] <= x, then the slope form."""
    n = len(xp)
    if x < xp[0]:
        return 0.0
    if x > xp[n - 1]:
        return float(n - 1)
    lo, hi = 0, n
    while lo < hi:
        mid = lo + ((hi - lo) >> 1)
        if x >= xp[mid]:
            lo = mid + 1
        else:
            hi = mid
    j = lo - 1
    if j == n - 1 or xp[j] == x:
        return float(j)
    slope = (float(j + 1) - float(j)) / (xp[j + 1] - xp[j])
    return float(slope * (x - xp[j]) + float(j))


@_jit()
def _rate(v: float, hub: int, high: Any, max_rate: float, slowest: int, slow: float, share: float) -> float:
    """synthesis._stride_clock's clip frames per frame (before the tempo) of hub ``hub`` at speed
    ``v`` (``slow``: the slowest hub's slowest clip speed, below which it plays slower)."""
    if hub == slowest and v < slow:
        return max(v / slow, share)
    return float(min(max(v / high[hub], 1.0), max_rate))


@_jit()
def _clocks(v: Any, high: Any, max_rate: float, slowest: int, slow: float, share: float, tempo: float,
            out: Any) -> None:
    """stride_clocks for one character: ``out (N_HUBS + 1, T + 1)`` (``high``: each hub's
    fastest clip, -inf for none; the last row is every transition's: plain time)."""
    T = v.shape[0]
    for hub in range(out.shape[0]):
        has = hub < len(high) and high[hub] > -np.inf and hub != STATIC
        acc = 0.0
        out[hub, 0] = 0.0
        for t in range(T):
            if has:
                acc += _rate(v[t], hub, high, max_rate, slowest, slow, share) * tempo
            else:
                acc = float(t + 1)
            out[hub, t + 1] = acc


@_jit()
def _choose(current: int, speed: float, draws: Any, low: Any, high: Any, slowest: int, fastest: int) -> int:
    """synthesis._choose for one character (``low``, ``high``: synthesis.coverage)."""
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
        if current == fastest:
            return current
        pick = fastest  # the only one covered
    if cover_current:
        return current
    return current + (1 if pick > current else (-1 if pick < current else 0))


@_jit()
def _schedule(tb_frames: Any, tr_kind: Any, entry: Any, exit_: Any, total: Any, low: Any, high: Any,
              slowest: int, fastest: int, v: Any, travelled: Any, clocks: Any, draws: Any,
              step: int, ahead: int, creep: float, start: Any, kind: Any, first: Any) -> None:
    """synthesis.schedule for one character: ``start, kind, first (E,)`` filled."""
    T = v.shape[0]
    K = draws.shape[0]
    start[:] = _NEVER
    kind[:] = 0
    first[:] = 0
    start[0] = 0
    count, current, busy = 1, 0, 0
    for k in range(K):
        a = k * step
        nxt = _choose(current, v[min(a + ahead, T - 1)], draws[k], low, high, slowest, fastest)
        if not (busy < a + step and nxt != current):
            continue
        cur, new, last = current, nxt, count - 1
        d = max(a, busy)
        clock = clocks[cur]
        played = clock[d] - clock[start[last]]
        frames = tb_frames[cur]
        phase = int(math.floor(first[last] + played + 0.5)) % frames
        wait = 0 if cur == STATIC else (entry[cur, new] - phase) % frames
        tr = tr_kind[cur, new]
        resume = 0 if new == STATIC else (exit_[cur, new] + 1) % tb_frames[new]
        due = clock[d] + wait - 1e-9
        begin = len(clock)
        for t in range(d, len(clock)):
            if clock[t] >= due:
                begin = t
                break
        at = travelled[min(max(begin, 0), T - 1)]
        end = T + tb_frames[tr]
        for t in range(begin + 1, T):
            if travelled[t] - at + creep * (t - begin) >= total[tr]:
                end = t
                break
        start[last + 1], kind[last + 1], first[last + 1] = begin, tr, 0
        start[last + 2], kind[last + 2], first[last + 2] = end, new, resume
        count += 2
        busy = end
        current = new


@_jit()
def _row(kind: int, local: int, speed: float, walked: float, has_walked: bool, offset: Any, frames_of: Any,
         clips: Any, cyclic: Any, curve_at: Any, curves: Any) -> Any:
    """synthesis._rows for one (character, frame): (row 0, row 1, the second's weight)."""
    frames = frames_of[kind]
    if cyclic[kind]:
        frame = local % frames
    else:
        frame = min(max(local, 0), frames - 1)
    clip0 = 0
    weight = 0.0
    at, n = curve_at[kind, 0], curve_at[kind, 1]
    if n > 0:
        curve = curves[at:at + n]
        if cyclic[kind]:  # a gait: the clips around the speed
            u = _interp(speed, curve)
            clip0 = min(int(math.floor(u)), n - 2) if n > 1 else 0
            weight = u - clip0
        elif has_walked:  # a transition: the frames around the distance walked
            f = _interp(walked, curve)
            frame = min(int(math.floor(f)), n - 1)
            weight = f - frame
    clip1 = min(clip0 + 1, clips[kind] - 1)
    base = offset[kind] + frame
    step = clip1 * frames if cyclic[kind] else min(frame + 1, frames - 1) - frame
    return base + clip0 * frames, base + step, weight


@_jit()
def _frames(offset: Any, frames_of: Any, clips: Any, cyclic: Any, source: Any, target: Any, curve_at: Any,
            curves: Any, contacts_of: Any, margin: int, n_hubs: int, v: Any, travelled: Any, clocks: Any,
            creep: float, start: Any, kind_e: Any, first_e: Any, rows: Any, weights: Any, gait: Any,
            contacts: Any, stitches: Any) -> None:
    """The rest of synthesis.plan for one character: which piece plays each frame, its rows, the
    piece fading out, gait, contacts and stitches -- of the first ``rows.shape[0]`` frames (a
    first window's plan needs the schedule further, its rows not)."""
    T = v.shape[0]
    E = start.shape[0]
    e = 0
    for t in range(rows.shape[0]):
        moved = False
        while e + 1 < E and min(start[e + 1], T + 1) <= t:
            e += 1
            moved = True
        stitches[t] = moved and t >= 1
        kind = kind_e[e]
        row = min(kind, n_hubs)
        s0 = start[e]
        local = int(math.floor(first_e[e] + clocks[row, t] - clocks[row, min(max(s0, 0), T)] + 0.5))
        walked = travelled[t] - travelled[min(max(s0, 0), T - 1)] + creep * local
        r0, r1, w = _row(kind, local, v[t], walked, True, offset, frames_of, clips, cyclic, curve_at, curves)
        rows[t, 0], rows[t, 1], weights[t, 0] = r0, r1, w
        rows[t, 2], rows[t, 3], weights[t, 1] = r0, r1, w
        weights[t, 2] = 0.0
        since = t - s0
        if e >= 1 and since < margin:
            pk = kind_e[e - 1]
            pr = min(pk, n_hubs)
            p_local = int(math.floor(first_e[e - 1] + clocks[pr, t]
                                          - clocks[pr, min(max(start[e - 1], 0), T)] + 0.5))
            if not cyclic[pk]:  # a finished transition stays at its end
                p_local = np.iinfo(np.int32).max
            p0, p1, pw = _row(pk, p_local, v[t], 0.0, False, offset, frames_of, clips, cyclic, curve_at,
                              curves)
            u = (since + 1) / (margin + 1)
            rows[t, 2], rows[t, 3], weights[t, 1] = p0, p1, pw
            weights[t, 2] = 1 - u * u * (3 - 2 * u)
        first_half = (r0 - offset[kind]) < frames_of[kind] // 2
        gait[t] = source[kind] if first_half else target[kind]
        for f in range(4):
            contacts[t, f] = contacts_of[r0, f]


@_jit(parallel=True)
def _plan_all(offset: Any, frames_of: Any, clips: Any, cyclic: Any, source: Any, target: Any, tr_kind: Any,
              entry: Any, exit_: Any, total: Any, low: Any, high: Any, curve_at: Any, curves: Any,
              contacts_of: Any, slowest: int, fastest: int, max_rate: float, slow: float, share: float,
              margin: int, n_hubs: int, step: int, ahead: int, creep: float, v: Any, path: Any, h: Any,
              tempo: Any,
              draws: Any, workers: int, rows: Any, weights: Any, gait: Any, contacts: Any,
              stitches: Any) -> None:
    C, T = v.shape
    E = 1 + 2 * draws.shape[1]
    workers = min(C, workers)
    for worker in _prange(workers):
        clocks = np.empty((n_hubs + 1, T + 1))
        travelled = np.empty(T)
        start = np.empty(E, np.int64)
        kind = np.empty(E, np.int64)
        first = np.empty(E, np.int64)
        for c in range(worker, C, workers):
            _clocks(v[c], high, max_rate, slowest, slow, share, tempo[c], clocks)
            acc = 0.0
            travelled[0] = 0.0
            for t in range(1, T):
                dx = path[c, t, 0] - path[c, t - 1, 0]
                dz = path[c, t, 2] - path[c, t - 1, 2]
                acc += math.sqrt(dx * dx + dz * dz)
                travelled[t] = acc / h[c]
            _schedule(frames_of, tr_kind, entry, exit_, total, low, high, slowest, fastest, v[c],
                      travelled, clocks, draws[c], step, ahead, creep, start, kind, first)
            _frames(offset, frames_of, clips, cyclic, source, target, curve_at, curves, contacts_of, margin,
                    n_hubs, v[c], travelled, clocks, creep, start, kind, first, rows[c], weights[c], gait[c],
                    contacts[c], stitches[c])


def plan_frames(tb: Tables, contacts_of: NDArray[np.bool_], slowest: int, fastest: int, max_rate: float,
                slow: float, share: float, margin: int, step: int, ahead: int, creep: float,
                v: NDArray[np.float64], path: NDArray[np.float64], h: NDArray[np.float64],
                tempo: NDArray[np.float64], draws: NDArray[np.float64], frames: int | None = None
                ) -> tuple[NDArray[np.int32], NDArray[np.float32], NDArray[np.int8], NDArray[np.bool_],
                           NDArray[np.bool_]]:
    """A plan's ``rows, weights, gait, contacts, stitches`` (see ``synthesis.Plan``) for speeds
    ``v (C, T)`` (the library's unit), smoothed ``path (C, T, 3)``, scales ``h (C,)``, stride
    tempos ``tempo (C,)`` (synthesis.character_tempo) and each decision's draws ``(C, decisions,
    hubs)``; of the first ``frames`` frames (default: all T),
    the schedule made from all T."""
    if not AVAILABLE:
        raise RuntimeError("synth_core.compiled.plan_kernels needs numba; use the numpy backend")
    C, T = v.shape[0], v.shape[1] if frames is None else min(frames, v.shape[1])
    rows = np.empty((C, T, 4), np.int32)
    weights = np.empty((C, T, 3), np.float32)
    gait = np.empty((C, T), np.int8)
    contacts = np.empty((C, T, 4), bool)
    stitches = np.empty((C, T), bool)
    c = np.ascontiguousarray
    k = tb.kinds
    _plan_all(k.offset, k.frames, k.clips, k.cyclic, k.source, k.target, k.tr_kind, k.entry, k.exit, tb.total,
              tb.low, tb.high, tb.curve_at, tb.curves, contacts_of, slowest, fastest, max_rate, slow, share,
              margin, len(tb.low), step, ahead, creep, c(v, np.float64), c(path, np.float64),
              c(h, np.float64), c(tempo, np.float64), c(draws), numba.get_num_threads(), rows, weights, gait,
              contacts, stitches)
    return rows, weights, gait, contacts, stitches


# --- the live mode's blocks (synth_core.runtime.live) --------------------------------------------------
#
# The live plan carries each character's pieces in a few slots (start frame, kind, first clip
# frame, the kind's clock and the distance at its start) from block to block; its numpy
# reference is LiveSynth._scan and LiveSynth._block_rows. Here, as above, one character at a
# time in parallel, in the reference's operations and order: the plans are equal bit for bit.

@_jit()
def _live_scan(c: int, t0: int, n: int, v: Any, pts: Any, h: float, tempo: float, high: Any, max_rate: float,
               slowest: int, slow: float, share: float, n_hubs: int, creep: float, total: Any, clock_in: Any,
               walked_in: Any, start: Any, kind: Any, clock0: Any, trav0: Any, busy: Any, clocks: Any,
               walked: Any) -> None:
    """Frames [t0, t0 + n) of character c: its clocks ``(n_hubs + 1, n + 1)`` and distance
    ``(n + 1,)`` from the carried ones; the distance at their start of pieces starting there;
    the end of a transition under way, if it is there (LiveSynth._start_distances and
    _end_transitions)."""
    never = _NEVER
    for hub in range(n_hubs + 1):
        if hub < len(high) and high[hub] > -np.inf and hub != STATIC:
            acc = clock_in[hub, c]
            clocks[hub, 0] = acc
            for t in range(n):
                acc += _rate(v[t], hub, high, max_rate, slowest, slow, share) * tempo
                clocks[hub, t + 1] = acc
        else:  # plain time
            for t in range(n + 1):
                clocks[hub, t] = float(t0 + t)
    acc = walked_in[c]
    walked[0] = acc
    for t in range(n):
        dx = pts[t + 1, 0] - pts[t, 0]
        dz = pts[t + 1, 2] - pts[t, 2]
        acc += math.sqrt(dx * dx + dz * dz)
        walked[t + 1] = acc
    S = start.shape[1]
    for j in range(1, S):
        s = start[c, j]
        if s >= t0 and s < t0 + n:
            trav0[c, j] = walked[s - t0]
    if busy[c] != never:
        return
    j = 0  # the slot before the gait not started yet (the transition's)
    for k in range(1, S):
        if start[c, k] == never:
            j = k - 1
            break
    b = start[c, j]
    if b >= t0 + n:
        return
    at = trav0[c, j] / h
    for t in range(n):
        if (walked[t] / h - at) + creep * float(t0 + t - b) >= total[kind[c, j]] and t0 + t > b:
            start[c, j + 1] = t0 + t
            clock0[c, j + 1] = clocks[min(kind[c, j + 1], n_hubs), t]
            trav0[c, j + 1] = walked[t]
            busy[c] = t0 + t
            return


@_jit(parallel=True)
def _live_block(offset: Any, frames_of: Any, clips: Any, cyclic: Any, source: Any, target: Any, total: Any,
                high: Any, curve_at: Any, curves: Any, contacts_of: Any, max_rate: float, slowest: int,
                slow: float, share: float, margin: int,
                n_hubs: int, creep: float, t0: int, v: Any, pts: Any, h: Any, tempo: Any, clock: Any,
                walked_in: Any,
                start: Any, kind: Any, first: Any, clock0: Any, trav0: Any, before: Any, busy: Any,
                with_rows: bool, out_step: int, workers: int, rows: Any, weights: Any, gait: Any,
                contacts: Any, stitches: Any, walked_out: Any) -> None:
    C, n = v.shape
    S = start.shape[1]
    workers = min(C, workers)
    for worker in _prange(workers):
        clocks = np.empty((n_hubs + 1, n + 1))
        walked = np.empty(n + 1)
        for c in range(worker, C, workers):
            hc = h[c]
            _live_scan(c, t0, n, v[c], pts[c], hc, tempo[c], high, max_rate, slowest, slow, share, n_hubs,
                       creep, total, clock,
                       walked_in, start, kind, clock0, trav0, busy, clocks, walked)
            walked_out[c] = walked[n]
            if not with_rows:
                continue
            for hub in range(n_hubs + 1):
                clock[hub, c] = clocks[hub, n]
            # The frame's rows, fade, gait and contacts below are _frames' too, written twice on
            # purpose: shared as one function (its tables and outputs as arguments), the batch
            # plan took 1.7x as long (_frames 0.067 -> 0.117 us a character-frame, even inlined).
            for tt in range(-t0 % out_step, n, out_step):  # the frames sent: multiples of out_step
                t = t0 + tt
                i = tt // out_step  # its row in the outputs
                e = 1  # the slot playing: the last started
                for j in range(2, S):
                    if t >= start[c, j]:
                        e += 1
                k = kind[c, e]
                local = int(math.floor(float(first[c, e]) + clocks[min(k, n_hubs), tt] - clock0[c, e] + 0.5))
                ws = (walked[tt] / hc - trav0[c, e] / hc) + creep * float(local)
                r0, r1, w = _row(k, local, v[c, tt], ws, True, offset, frames_of, clips, cyclic, curve_at,
                                 curves)
                rows[c, i, 0], rows[c, i, 1], weights[c, i, 0] = r0, r1, w
                rows[c, i, 2], rows[c, i, 3], weights[c, i, 1] = r0, r1, w
                weights[c, i, 2] = 0.0
                since = t - start[c, e]
                if (e >= 2 or before[c]) and since < margin:  # the piece before fades out
                    pk = kind[c, e - 1]
                    p_local = int(math.floor(float(first[c, e - 1]) + clocks[min(pk, n_hubs), tt]
                                             - clock0[c, e - 1] + 0.5))
                    if not cyclic[pk]:  # a finished transition stays at its end
                        p_local = np.iinfo(np.int32).max
                    p0, p1, pw = _row(pk, p_local, v[c, tt], 0.0, False, offset, frames_of, clips, cyclic,
                                      curve_at, curves)
                    u = (since + 1) / (margin + 1)
                    rows[c, i, 2], rows[c, i, 3], weights[c, i, 1] = p0, p1, pw
                    weights[c, i, 2] = 1 - u * u * (3 - 2 * u)
                first_half = (r0 - offset[k]) < frames_of[k] // 2
                gait[c, i] = source[k] if first_half else target[k]
                for f in range(4):
                    contacts[c, i, f] = contacts_of[r0, f]
                stitch = False
                if t >= 1:
                    for j in range(1, S):
                        stitch = stitch or start[c, j] == t
                stitches[c, i] = stitch


def live_block(tb: Tables, contacts_of: NDArray[np.bool_], max_rate: float, slowest: int, slow: float,
               share: float, margin: int, creep: float,
               t0: int, v: NDArray[np.float64], pts: NDArray[np.float64], h: NDArray[np.float64],
               tempo: NDArray[np.float64], clock: NDArray[np.float64], walked: NDArray[np.float64],
               slots: tuple[NDArray[Any], ...], before: NDArray[np.bool_], busy: NDArray[np.int64],
               out: tuple[NDArray[Any], ...] | None, out_step: int = 1) -> NDArray[np.float64]:
    """Frames ``[t0, t0 + n)`` of a live plan (``v (C, n)`` speeds, ``pts (C, n + 1, 3)`` path):
    the pieces' ``slots`` (start, kind, first, clock0, trav0, each ``(C, SLOTS)``) and ``busy``
    brought up to date; with ``out`` (rows, weights, gait, contacts, stitches, each ``(C, n',
    ...)``) the rows of the frames sent -- those a multiple of ``out_step``, n' of them -- too,
    and ``clock (kinds, C)`` carried on to ``t0 + n``. Returns the distance walked at ``t0 + n``
    (to carry when ``out`` is given)."""
    if not AVAILABLE:
        raise RuntimeError("synth_core.compiled.plan_kernels needs numba; use the numpy backend")
    C, n = v.shape
    walked_out = np.empty(C)
    with_rows = out is not None
    if out is None:
        none = np.empty((C, 0, 4), np.int32)
        out = (none, np.empty((C, 0, 3), np.float32), np.empty((C, 0), np.int8), np.empty((C, 0, 4), bool),
               np.empty((C, 0), bool))
    k = tb.kinds
    start, kind, first, clock0, trav0 = slots
    rows, weights, gait, contacts, stitches = out
    sent = -(-(t0 + n) // out_step) - -(-t0 // out_step)
    assert not with_rows or all(a.shape[:2] == (C, sent) for a in out), "out: a row per frame sent"
    _live_block(k.offset, k.frames, k.clips, k.cyclic, k.source, k.target, tb.total, tb.high, tb.curve_at,
                tb.curves, contacts_of, max_rate, slowest, slow, share, margin, len(tb.low), creep, t0, v,
                pts, h, tempo, clock, walked, start, kind, first, clock0, trav0, before, busy, with_rows,
                out_step, numba.get_num_threads(), rows, weights, gait, contacts, stitches, walked_out)
    return walked_out


@_jit()
def _points_fine(last: Any, pts: Any, limit: float) -> bool:
    ok = True
    for c in range(pts.shape[0]):
        px, py, pz = last[c, 0], last[c, 1], last[c, 2]
        for i in range(pts.shape[1]):
            x, y, z = pts[c, i, 0], pts[c, i, 1], pts[c, i, 2]
            dx, dy, dz = x - px, y - py, z - pz
            ok = ok and math.isfinite(x) and math.isfinite(y) and math.isfinite(z)
            # A NaN last point means none before (a session's first points): no jump to check,
            # and any comparison with NaN is false, so isnan is asked first.
            ok = ok and (math.isnan(px) or dx * dx + dy * dy + dz * dz <= limit * limit)
            px, py, pz = x, y, z
    return ok


def live_points_fine(last: NDArray[np.float64], pts: NDArray[np.float64], limit: float) -> bool:
    """Whether every point of ``pts (C, n, 3)`` is finite and within ``limit`` of the one before
    (``last (C, 3)``: each character's point before them; NaN: none). False sends a caller to its
    own checks for what is wrong and where (:meth:`synth_core.runtime.live.LiveSynth.check`, whose numpy
    took a millisecond of a 2,000-horse tick's serial part)."""
    if not AVAILABLE:
        raise RuntimeError("synth_core.compiled.plan_kernels needs numba; use the numpy backend")
    return bool(_points_fine(np.ascontiguousarray(last, np.float64), np.ascontiguousarray(pts, np.float64),
                             float(limit)))


@_jit()
def _live_headings(pts: Any, off: int, fps: float, min_speed: float, last_dir: Any, moved: Any,
                   yaw: Any, never: Any) -> None:
    n = yaw.shape[1]
    m = pts.shape[1]
    for c in range(pts.shape[0]):
        hx, hz = last_dir[c, 0], last_dir[c, 1]
        first = -1
        for i in range(n):
            j = off + i
            if m < 2:
                dx = dz = 0.0
            elif j == 0:
                dx, dz = pts[c, 1, 0] - pts[c, 0, 0], pts[c, 1, 1] - pts[c, 0, 1]
            elif j == m - 1:
                dx, dz = pts[c, j, 0] - pts[c, j - 1, 0], pts[c, j, 1] - pts[c, j - 1, 1]
            else:
                dx = (pts[c, j + 1, 0] - pts[c, j - 1, 0]) / 2.0  # np.gradient's central difference
                dz = (pts[c, j + 1, 1] - pts[c, j - 1, 1]) / 2.0
            if math.sqrt(dx * dx + dz * dz) * fps >= min_speed:
                hx, hz = dx, dz
                if first < 0:
                    first = i
            yaw[c, i] = math.atan2(hx, hz)
        never[c] = not moved[c] and first < 0
        if first >= 0:
            if not moved[c]:  # starts moving in this block: before, it faces that way
                for i in range(first):
                    yaw[c, i] = yaw[c, first]
            last_dir[c, 0], last_dir[c, 1] = hx, hz
            moved[c] = True


def live_headings(pts: NDArray[np.float64], off: int, n: int, fps: float, min_speed: float,
                  last_dir: NDArray[np.float64], moved: NDArray[np.bool_]) -> tuple[NDArray[np.float64],
                                                                                  NDArray[np.bool_]]:
    """A live block's yaw ``(C, n)``, as :meth:`synth_core.runtime.live.LiveSynth._headings` makes it:
    ``pts (C, m, 2)`` the path's ground coordinates around the block (its frame 0 at ``pts``'
    ``off``); ``last_dir`` and ``moved`` carried on. Also which characters have not moved yet
    (their yaw, the known path's first move, is the caller's)."""
    if not AVAILABLE:
        raise RuntimeError("synth_core.compiled.plan_kernels needs numba; use the numpy backend")
    C = pts.shape[0]
    yaw, never = np.empty((C, n)), np.empty(C, np.bool_)
    _live_headings(np.ascontiguousarray(pts), off, fps, min_speed, last_dir, moved, yaw, never)
    return yaw, never
