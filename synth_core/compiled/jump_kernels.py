"""A foot target's one-frame jumps eased into ramps (issue 27's jump target, issue 28's paws).

Every cause of a foot jumping in one frame at a stitch (docs/stitch_jumps.md: a held transition
fading out, a clip frame skipped at a contact change, settling pinning a raised hoof, a
transition played far faster than its clip) ends up as the same thing in the foot lock: a step
of a foot's target much longer than the steps either side of it. :func:`ease_jumps` finds those
in the targets :func:`~synth_core.compiled.foot_kernels.plant_targets` made and spreads each
one's excess over the swing frames around it, eased; planted frames are never moved.
"""

from __future__ import annotations

import math
from typing import Any

from synth_core.compiled.jit import render_jit
from synth_core.compiled.replant_kernels import step_over, stood
from synth_core.compiled.vec_kernels import smoothstep
from synth_core.runtime.footlock import JUMP_EASE, SWING_CLEAR, SWING_MOVING

CARRY_FRAMES = 6  # a low-latency window's offset from the frame sent fades over so many frames
CARRY_CLEAR = 0.025  # metres: a swing frame under this carries none of it, twice this all

_jit = render_jit


@_jit(inline="always")
def _step(out: Any, f: int, t: int, k: int) -> float:
    """Axis k of foot f's target step from frame t - 1 to frame t."""
    return float(out[t, f, k] - out[t - 1, f, k])


@_jit(inline="always")
def _beyond(out: Any, f: int, t: int, k: int) -> float:
    """Axis k of foot f's step into frame t beyond the mean of the steps before and after it."""
    return _step(out, f, t, k) - 0.5 * (_step(out, f, t - 1, k) + _step(out, f, t + 1, k))


@_jit()
def _lengths(out: Any, f: int, a: int, b: int, lengths: Any) -> None:
    """``lengths[t]``: how far foot f's target moves from frame t - 1 to frame t, for t in [a, b).
    Each step's length once: an excess (:func:`_excess`) reads three of them."""
    for t in range(max(a, 1), b):
        x, y, z = _step(out, f, t, 0), _step(out, f, t, 1), _step(out, f, t, 2)
        lengths[t] = math.sqrt(x * x + y * y + z * z)


@_jit(inline="always")
def _excess(lengths: Any, t: int) -> float:
    """How much longer the step into frame t is than the mean of the steps before and after it
    (metrics.one_frame_jumps_mm, in the targets' unit; ``lengths``: :func:`_lengths`)."""
    return float(lengths[t] - 0.5 * (lengths[t - 1] + lengths[t + 1]))


@_jit()
def _worst(lengths: Any, a: int, b: int) -> float:
    """The largest :func:`_excess` of the steps into frames [a, b] (those within the path)."""
    worst = -math.inf
    for t in range(max(a, 2), min(b, lengths.shape[0] - 2) + 1):
        worst = max(worst, _excess(lengths, t))
    return worst


@_jit(inline="always")
def _ground_step(out: Any, f: int, t: int) -> float:
    """How far foot f's target moves over the ground (x, z) from frame t - 1 to frame t."""
    return math.hypot(_step(out, f, t, 0), _step(out, f, t, 2))


@_jit()
def _floor(out: Any, down: Any, f: int, lo: int, hi: int, u: int, clear: float) -> float:
    """The height foot f's frame u in the swing (lo, hi) may be lowered to at least while it moves
    over the ground: ``clear`` over its plants' (frames lo and hi, those of them planted; between,
    their heights interpolated: a plant's height is its foot's standing one), or none (-inf: no
    plant either side)."""
    if down[lo] and down[hi]:
        w = (u - lo) / (hi - lo)
        return float((1.0 - w) * out[lo, f, 1] + w * out[hi, f, 1]) + clear
    if down[lo] or down[hi]:
        return float(out[lo if down[lo] else hi, f, 1]) + clear
    return -math.inf


