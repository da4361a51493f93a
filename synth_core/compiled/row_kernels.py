"""What a frame of a plan shows (:mod:`synth_core.compiled.plan_kernels`' step 5): a piece's table
rows at a clip frame -- a gait's two speed-map clips around the speed, a transition's two frames
around the distance walked -- the piece before it fading out, a gait's stride clock between two
clip frames, and the rows on the character's lead. Numba compiles these with the planner (the
interpreter runs their source as its reference: plan_kernels.REFERENCE).
"""

from __future__ import annotations

import math
from typing import Any

from synth_core.compiled.jit import jit


@jit(inline="always")
def interp(x: float, xp: Any, at: int, n: int) -> float:
    """np.interp(x, xp[at:at + n], arange(n)) for one x, as numpy computes it (same branches, same
    operations): the last j with xp[j] <= x, then the slope form."""
    if x < xp[at]:
        return 0.0
    if x > xp[at + n - 1]:
        return float(n - 1)
    lo, hi = 0, n
    while lo < hi:
        mid = lo + ((hi - lo) >> 1)
        if x >= xp[at + mid]:
            lo = mid + 1
        else:
            hi = mid
    j = lo - 1
    if j == n - 1 or xp[at + j] == x:
        return float(j)
    slope = (float(j + 1) - float(j)) / (xp[at + j + 1] - xp[at + j])
    return float(slope * (x - xp[at + j]) + float(j))


@jit(inline="always")
def piece_rows(kind: int, local: int, speed: float, walked: float, has_walked: bool, offset: Any,
               frames_of: Any, clips: Any, cyclic: Any, curve_at: Any, curves: Any) -> Any:
    """Table rows of a piece at clip frame ``local``: (row 0, row 1, the second's weight). Gaits:
    the two speed-map clips around ``speed``; transitions: the two clip frames around the one whose
    progress is ``walked`` (the distance since it began; ``has_walked`` False: past its end)."""
    frames = frames_of[kind]
    if cyclic[kind]:
        frame = local % frames
    else:
        frame = min(max(local, 0), frames - 1)
    clip0 = 0
    weight = 0.0
    at, n = curve_at[kind, 0], curve_at[kind, 1]
    if n > 0:
        if cyclic[kind]:  # a gait: the clips around the speed
            u = interp(speed, curves, at, n)
            clip0 = min(int(math.floor(u)), n - 2) if n > 1 else 0
            weight = u - clip0
        elif has_walked:  # a transition: the frames around the distance walked
            f = interp(walked, curves, at, n)
            frame = min(int(math.floor(f)), n - 1)
            weight = f - frame
    clip1 = min(clip0 + 1, clips[kind] - 1)
    base = offset[kind] + frame
    step = clip1 * frames if cyclic[kind] else min(frame + 1, frames - 1) - frame
    return base + clip0 * frames, base + step, weight


@jit(inline="always")
def fade(since: int, margin: int) -> float:
    """The share left of a piece fading out ``since`` frames after the next one started (1 -
    smoothstep over ``margin`` frames; 0 once they are over)."""
    if since >= margin:
        return 0.0
    u = (since + 1) / (margin + 1)
    return 1 - u * u * (3 - 2 * u)


@jit(inline="always")
def local_frame(first: int, kind: int, clock: float, clock0: float, cyclic: Any) -> int:
    """The clip frame a piece that started at clip frame ``first`` shows: a gait's runs on with
    its stride clock (``clock0`` at its start), a transition fading out holds its frame."""
    if not cyclic[kind]:
        return first
    return int(math.floor(first + clock - clock0 + 0.5))


@jit(inline="always")
def tween(kind: int, d: float, local: int, frames_of: Any, contacts_of: Any, o: int, rows: Any,
           weights: Any) -> None:
    """A gait's stride clock between clip frames: ``d`` (in [-0.5, 0.5)) from the frame shown,
    ``local``. Its neighbour that way goes into the free fading rows of output row ``o``, weighted
    ``|d|``, so the pose is interpolated in time. Played at any rate but 1 (a character's tempo,
    its size's, a stride faster than the fastest clip), whole clip frames were shown, repeated or
    skipped now and then: a skipped frame moved a paw two frames' way in one (issue 28: the real
    dog's galloping paws jumped up to 14 cm). Not where a foot lands or lifts between the two: the
    foot lock pins the shown frame's planted feet, and a foot drawn part way to or from its plant
    skimmed the ground unpinned (the edge suite's strict skate and touchdown speeds)."""
    if d == 0.0:
        return
    # _row of the neighbour: output row o's speed clips and weight, one clip frame on (shifted).
    frames = frames_of[kind]
    shift = (local + (1 if d > 0 else -1)) % frames - local % frames
    q0, q1, qw = rows[o, 0] + shift, rows[o, 1] + shift, weights[o, 0]
    for foot in range(4):
        if contacts_of[q0, foot] != contacts_of[rows[o, 0], foot]:
            return
    rows[o, 2], rows[o, 3], weights[o, 1] = q0, q1, qw
    weights[o, 2] = abs(d)


@jit(inline="always")
def frame_rows(kind: int, local: int, walked: float, since: int, p_kind: int, p_local: int, o_kind: int,
                o_local: int, o_keep: float, v: float, offset: Any, frames_of: Any, clips: Any, cyclic: Any,
                source: Any, target: Any, curve_at: Any, curves: Any, margin: int, o: int, rows: Any,
                weights: Any) -> int:
    """A frame's rows and weights (into row ``o`` of the outputs): the piece ``kind`` at
    clip frame ``local`` (``walked`` since it started ``since`` frames ago), and unless ``p_local``
    is -1, the piece before it (``p_kind`` at ``p_local``) fading out -- itself over the one before
    it (``o_kind`` at ``o_local``, share ``o_keep``) unless ``o_local`` is -1; returns the
    frame's gait."""
    r0, r1, w = piece_rows(kind, local, v, walked, True, offset, frames_of, clips, cyclic, curve_at, curves)
    rows[o, 0], rows[o, 1], weights[o, 0] = r0, r1, w
    rows[o, 2], rows[o, 3], weights[o, 1] = r0, r1, w
    weights[o, 2] = 0.0
    if p_local >= 0:
        p0, p1, pw = piece_rows(p_kind, p_local, v, 0.0, False, offset, frames_of, clips, cyclic, curve_at,
                                curves)
        if o_local >= 0:  # two pieces fading out, in the one pair of rows the render blends: each
            # by its nearer row (neighbouring speed clips or frames: millimetres apart)
            q0, q1, qw = piece_rows(o_kind, o_local, v, 0.0, False, offset, frames_of, clips, cyclic,
                                    curve_at, curves)
            p0 = p1 if pw >= 0.5 else p0
            p1 = q1 if qw >= 0.5 else q0
            pw = o_keep
        rows[o, 2], rows[o, 3], weights[o, 1] = p0, p1, pw
        weights[o, 2] = fade(since, margin)  # smoothstep out
    first_half = (r0 - offset[kind]) < frames_of[kind] // 2  # a transition: the hub it leaves, then
    return int(source[kind] if first_half else target[kind])  # the one it reaches


@jit(inline="always")
def on_lead(lead: int, contacts_of: Any, o: int, rows: Any, contacts: Any) -> None:
    """Output row ``o`` on the character's lead: its table rows ``lead`` on (0, or the bank's
    mirror: their mirror images, left and right swapped), and the contacts of the row shown."""
    for j in range(4):
        rows[o, j] += lead
    for foot in range(4):
        contacts[o, foot] = contacts_of[rows[o, 0], foot]
