"""The render's feet: the feet measured, plant targets, the root's sink, targets on a terrain;
the foot lock's context.

Passes 2 and 3 of ``synth_core.compiled.kernels._character`` for one character (the foot lock:
:mod:`synth_core.runtime.footlock`): :func:`measure_feet`, :func:`plant_targets`,
:func:`reach_sink`, :func:`ease_sink` and
:func:`ground_targets` (on a terrain: :mod:`synth_core.runtime.terrain`); :func:`lock_contexts`,
the frames a window's foot lock reads.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from synth_core.compiled.ground_kernels import ground_at
from synth_core.compiled.jit import render_jit
from synth_core.compiled.jump_kernels import ease_jumps, ease_unsent, widen_swings
from synth_core.compiled.limb_kernels import unit4, world_position
from synth_core.compiled.pose_kernels import lean_tilt
from synth_core.compiled.replant_kernels import (
    LEG_REACH,
    LEG_THIGH,
    LEG_TOE,
    LEG_UP,
    from_hip,
    replant,
    sink_within,
    strays,
)
from synth_core.compiled.replant_kernels import LEG_WIDTH as LEG_WIDTH  # (callers ask foot_kernels)
from synth_core.compiled.replant_kernels import NOWHERE as NOWHERE
from synth_core.compiled.replant_kernels import no_steps as no_steps
from synth_core.compiled.swing_kernels import swings
from synth_core.compiled.vec_kernels import conj, norm3, q4, qmul, qrot, v3, vadd, vscale, vsub
from synth_core.runtime.footlock import (
    EASE_FRAMES,
    LIFTED_PLANT,
    LONGEST_OVER,
    PLANTED_SLACK,
    PLANTED_UP,
    REACH,
    STEP_HEIGHT,
)

_jit = render_jit


@_jit()
def plant_targets(feet: Any, soles: Any, contacts: Any, out: Any, most: int, pins: Any, pinned: Any,
                  last: int, body: Any) -> Any:
    """Foot targets ``out (T, 4, 3)`` of one character from its feet ``(T, 4, 3)``, their heights
    as its clips stand them (``soles (T, 4)``: pose_kernels.clip_soles) and ``contacts (T, 4)``:
    each plant where the foot stands (:func:`_plants`); a swing on its own path plus a correction
    eased (smoothstep) from its last plant's at lift-off to its next's, clear of the ground (swing_kernels).
    ``most``: a plant's position averages its first so many frames at most (and, ``most`` < T, a
    swing before no plant eases its correction out as there). A target's one-frame jump is then
    eased into a ramp over the swing frames around it (:func:`ease_jumps`; where ``most`` < T,
    whose swings are sent before their next plant is planned, in a live window only (``last`` >=
    0), on its frames not sent yet, from the targets sent: :func:`ease_unsent`, ``body``'s last);
    in a batch, a swing with no frames for one widened into its plants' ends (:func:`widen_swings`).

    A plant the body's turn carries out of its leg's reach (a body turning on the spot over a
    standing foot: :func:`~synth_core.compiled.replant_kernels.replant`) is stepped instead: split
    into plants each within reach, the foot lifted between them. ``body``: ``bends (4, 6)`` (per
    leg its longest reach, column 4, the unit's, and a step's frames, column 5: 0, no steps),
    ``legs (T, 4, LEG_WIDTH)`` (what the sink reads of each leg), the sink's bound (a target
    needing more is out of reach), the first frame posed (earlier ones count as in reach), the
    path ``(T, 3)`` and the share of its height added to a foot's for the legs (on a terrain the
    feet's heights are over the body's ground: 1 / h; else 0), the body's yaw ``(T,)`` and root
    ``(T, 3)`` (world), the scale h, whether to step at all (kernels.render_window's ``steps``),
    the window's first frame and the targets sent (:func:`ease_unsent`'s ``first``, ``sent``).

    ``pins (4, 3)``, ``pinned (4,)``: foot f's plant through frame ``pinned[f]`` (if that is one
    of its planted frames) is at ``pins[f]`` over the ground, whatever its frames here average:
    where an earlier window sent it (a live window's context may have lost that plant's first
    frames). Its height is still its frames' here: a stand begun with a foot still coming down
    (braking from a canter, 3-5 cm up) puts it down as its first frames leave the context, where
    pinned it would hover the whole stand. Then, for ``last`` >= 0, the same of each foot's last
    plant up to frame ``last``: the one it is in, or the one before its swing (whose lift-off
    correction the swing eases out).

    Returns ``air (T, 4)``: each foot's frames off the ground as the targets have them -- the
    plan's swings, and the steps and early lift-offs of plants stepped (:func:`held` reads it)."""
    T = feet.shape[0]
    down, saved, lengths = np.empty(T, np.bool_), np.empty((T + 4, 3)), np.empty(T)  # jump_kernels' scratch
    air = np.logical_not(contacts)  # each foot off the ground (steps too, once made)
    bends, legs, limit, posed, path, lift, yaw, root, h, steps, first, sent = body
    out[...] = feet  # every foot's at once (one contiguous copy); a foot's passes read its own alone
    for f in range(4):
        down[:] = contacts[:, f]
        reach = (legs, bends[f], limit, posed, path, lift, yaw, root, 1.0 / h)
        _plants(feet, soles, down, f, out, most, pins[f], pinned[f], reach, air, steps)
        swings(feet, down, contacts[:, f], out, f, most, (STEP_HEIGHT * bends[f, 4], h), int(bends[f, 5]),
               pinned[f])
        if most >= T:  # a batch's or the exact live mode's: every frame free
            if ease_jumps(out, down, f, h, saved, 0, lengths):  # a step left jumping: widened if it can be
                widen_swings(out, down, air, f, h, STEP_HEIGHT * bends[f, 4], saved, lengths)
        elif last >= 0:  # the low-latency mode sends a swing before its next plant is planned
            ease_unsent(out, down, f, h, (saved, lengths), last, first, sent)
        u = last
        while u >= 0 and not down[u]:
            u -= 1
        if u >= 0:
            pins[f, :] = out[u, f, :]
            pinned[f] = u
    hovering(air, out, path, lift > 0.0, h, 0, feet.shape[0])  # (on the ground, as held reads it)
    return air


