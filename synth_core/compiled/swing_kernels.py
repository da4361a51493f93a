"""A swinging foot's targets between its plants (part of ``foot_kernels.plant_targets``): its
clip's path with the corrections its plants need eased in and out over the ground, and lifted
clear of the ground (footlock.CLEARANCE); a foot lifted off early steps over to its next plant."""

from __future__ import annotations

from typing import Any

from synth_core.compiled.jit import render_jit
from synth_core.compiled.replant_kernels import step_over
from synth_core.compiled.vec_kernels import smoothstep
from synth_core.runtime.footlock import CLEAR_DOWN, CLEAR_LEAST, CLEAR_RISE_S, CLEAR_UP, CLEARANCE, STEP_S

_jit = render_jit


@_jit()
def swings(feet: Any, down: Any, planted: Any, out: Any, f: int, most: int, heights: Any,
            step: int, pinned: int) -> None:
    """Foot f's swings (``down (T,)``: its planted frames): eased from the last plant's lift-off
    correction to the next one's touchdown one (``out``: the plants' targets, by foot_kernels._plants;
    the shares: :func:`_eased`, ``step`` a step's frames), clear of the line between them
    (:func:`_swing`): by CLEARANCE of a step's height ``heights[0]``, CLEAR_LEAST at least
    (world metres, over the scale ``heights[1]``). A plant whose swing in had not eased
    its lift-off correction out by its touchdown, where its next plant is planned late (``most``
    < T, the low-latency mode), keeps what is left (over the ground) unless it was sent already
    (its frame ``pinned``): the foot lands where its swing took it, the next swing eases it out.
    A swing a plant lifted off early into (its first frame ``planted``, as the clip has it: see
    replant_kernels.replant) is a step instead, ``heights[0]`` high, from the one plant to the next:
    the clip's own swing, a few frames of it at the plant's end, moved a foot the body had carried
    far 20-40 cm a frame (replant_kernels.step_over)."""
    T = feet.shape[0]
    t = 0
    last_start = -1
    last_end = -1
    while t < T:
        if down[t]:
            if t == 0 or not down[t - 1]:
                last_start = t
            if t == T - 1 or not down[t + 1]:
                last_end = t
            t += 1
            continue
        s = t
        while t < T and not down[t]:
            t += 1
        has_before = last_start >= 0
        has_after = t < T
        if not (has_before or has_after):
            continue
        if planted[s] and has_before and has_after:  # lifted off early: one step to the next plant
            step_over(out, f, s, t, heights[0])
            continue
        e = t
        while e < T and down[e]:
            e += 1
        # What is left of the lift-off correction at touchdown, kept by a plant not sent yet.
        keep = has_before and has_after and most < T and not t <= pinned < e
        clear = max(CLEARANCE * heights[0], CLEAR_LEAST / heights[1])
        _swing(feet, out, f, s, t, e if keep else t, (last_start, last_end, has_before, has_after, most < T,
                                                       step), clear)


@_jit()
def _swing(feet: Any, out: Any, f: int, s: int, t: int, e: int, plants: Any, clear: float) -> None:
    """Foot f's swing [s, t) (:func:`swings`; ``plants``: :func:`_eased`'s arguments but u and
    the next plant's start t), and the lift-off correction's share left at t added to its next
    plant's frames [t, e)."""
    last_start, last_end, has_before, has_after, unplanned, step = plants
    left = 1.0 - _eased(t, last_start, last_end, t, has_before, has_after, unplanned, step)[0]
    # Over the ground only (x, z): the corrections read before any frame is moved.
    lift_x = out[last_end, f, 0] - feet[last_end, f, 0] if has_before else 0.0
    lift_z = out[last_end, f, 2] - feet[last_end, f, 2] if has_before else 0.0
    touch_x = out[t, f, 0] - feet[t, f, 0] if has_after else 0.0
    touch_z = out[t, f, 2] - feet[t, f, 2] if has_after else 0.0
    y0 = out[last_end, f, 1] if has_before else out[t, f, 1]
    y1 = out[t, f, 1] if has_after else y0
    # Frames the lift rises over: CLEAR_UP of the swing, no fewer than CLEAR_RISE_S's (a step's
    # frames are STEP_S's: the frame rate is not passed down here).
    rise_frames = max(CLEAR_UP * (t - s + 1), step * (CLEAR_RISE_S / STEP_S))
    for u in range(s, t):
        eased, landed = _eased(u, last_start, last_end, t, has_before, has_after, unplanned, step)
        out[u, f, 0] = feet[u, f, 0] + (1 - eased) * lift_x + landed * touch_x
        out[u, f, 2] = feet[u, f, 2] + (1 - eased) * lift_z + landed * touch_z
        p = (u - s + 1) / (t - s + 1)
        lift = smoothstep(min(1.0, (u - s + 1) / rise_frames)) * smoothstep(min(1.0, (1.0 - p) / CLEAR_DOWN))
        out[u, f, 1] = max(feet[u, f, 1], y0 + (y1 - y0) * p + clear * lift)
    for u in range(t, e):
        out[u, f, 0] += left * lift_x
        out[u, f, 2] += left * lift_z


@_jit()
def _eased(u: int, last_start: int, last_end: int, nxt: int, has_before: bool, has_after: bool,
           unplanned: bool, step: int) -> tuple[float, float]:
    """The shares on frame u of a swing from the plant ``[last_start, last_end]`` to the plant
    starting at ``nxt`` of the corrections these plants need: the lift-off one eased out, the
    touchdown one eased in (smoothstep over the swing; all of it, or none, where a plant is
    missing). ``unplanned``: the swing's next plant may not be planned yet when its first frames
    are sent (a live window in the low-latency mode: planned a few frames before it is sent), so
    its lift-off correction is eased out over a span that does not depend on it: ``step`` frames
    (0: half its plant's). Eased over the swing, the frames sent before the plant came had eased
    it out over a guess (half the plant before: a second for a standing plant, whose correction
    a body turning on the spot over it made 1.3 m) and let go of the rest in one frame once it
    came (low-latency horse turn_on_spot: a 95 cm jump). What a swing shorter than that leaves,
    its plant keeps (:func:`swings`)."""
    x = 1.0 if has_after else 0.0
    if has_before and has_after:
        x = smoothstep((u - last_end) / max(nxt - last_end, 1))
    if not (unplanned and has_before):
        return x, x
    span = step if step > 0 else max((last_end - last_start + 1) // 2, 1)
    return smoothstep((u - last_end) / span), x