@_jit()
def _ramp(out: Any, down: Any, f: int, t: int, a: int, b: int, swing: Any) -> None:
    """Foot f's step into frame t made the mean of the steps either side (its excess over that,
    a vector: taken off, the step is no longer than their mean length), the excess eased in
    instead over frames (a, b): a smoothstep from a to b put on, the jump (a step function at
    t) taken off. Its vertical part last, and lowering no frame moving over the ground more than
    SWING_MOVING a frame (its ground step into it or out of it, as eased) under :func:`_floor`
    (nor, if it was under it, at all). ``swing``: the swing's (lo, hi) and the scale h."""
    lo, hi, h = swing
    moving = SWING_MOVING / h
    for k in (0, 2, 1):
        x = _beyond(out, f, t, k)
        for u in range(a + 1, b):
            d = (smoothstep((u - a) / (b - a)) - (1.0 if u >= t else 0.0)) * x
            if k == 1 and d < 0.0 and max(_ground_step(out, f, u), _ground_step(out, f, u + 1)) > moving:
                d = min(max(d, _floor(out, down, f, lo, hi, u, SWING_CLEAR / h) - out[u, f, 1]), 0.0)
            out[u, f, k] += d


@_jit(inline="always")
def _dist(a: Any, b: Any) -> float:
    """How far apart points a and b are (3D)."""
    return math.hypot(math.hypot(float(a[0] - b[0]), float(a[1] - b[1])), float(a[2] - b[2]))


@_jit(inline="always")
def _seg(path: Any, lo: int, hi: int, i: int, ends: Any) -> float:
    """Step i of the swing (lo, hi) along ``path``: from frame lo + i - 1 to lo + i; step 0 and
    step hi - lo + 1 (into lo, out of hi) are ``ends``."""
    if i <= 0:
        return float(ends[0])
    if i > hi - lo:
        return float(ends[1])
    return _dist(path[lo + i], path[lo + i - 1])


@_jit()
def _reshape(path: Any, lo: int, hi: int, ends: Any, bound: float) -> Any:
    """How the swing (lo, hi)'s steps along ``path`` are reshaped (:func:`_retime`): the jump e
    every step of the parabola has, and the share of the way to it (0: its own steps; 1: the
    parabola's) that brings every step's jump within ``bound`` (the least: the swing keeps as
    much of its own progress as it can, a touchdown's slowing down); -1, none (a parabola
    stepping backwards: the swing is slow for its distance, it does not jump)."""
    n, length = hi - lo, 0.0
    for i in range(1, n + 1):
        length += _seg(path, lo, hi, i, ends)
    s0, s1 = ends
    e = (length - 0.5 * n * (s0 + s1)) * 6.0 / (n * (n + 1) * (n + 2))
    if s0 + (s1 - s0) * n / (n + 1) + e * n < 0.0 or s1 + (s0 - s1) * n / (n + 1) + e * n < 0.0:
        return e, -1.0
    share = 0.0
    for i in range(1, n + 1):
        x = _seg(path, lo, hi, i, ends)
        x -= 0.5 * (_seg(path, lo, hi, i - 1, ends) + _seg(path, lo, hi, i + 1, ends))
        if x > bound:
            share = max(share, (x - bound) / (x - e) if x > e else 1.0)
    return e, min(share, 1.0)