@_jit()
def hovering(air: Any, targets: Any, path: Any, terrain: bool, h: float, a: int, b: int) -> None:
    """Marks in ``air`` the frames of ``[a, b)`` whose plant stands higher than PLANTED_UP over the
    ground (targets as :func:`plant_targets` left them: on a terrain, over the body's ground; else
    over the path's height): a plant taken while the foot still comes down holds it up there."""
    for t in range(a, b):
        ground = 0.0 if terrain else path[t, 1] / h
        for f in range(4):
            if (targets[t, f, 1] - ground) * h > PLANTED_UP:
                air[t, f] = True


@_jit()
def held(air: Any, targets: Any, legs: Any, bends: Any, eased: Any, h: float, a: int, b: int,
         kept: Any) -> None:
    """``kept[t - a, f]`` for frames t of ``[a, b)``: foot f stands on its plant -- its target is
    not in the air (``air``: :func:`plant_targets`') and its leg reaches it, the root sunk by
    ``eased``, within PLANTED_SLACK (world metres; the IK's reach: the chain's and LONGEST_OVER
    past the poses' longest, ``bends[:, 4]``). Where the sink's bound leaves a plant out of reach
    (a live plant held where it was sent while the body ran on), the foot hangs short of it: not
    on the ground, so not flagged. The wire's contacts (docs/wire-format.md)."""
    for t in range(a, b):
        for f in range(4):
            if air[t, f]:
                kept[t - a, f] = False
                continue
            up, across2 = from_hip(targets[t, f], legs[t, f])
            allowed = min(legs[t, f, LEG_REACH], (1.0 + LONGEST_OVER) * bends[f, 4])
            short = (sink_within(up, across2, allowed) - eased[t]) * h  # the IK's shortfall, metres
            kept[t - a, f] = short <= PLANTED_SLACK