@_jit()
def _retime(out: Any, f: int, lo: int, hi: int, path: Any, bound: float) -> None:
    """Foot f's swing frames (lo, hi) moved along its own path (the targets ``out[lo:hi + 1, f]``
    joined by straight lines, copied into ``path``), its steps taken towards those whose every
    one jumps out of the mean of its neighbours by the same e: s_i = s_0 + (s_n+1 - s_0) i / (n
    + 1) + e i (n + 1 - i) (a parabola: second difference -2e), s_0 and s_n+1 the steps into lo
    and out of hi (kept), e such that they sum to the path's length -- the least any progress
    along it can jump -- as far as brings each step within ``bound`` (:func:`_reshape`). Issue
    27: a swing too short for its distance, a start from a stand played fast, 3 frames over 53
    cm stepping 10 20 19 4 cm, becomes 11 16 16 10."""
    T, n = out.shape[0], hi - lo
    path[lo:hi + 1] = out[lo:hi + 1, f]
    ends = (_dist(out[lo, f], out[lo - 1, f]) if lo >= 1 else 0.0,
            _dist(out[hi + 1, f], out[hi, f]) if hi + 1 < T else 0.0)
    e, share = _reshape(path, lo, hi, ends, bound)
    if share <= 0.0:
        return
    s0, s1 = ends
    at, j, walked = 0.0, lo + 1, 0.0  # arc length to frame u's new place; segment j - 1 -> j
    for i in range(1, n):
        seg = _dist(path[j], path[j - 1])
        parabola = s0 + (s1 - s0) * i / (n + 1) + e * i * (n + 1 - i)
        at += (1.0 - share) * _seg(path, lo, hi, i, ends) + share * parabola
        while j < hi and walked + seg < at:
            walked += seg
            j += 1
            seg = _dist(path[j], path[j - 1])
        w = min(max((at - walked) / seg, 0.0), 1.0) if seg > 0.0 else 1.0
        for k in range(3):
            out[lo + i, f, k] = path[j - 1, k] + w * (path[j, k] - path[j - 1, k])


@_jit()
def _clear_retime(out: Any, down: Any, f: int, swing: Any, saved: Any, bound: float, lengths: Any) -> None:
    """Foot f's swing (lo, hi) retimed (:func:`_retime`) but for its frames at either end still
    within SWING_CLEAR of its plants' height (:func:`_floor`): a lift-off or touchdown skimming
    the ground keeps its own slow steps there (the real dog's gallop: its first swing frame 6-8
    mm up, sped up 26 -> 49 mm a frame, read as a plant skating); kept only if the worst step
    of the swing got better. ``lengths``: :func:`_lengths` of ``out``, kept so."""
    lo, hi, h = swing
    a, b = lo, hi
    while a + 1 < b and out[a + 1, f, 1] < _floor(out, down, f, lo, hi, a + 1, SWING_CLEAR / h):
        a += 1
    while b - 1 > a and out[b - 1, f, 1] < _floor(out, down, f, lo, hi, b - 1, SWING_CLEAR / h):
        b -= 1
    if b - a < 2:
        return
    before = _worst(lengths, lo, hi + 1)
    _retime(out, f, a, b, saved, bound)
    _lengths(out, f, a + 1, b + 1, lengths)  # the steps into the frames it moved, (a, b)
    if _worst(lengths, lo, hi + 1) >= before:
        out[a:b + 1, f] = saved[a:b + 1]
        _lengths(out, f, a + 1, b + 1, lengths)


@_jit()
def step_lengths(out: Any, f: int, lengths: Any) -> None:
    """``lengths[t]``: how far foot f's target moves from frame t - 1 to frame t, for every t from
    1 on (:func:`widen_swings` reads them so, as :func:`ease_jumps` leaves them)."""
    _lengths(out, f, 1, out.shape[0], lengths)


@_jit()
def ease_jumps(out: Any, down: Any, f: int, h: float, saved: Any, first: int, lengths: Any) -> bool:
    """Foot f's targets ``out (T, 4, 3)`` with every step longer than the mean of the steps before
    and after it by more than ``bound`` (JUMP_EASE over the scale ``h``) made that mean, its
    excess spread instead over the frames around it that are not planted (``down (T,)``: its
    planted frames): a smoothstep ramp over
    enough of them that no frame takes more than ``bound`` of it (1.5 / n of the excess over n
    frames at the ramp's steepest), centred on the step, as many as its swing holds (its vertical
    part bringing no frame moving over the ground down near it: :func:`_ramp`). A step into
    a plant's first frame (a raised hoof pinned down at once) so ramps over the frames before
    it; a step out of a plant, over those after. A ramp that leaves a step around it jumping as
    far as before or further is not made (a swing of a frame or two between plants far apart:
    no frames to spread it over); where a step still jumps past ``bound`` either way (that, or
    a touchdown slowing faster than a ramp can ease: the ramp moves the jump a frame back), the
    swing's progress along its path is reshaped, if its next plant is known (:func:`_retime`,
    kept only if it helps). Scanned forward, each step read as the ramps before it left
    it. Reads the swing the step is in and its plants' frames either side only (a live window's
    foot-lock context holds them: kernels.lock_context). ``saved (T, 3)``: scratch; ``lengths
    (T,)``: left holding :func:`step_lengths` of the targets eased (each ramp re-measures the
    steps it moved), which :func:`widen_swings` reads rather than measure them again. ``first``:
    frames before it are never moved (a live window's frames sent already: a step into a frame
    sent is left, a ramp that would reach back past ``first`` is shortened to the frames after).
    Returns whether a step may still jump past ``bound`` (a ramp left one, or none was made)."""
    T, bound = out.shape[0], JUMP_EASE / h
    _lengths(out, f, 1, T, lengths)
    left = False
    for t in range(max(2, first), T - 1):
        if (down[t - 1] and down[t]) or _excess(lengths, t) <= bound:
            continue
        lo, hi = t - 1, t  # the frames free to move: (lo, hi), lo and hi planted, sent or the ends
        while lo > max(first - 1, 0) and not down[lo]:
            lo -= 1
        while hi < T - 1 and not down[hi]:
            hi += 1
        ex = 0.0
        for k in range(3):
            ex = math.hypot(ex, _beyond(out, f, t, k))
        n = max(int(math.ceil(1.5 * ex / bound)), 2)
        a = max(lo, t - 1 - (n - 1) // 2)
        b = min(hi, a + n)
        a = max(lo, b - n)
        before = _worst(lengths, a, b + 1)
        saved[a:b + 1] = out[a:b + 1, f]
        _ramp(out, down, f, t, a, b, (lo, hi, h))
        _lengths(out, f, a + 1, b + 1, lengths)  # the steps into the frames it moved, (a, b)
        after = _worst(lengths, a, b + 1)
        if after >= before:
            out[a:b + 1, f] = saved[a:b + 1]
            _lengths(out, f, a + 1, b + 1, lengths)
        jumps = min(after, before) > bound
        if jumps and down[hi]:  # a ramp cannot ease it: the swing's progress reshaped
            _clear_retime(out, down, f, (lo, hi, h), saved, bound, lengths)
            jumps = _worst(lengths, lo, hi + 1) > bound
        left = left or jumps
    return left


@_jit()
def ease_unsent(out: Any, down: Any, f: int, h: float, scratch: Any, last: int, first: int,
                 sent: Any) -> None:
    """Foot f's targets' one-frame jumps eased (:func:`ease_jumps`) on the frames of a live
    window in the low-latency mode not sent yet (from frame ``first`` on). ``sent``: ``(kept (2,
    4, 3), at)``: the targets of frames ``at - 1``, ``at`` as sent (if ``at`` is ``first - 1``),
    put back on those frames first: recomputed, a sent swing's frames may lie elsewhere (its
    next plant came since) and a ramp an earlier window began was sent in part, so the frames
    here are eased on from where the foot was sent (sent, a frame stays), its first swing frames
    carrying the offset of the frame sent (:func:`_carry`); put back after (the
    sink and the pins read the sent frames' targets as before). The targets of frames ``last -
    1``, ``last`` (the window's last, sent now) are then kept there for the next one.
    ``scratch``: ``(saved (T + 4, 3), lengths (T,))``."""
    kept, at = sent
    saved, lengths = scratch
    T = out.shape[0]
    here, now = saved[T:T + 2], saved[T + 2:T + 4]
    anchored = first >= 2 and at == first - 1
    if anchored:
        here[:] = out[first - 2:first, f]
        out[first - 2:first, f] = kept[:, f]
        _carry(out, down, f, first, here[1], h)
    ease_jumps(out, down, f, h, saved, first, lengths)
    if last >= 1:
        now[:] = out[last - 1:last + 1, f]
    if anchored:
        out[first - 2:first, f] = here
    if last >= 1:
        kept[:, f] = now


@_jit()
def _carry(out: Any, down: Any, f: int, first: int, raw: Any, h: float) -> None:
    """Foot f's swing frames from ``first`` on moved by how far its frame ``first - 1`` was sent
    from where this window has it (``raw``), the offset fading out (smoothstep) over CARRY_FRAMES:
    each window starts again from the targets it makes, and the ramps that eased the frames sent
    left them behind those (a swing's steps uneven frame to frame, the clip sampled between its
    frames: 20.7 cm sent, then 30.2 into the next window's first frame). None of it is carried
    by a frame under CARRY_CLEAR over the ground, all of it at twice that (carried down there, a
    lift-off's or touchdown's frames moved near the ground: the low-latency dog's jitter glide
    0.116 -> 0.141). Planted frames keep their plants; the offset stops at the first.
    CARRY_FRAMES counts the library's frames (a window's)."""
    T = out.shape[0]
    for u in range(first, min(first + CARRY_FRAMES, T)):
        if down[u]:
            return
        w = 1.0 - smoothstep((u - first + 1) / CARRY_FRAMES)
        w *= min(max(out[u, f, 1] * h / CARRY_CLEAR - 1.0, 0.0), 1.0)  # (none moved near the ground)
        for k in range(3):
            out[u, f, k] += w * (out[first - 1, f, k] - raw[k])


@_jit()
def _wider(out: Any, down: Any, air: Any, f: int, lo: int, hi: int, bound: float, height: float) -> Any:
    """The frames (a, b) foot f's swing (lo, hi) is widened to by taking frames off the ends of
    its plants either side, a frame at a time, in turn before and after, while each keeps a frame and
    two other feet stand on the frame taken (``air``): until a step over the widened swing,
    its progress a parabola (:func:`_retime`), jumps no more than ``bound`` a frame (its path:
    the plants' distance plus the lift there and back, ``height``)."""
    T = out.shape[0]
    length = _dist(out[lo, f], out[hi, f]) + 2.0 * height
    a, b = lo, hi
    while True:
        n = b - a
        if length * 6.0 / (n * (n + 1) * (n + 2)) <= bound:
            return a, b
        before = a >= 2 and down[a - 1] and stood(air, f, a, a + 1)
        after = b + 2 < T and down[b + 1] and stood(air, f, b, b + 1)
        if before and (n % 2 == 0 or not after):
            a -= 1
        elif after:
            b += 1
        else:
            return a, b


@_jit()
def widen_swings(out: Any, down: Any, air: Any, f: int, h: float, height: float, saved: Any,
                 lengths: Any) -> None:
    """Foot f's swings between two plants whose targets still jump further than JUMP_EASE over
    the scale ``h`` in a frame once eased (:func:`ease_jumps`: a swing of a frame or two between
    plants far apart, a transition played at 4-8x its clip to a stop -- issue 27's accel_brake,
    66 cm in 2 frames), widened into the frames of its plants (:func:`_wider`: lifted off
    earlier, set down later, other feet standing) and made a step over them, ``height`` high
    (``replant_kernels.step_over``), its progress retimed (:func:`_retime`); kept only if its
    worst step got better. ``down``, ``air`` unmarked / marked where the foot is now up.
    ``saved (T, 3)``: scratch; ``lengths (T,)``: :func:`step_lengths` of ``out`` (as ease_jumps
    leaves them: measured once, not again here), kept so."""
    T, bound = out.shape[0], JUMP_EASE / h
    t = 1
    while t < T - 1:
        if down[t]:
            t += 1
            continue
        lo, hi = t - 1, t
        while hi < T - 1 and not down[hi]:
            hi += 1
        t = hi
        if not (down[lo] and down[hi]) or _worst(lengths, lo, hi + 1) <= bound:
            continue
        a, b = _wider(out, down, air, f, lo, hi, bound, height)
        if b - a <= hi - lo:
            continue
        before = _worst(lengths, a, b + 1)
        kept = out[a:b + 1, f].copy()
        step_over(out, f, a + 1, b, height)
        _retime(out, f, a, b, saved, bound)
        _lengths(out, f, a + 1, b + 1, lengths)  # the steps into the frames it moved, (a, b)
        if _worst(lengths, a, b + 1) >= before:
            out[a:b + 1, f] = kept
            _lengths(out, f, a + 1, b + 1, lengths)
            continue
        down[a + 1:b] = False
        air[a + 1:b, f] = True