@_jit()
def _plants(feet: Any, soles: Any, down: Any, f: int, out: Any, most: int, pin: Any, pinned: int,
            reach: Any, air: Any, steps: bool) -> None:
    """Foot f's plants at their average places over their first ``most`` frames at most, at their
    average height in ``soles`` unless more than LIFTED_PLANT over their lower quartile where every frame is
    free (a fade lifted part of it: then at the quartile); the one through ``pinned`` at ``pin``;
    one the body carries out of reach, stepped (:func:`~synth_core.compiled.replant_kernels.replant`;
    ``reach``: plant_targets' legs, the foot's bends, limit, posed, path and its height's share,
    yaw, root and 1 / h).
    ``down (T,)``: its planted frames, those it lifts off early from unmarked; ``air (T, 4)``:
    each foot's frames off the ground, its steps marked as they are made; ``steps``: else none."""
    T = feet.shape[0]
    t = 0
    while t < T:
        if not down[t]:
            t += 1
            continue
        s = t
        while t < T and down[t]:
            t += 1
        n = min(t - s, most)
        acc0 = acc1 = acc2 = 0.0
        lowest = np.inf
        for u in range(s, s + n):
            acc0 += feet[u, f, 0]
            acc1 += soles[u, f]
            acc2 += feet[u, f, 2]
            lowest = min(lowest, soles[u, f])
        x, y, z = acc0 / n, acc1 / n, acc2 / n
        lifted = LIFTED_PLANT * reach[8] if most >= T else np.inf  # (world metres over h; low
        # latency: a plant from its first frames, re-read as they leave the context, hovered 7 mm)
        if y - lowest > lifted:  # (else so is the quartile, never under the lowest: no sort)
            low = np.sort(soles[s:s + n, f])[n // 4]
            y = low if y - low > lifted else y
        if s <= pinned < t:
            x, z = pin[0], pin[2]
        for u in range(s, t):
            out[u, f, 0], out[u, f, 1], out[u, f, 2] = x, y, z
        if steps and reach[1][5] > 0 and strays(x, y, z, reach, f, s, max(s, reach[3]), t):
            replant(feet, down, f, s, t, out, most, reach, s <= pinned < t, air)


@_jit()
def ease_sink(sink: Any, limit: float, out: Any) -> None:
    """A per-frame sink ``(T,)`` spread in time and bounded by ``limit``, into ``out``: a running
    max over EASE_FRAMES, then a Gaussian (sigma EASE_FRAMES / 6, truncated at 4 sigma), the
    ends held (scipy.ndimage's ``mode="nearest"``). ``sink`` may be ``out``. A frame with no sink
    above 0 within either pass's reach is 0, as the sums make it: the sink is 0 on most frames of
    a walk on flat ground, fold_room's raise and reach given back on nearly all."""
    T = sink.shape[0]
    half = EASE_FRAMES // 2
    spread = np.empty(T)
    nxt = 0  # the first frame from the window's start on with a sink above 0 (T: none)
    for t in range(T):
        nxt = _next_above(sink, limit, max(nxt, t - half), T)
        if nxt > t - half + EASE_FRAMES - 1:
            spread[t] = 0.0
            continue
        m = 0.0
        for u in range(t - half, t - half + EASE_FRAMES):
            m = max(m, min(sink[min(max(u, 0), T - 1)], limit))
        spread[t] = m
    sigma = EASE_FRAMES / 6
    radius = int(4.0 * sigma + 0.5)
    kernel = np.empty(2 * radius + 1)
    total = 0.0
    for i in range(-radius, radius + 1):
        kernel[i + radius] = math.exp(-0.5 * i * i / (sigma * sigma))
        total += kernel[i + radius]
    nxt = 0
    for t in range(T):
        nxt = _next_above(spread, np.inf, max(nxt, t - radius), T)
        if nxt > t + radius:
            out[t] = 0.0
            continue
        acc = 0.0
        for i in range(-radius, radius + 1):
            acc += kernel[i + radius] * spread[min(max(t + i, 0), T - 1)]
        out[t] = acc / total


@_jit(inline="always")
def _next_above(x: Any, limit: float, u: int, T: int) -> int:
    """The first frame from ``max(u, 0)`` on whose ``x``, bounded by ``limit``, is above 0 (T: none)."""
    u = max(u, 0)
    while u < T and not min(x[u], limit) > 0.0:
        u += 1
    return u


@_jit()
def _swing_share(targets: Any, f: int, last: int, u: int, nxt: int) -> float:
    """How far frame u's target is along its swing from the plant at frame ``last`` to the one at
    ``nxt`` -- over the ground (its distance from the first over its distances from both), or in
    time where the foot does not travel."""
    gone = math.hypot(targets[u, f, 0] - targets[last, f, 0], targets[u, f, 2] - targets[last, f, 2])
    left = math.hypot(targets[nxt, f, 0] - targets[u, f, 0], targets[nxt, f, 2] - targets[u, f, 2])
    if gone + left > 1e-9:
        return float(gone / (gone + left))
    return float((u - last) / (nxt - last))


@_jit()
def ground_targets(targets: Any, contacts: Any, heights: Any, x0: float, z0: float, spacing: float,
                    h: float, under: Any, most: int = 0) -> None:
    """One character's foot targets ``(T, 4, 3)`` (the library's unit: world / h) whose y is the
    height above the body's ground, put on the terrain ``heights`` (origin x0, z0; ``spacing``),
    in place (``under (T,)``: scratch). Planted: on the terrain under the target. Swinging
    between two plants: over the ground straight from the last plant's height to the next one's
    (by :func:`_swing_share`: on a plane, the plane's own heights), raised where the terrain under
    the swing is above that line: to the tent over that excess (straight up from lift-off to each
    point's excess and straight down from it to touchdown, along the swing's progress: the mean
    of its share of the way and of the time), and never below the terrain under it. A foot so
    rises onto a step or over a bump from lift-off on, reaches the top as it gets there and no
    higher; it does not jump onto it in the frame it crosses the edge. A swing with no plant
    before or after it (a window's ends): the terrain under it. ``most`` >= T (plant_targets':
    every frame free, a batch or the exact live mode): the terrain's own one-frame jumps then
    eased as plant_targets eases the clip's (a hoof planted on a step's edge is over the top in its
    first swing frame: 13.7 cm up at once; :func:`~synth_core.compiled.jump_kernels.ease_jumps`)."""
    T = targets.shape[0]
    lift = np.empty(T)  # a swing's envelope of the terrain's excess over its straight line
    for f in range(4):
        for t in range(T):
            under[t] = ground_at(heights, x0, z0, spacing, targets[t, f, 0] * h, targets[t, f, 2] * h) / h
        t = 0
        while t < T:
            if contacts[t, f]:
                targets[t, f, 1] = max(targets[t, f, 1], 0.0) + under[t]
                t += 1
                continue
            s = t
            while t < T and not contacts[t, f]:
                t += 1
            last, nxt = s - 1, t
            if last < 0 or nxt >= T:  # no plant before or after it: the terrain under it
                for u in range(s, t):
                    targets[u, f, 1] = max(targets[u, f, 1], 0.0) + under[u]
                continue
            best = -np.inf
            for u in range(s, t):  # the tent over the terrain's excess behind each frame ...
                x = _swing_share(targets, f, last, u, nxt)
                w = 0.5 * (x + (u - last) / (nxt - last))
                best = max(best, (under[u] - (under[last] + (under[nxt] - under[last]) * x)) / (1.0 - w))
                lift[u] = (1.0 - w) * best
            best = -np.inf
            for u in range(t - 1, s - 1, -1):  # ... and ahead of it
                x = _swing_share(targets, f, last, u, nxt)
                w = 0.5 * (x + (u - last) / (nxt - last))
                best = max(best, (under[u] - (under[last] + (under[nxt] - under[last]) * x)) / w)
                lift[u] = max(max(lift[u], w * best), 0.0)
            for u in range(s, t):
                e = under[last] + (under[nxt] - under[last]) * _swing_share(targets, f, last, u, nxt)
                targets[u, f, 1] = max(targets[u, f, 1], 0.0) + max(e + lift[u], under[u])
    _jumps_eased(targets, contacts, (heights, x0, z0, spacing), h, most >= T)


@_jit()
def _jumps_eased(targets: Any, contacts: Any, ground: Any, h: float, whole: bool) -> None:
    """ground_targets' last pass (``whole``: else none): each foot's one-frame jumps eased, no
    frame left under the terrain (``ground``: its heights, origin and spacing)."""
    if not whole:
        return
    T = targets.shape[0]
    down, saved, lengths = np.empty(T, np.bool_), np.empty((T + 4, 3)), np.empty(T)
    for f in range(4):
        down[:] = contacts[:, f]
        ease_jumps(targets, down, f, h, saved, 0, lengths)
        for t in range(T):  # (a ramp over the frames after a step's edge took them into it: 4 cm)
            floor = ground_at(ground[0], ground[1], ground[2], ground[3], targets[t, f, 0] * h,
                              targets[t, f, 2] * h) / h
            targets[t, f, 1] = max(targets[t, f, 1], floor)


@_jit()
def _run_start(flags: Any, t: int) -> int:
    """The first frame of the run of equal flags that frame t is in."""
    while t > 0 and flags[t - 1] == flags[t]:
        t -= 1
    return t


@_jit()
def _run_end(flags: Any, t: int) -> int:
    """The frame after the last of the run of equal flags that frame t is in."""
    T = len(flags)
    while t + 1 < T and flags[t + 1] == flags[t]:
        t += 1
    return t + 1


@_jit()
def lock_contexts(contacts: Any, start: int, stop: int, pad: int, begin: Any, end: Any) -> None:
    """Per character ``begin[c], end[c]``: the frames the foot lock of ``[start, stop)`` reads
    (``kernels.lock_context``): a scan from the window's ends over the runs each foot is in."""
    C, T, F = contacts.shape
    lo, hi = max(start - pad, 0), min(stop + pad, T)
    for c in range(C):
        b, e = T, 0
        for f in range(F):
            flags = contacts[c, :, f]
            run = _run_start(flags, lo)  # the plant lo is in, or the plant before its swing
            b = min(b, run if flags[lo] else (_run_start(flags, run - 1) if run > 0 else 0))
            after = _run_end(flags, hi - 1)  # the plant hi - 1 is in, or the plant after its swing
            e = max(e, after if flags[hi - 1] else (_run_end(flags, after) if after < T else T))
        begin[c], end[c] = b, e


@_jit(inline="always")
def measure_feet(world: Any, out_root: Any, yaw: Any, lean: Any, path: Any, tilt: Any, tilt_at: int,
             terrain: bool, rigs: Any, h: float, a: int, T: int, o: int, feet: Any, legs: Any) -> None:
    """Pass 2's measure of frames ``[a, T)``: each foot (``feet``, unit space) and what the sink
    reads of its leg (``legs``), from ``world`` (origin ``o``). On a terrain or leant into a
    turn, a foot is measured with the tilt (and the lean) taken back off: its height as without
    it (over the ground, the body's height is the clip's), its place over the ground turned back
    by half the tilt -- legs hang between square to the body and plumb. Plumb (the whole tilt
    taken off), a body pitched down a 30% slope swung its forelegs 17 degrees forward of where it
    carries them and their shoulders flipped through straight; square, the hooves slid 35 cm
    ahead of the root and the body leant back."""
    for t in range(a, T):
        for f in range(4):
            up, hi, an, ef = rigs[f, 0], rigs[f, 1], rigs[f, 2], rigs[f, 3]
            p_up, p_hi = world_position(world, up, t - o), world_position(world, hi, t - o)
            p_an, p_ef = world_position(world, an, t - o), world_position(world, ef, t - o)
            if terrain or lean[t] != 0.0:  # as the leg hangs untilted, unleaned (see the doc)
                r = vscale(v3(out_root[t]), 1.0 / h)
                q = lean_tilt(yaw[t], lean[t])
                if terrain:
                    q = qmul(q4(tilt[tilt_at + t]), q)
                p = vadd(r, qrot(conj(unit4((q[0], q[1], q[2], q[3] + 1.0))), vsub(p_ef, r)))
                y = r[1] + qrot(conj(q), vsub(p_ef, r))[1]
                # On a terrain above the body's ground (ground_targets puts it on the terrain).
                y = y - path[t, 1] / h if terrain else y
                feet[t, f, 0], feet[t, f, 1], feet[t, f, 2] = p[0], y, p[2]
            else:
                feet[t, f, 0], feet[t, f, 1], feet[t, f, 2] = p_ef
            leg = legs[t, f]
            leg[LEG_TOE], leg[LEG_TOE + 1], leg[LEG_TOE + 2] = vsub(p_ef, p_an)
            leg[LEG_UP], leg[LEG_UP + 1], leg[LEG_UP + 2] = p_up
            thigh, shin = norm3(vsub(p_hi, p_up)), norm3(vsub(p_an, p_hi))
            leg[LEG_REACH], leg[LEG_THIGH] = thigh + shin, thigh


@_jit(inline="always")
def reach_sink(targets: Any, legs: Any, bends: Any, path: Any, h: float, terrain: bool, s: int, T: int,
               sink: Any) -> None:
    """Pass 3's sink of frames ``[s, T)``: how far the root must come down for the leg furthest
    from its target to reach it within ``REACH`` of its length and ``LONGEST_OVER`` beyond its
    longest reach in the animal's poses (``bends[:, 4]``; flat ground: targets no lower than the
    path)."""
    for t in range(s, T):
        floor = path[t, 1] / h
        worst = 0.0
        for f in range(4):
            if not terrain and targets[t, f, 1] < floor:
                targets[t, f, 1] = floor
            up, across2 = from_hip(targets[t, f], legs[t, f])
            allowed = min(REACH * legs[t, f, LEG_REACH], (1.0 + LONGEST_OVER) * bends[f, 4])
            worst = max(worst, sink_within(up, across2, allowed))
        sink[t] = worst


@_jit(inline="always")
def fold_room(targets: Any, legs: Any, bends: Any, limit: float, s: int, T: int, eased: Any,
              lift: Any) -> None:
    """The eased sink of frames ``[s, T)`` lowered no further than lets every leg reach its
    target with its hinge folded no more than the animal's own poses fold it (``bends[:, 3]``) --
    raised for that where it must, by ``limit`` at most, and no further than every leg still
    reaches its own within reach_sink's rule and its longest reach in the poses (``bends[:, 4]``:
    a leg straighter than the animal holds it reads stretched; a stretched leg lifts a planted
    foot). The easing spreads a sink over the frames around the one that needs it: a dog's hind
    leg stretching back to its plant below a 20 cm step sank the body 9 cm while the other hind
    paw swung up onto the step, and the IK folded that knee through its thigh to reach it (185
    deg; the clips' furthest, 128): a limb flip, the bend's side reversing in one frame.

    The raise is eased as the sink is (:func:`ease_sink`, ``lift``: its per-frame amounts), and
    so is what it takes back where it would lift the body past a leg's reach: applied frame by
    frame, the bounds moved the root 8 cm in one frame on the step as a plant's target changed."""
    reach = np.empty(T)
    for t in range(s, T):
        room, need = np.inf, -np.inf
        for f in range(4):
            leg = legs[t, f]
            up, across2 = from_hip(targets[t, f], leg)
            need = max(need, sink_within(up, across2, min(REACH * leg[LEG_REACH], bends[f, 4])))
            thigh, shin = leg[LEG_THIGH], leg[LEG_REACH] - leg[LEG_THIGH]
            gap2 = thigh * thigh + shin * shin + 2.0 * thigh * shin * bends[f, 3] - across2
            if gap2 > 0.0:  # folded that far, the hip is sqrt(gap2) above the target; sunk by s,
                # it is -(up + s) above it
                room = min(room, -up - math.sqrt(gap2))
        reach[t] = max(need, -limit)
        lift[t] = eased[t] - max(min(eased[t], max(room, need)), -limit)
    ease_sink(lift[s:T], 2.0 * limit, lift[s:T])
    for t in range(s, T):  # how far the eased raise lifts the body past a leg's reach: given back,
        reach[t] = max(reach[t] - (eased[t] - lift[t]), 0.0)  # eased too
    ease_sink(reach[s:T], 2.0 * limit, reach[s:T])
    for t in range(s, T):
        eased[t] = min(eased[t], eased[t] - lift[t] + reach[t])
