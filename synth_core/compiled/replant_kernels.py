"""The foot lock's steps: a plant its leg can no longer reach is stepped (issue 27, turning on the
spot), and the reach rule it and the sink share.

:func:`replant` splits such a plant into plants each within reach, the foot stepped between
them (:func:`~synth_core.compiled.foot_kernels.plant_targets` calls it); :func:`sink_within`
is how far the root must come down for a leg to reach a target (``foot_kernels.reach_sink`` and
``fold_room`` too). Constants: :mod:`synth_core.runtime.footlock` (STEP_*).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from synth_core.compiled.jit import render_jit
from synth_core.compiled.vec_kernels import smoothstep, v3, vsub
from synth_core.runtime.footlock import LONGEST_OVER, REACH, STEP_HEIGHT, STEP_LIFT, TURN_CARRY

_jit = render_jit

# What the sink of a frame reads of its pose, per foot (see ``kernels._character``): the ankle-to-toe
# vector, the upper joint's position, the leg's reach (thigh and shin) and its thigh (fold_room). A
# live window keeps them for its last PAD frames, whose sink the next window's first frames read:
# those are then not posed again.
LEG_TOE, LEG_UP, LEG_REACH, LEG_THIGH = 0, 3, 6, 7
LEG_WIDTH = 8
NOWHERE = -(1 << 62)  # Posed.legs_at of a character whose last window kept no legs
_SURELY = 1.0 - 1e-9  # strays: r d squared under this share of the limit's is under it, whatever
# the rounding of r (hypot) and the products (a few units in the last place)


@_jit(inline="always")
def from_hip(target: Any, leg: Any) -> tuple[float, float]:
    """A foot's target from its leg's upper joint, the ankle-to-toe vector taken off: its height
    (up) and its squared distance across the ground."""
    to_ankle = vsub(vsub(v3(target), v3(leg[LEG_TOE:])), v3(leg[LEG_UP:]))
    return to_ankle[1], to_ankle[0] ** 2 + to_ankle[2] ** 2


@_jit(inline="always")
def sink_within(up: float, across2: float, allowed: float) -> float:
    """How far the root must come down for a leg to reach a target ``up`` above its upper joint
    and ``sqrt(across2)`` across within ``allowed`` (foot_kernels.reach_sink's and fold_room's rule)."""
    return -up - math.sqrt(max(allowed * allowed - across2, 0.0))


def no_steps(T: int) -> tuple[Any, ...]:
    """plant_targets' ``body`` for ``T`` frames where no plant is stepped (its targets the
    plants' averages alone): no step frames, legs never out of reach; no frame sent before it."""
    return (np.zeros((4, 6)), np.zeros((T, 4, LEG_WIDTH)), np.inf, 0, np.zeros((T, 3)), 0.0, np.zeros(T),
            np.zeros((T, 3)), 1.0, False, 0, (np.zeros((2, 4, 3)), NOWHERE))


@_jit(inline="always")
def _from_leg(x: float, y: float, z: float, reach: Any, f: int, u: int) -> tuple[float, float, float]:
    """(x, y, z) from leg f's upper joint on frame u (:func:`from_hip`: up, across squared) and how
    far the leg may reach (reach_sink's rule; ``reach``: see foot_kernels._plants)."""
    legs, bend, path, lift = reach[0], reach[1], reach[4], reach[5]
    up, across2 = from_hip((x, y + path[u, 1] * lift, z), legs[u, f])
    return up, across2, min(REACH * legs[u, f, LEG_REACH], (1.0 + LONGEST_OVER) * bend[4])


@_jit()
def _needs(x: float, y: float, z: float, reach: Any, f: int, u: int) -> float:
    """How far the root must come down on frame u for leg f to reach (x, y, z) (reach_sink's rule)."""
    up, across2, allowed = _from_leg(x, y, z, reach, f, u)
    return sink_within(up, across2, allowed)


@_jit()
def strays(x: float, y: float, z: float, reach: Any, f: int, a: int, s: int, t: int) -> bool:
    """Whether the body turning on the spot since frame a carries leg f out of reach of its plant
    at (x, y, z) on some frame of [s, t): it cannot reach it within the sink's limit (reach_sink's
    rule) while the turn carries the plant round the root TURN_CARRY times as far as the root has
    travelled, and further than that limit. Not a body on its way: a gait played faster than its
    clips, or round a circle, reaches as far behind at the end of each stance, which the lock
    lets fall short (a step there took a foot off the ground it stands on: walk frames with two
    feet down 1.0 -> 0.81 on a 30% slope, 0.91 on small circles). ``reach``: see foot_kernels._plants."""
    limit, yaw, root, unit = reach[2], reach[6], reach[7], reach[8]
    for u in range(s, t):
        # Read on every planted frame: the turn's wrap and the distance are skipped where they
        # cannot change the answer (a sixth of the render's plant_targets went on them).
        w = yaw[u] - yaw[a] + math.pi
        d = abs((w if 0.0 <= w < 2.0 * math.pi else w % (2.0 * math.pi)) - math.pi)  # (% of such w: w)
        dx, dz = x - root[u, 0] * unit, z - root[u, 2] * unit
        if (dx * dx + dz * dz) * (d * d) <= _SURELY * limit * limit:  # r d well within the limit
            continue
        r = math.hypot(dx, dz)
        if r * d <= limit:  # not carried far: most frames, so read before the leg's reach
            continue
        o = max(a, reach[3])  # (the root is known from the first frame posed on)
        travel = math.hypot(root[u, 0] - root[o, 0], root[u, 2] - root[o, 2]) * unit
        # (a standing body's yaw holds to the last bit)
        if r * d > TURN_CARRY * travel and _needs(x, y, z, reach, f, u) > limit:
            return True
    return False


@_jit()
def replant(feet: Any, down: Any, f: int, s: int, t: int, out: Any, most: int, reach: Any, keep_first: bool,
             air: Any) -> None:
    """Foot f's plant [s, t), which the body carries out of reach (it turns on the spot over it),
    as the steps an animal turning in place takes: plants each held while its leg reaches its
    place (the average of its first ``most`` frames so far), the foot lifted STEP_HEIGHT of the
    leg between them over a step's frames to the next (marked in ``air``), when the other
    feet stand on it (:func:`_in_turn`). Where no step and a plant after it fit before the plant
    ends, the foot lifts off into its swing, or, no two other feet down, stands where its leg
    reaches (:func:`_lift_off`).
    ``keep_first``: the first one keeps its place (pinned, see foot_kernels._plants)."""
    step, height = int(reach[1][5]), STEP_HEIGHT * reach[1][4]
    a = s
    lift = -1  # the frame a step began (-1: none pending)
    while a < t:
        # The first plant's place over the ground: where the foot came down (its first half-step's
        # frames), so its swing in lands where it goes; a step's: its frames' average, so it lands
        # ahead of the foot the body carries on. Its height: its frames' (a foot still coming down
        # as a stand begins is set down, as _plants does).
        first = min(most, max(step // 2, 1)) if a == s else most
        b = _held(feet, f, a, t, first, reach, air)
        n, m = min(b - a, first), min(b - a, most)
        acc0 = acc1 = acc2 = 0.0
        for u in range(a, a + m):
            acc0 += feet[u, f, 0] if u < a + n else 0.0
            acc1 += feet[u, f, 1]
            acc2 += feet[u, f, 2] if u < a + n else 0.0
        if not (keep_first and a == s):  # (else it stays where _plants put it)
            for u in range(a, b):
                out[u, f, 0], out[u, f, 1], out[u, f, 2] = acc0 / n, acc1 / m, acc2 / n
        if lift >= 0:
            step_over(out, f, lift, a, height)
            air[lift:a, f] = True
        if t - b < step + step // 2:  # no room for a step and a plant after it
            _lift_off(out, down, air, f, (a, b, t), step, reach)
            return
        lift, a = b, b + step


@_jit()
def _held(feet: Any, f: int, a: int, t: int, first: int, reach: Any, air: Any) -> int:
    """Where foot f's plant from frame a (of a plant to frame t) ends: the frame its leg first
    cannot reach its place (the average of its ``first`` frames so far), moved to a step's
    turn (:func:`_in_turn`); t if it reaches it to the end (``reach``: see foot_kernels._plants)."""
    acc0 = acc1 = acc2 = 0.0
    n = 0
    for b in range(a, t):
        if n > 0 and b >= reach[3] and strays(acc0 / n, acc1 / n, acc2 / n, reach, f, a, b, b + 1):
            turned = a  # a step starts once the body has started turning (not before, standing)
            while turned + 1 < b and reach[6][turned + 1] == reach[6][a]:
                turned += 1
            return _in_turn(air, f, turned, b, t, int(reach[1][5]))
        if n < first:
            acc0 += feet[b, f, 0]
            acc1 += feet[b, f, 1]
            acc2 += feet[b, f, 2]
            n += 1
    return t


@_jit()
def _lift_off(out: Any, down: Any, air: Any, f: int, frames: Any, step: int, reach: Any) -> None:
    """Foot f's plant [a, t) strays at frame b (``frames``: a, b, t) with no room left for a step:
    it lifts off early into its swing (``down`` unmarked), the two at least a step long (a few
    frames of the clip's swing moved the foot the body had carried far in a jerk), if two other
    feet stand meanwhile; else it stands to the plant's end where its leg reaches (:func:`_drag`)."""
    a, b, t = frames
    e = t
    while e < down.shape[0] and not down[e]:
        e += 1
    c = max(min(b, e - step), a + 1)
    if stood(air, f, c, e):
        down[c:t] = False
        air[c:t, f] = True
        return
    for u in range(b, t):
        for k in range(3):
            out[u, f, k] = out[b - 1, f, k]
    for u in range(a, t):  # (from its start: a step's turn, b, may come frames after it strayed)
        _drag(out, f, u, reach)


@_jit()
def _drag(out: Any, f: int, u: int, reach: Any) -> None:
    """Foot f's target on frame u moved across the ground toward its leg's upper joint until the
    leg reaches it (reach_sink's rule, the sink's bound taken): a plant the body carries out of
    reach that cannot be lifted (no two other feet down) is dragged round with the body. Held
    where it stood, the leg reached for it straight and the foot hung: the horse's turn on the
    spot, a forefoot 45 cm up for 28 frames (the edge suite's hanging_s_max). The wire flags it
    planted (foot_kernels.held: its leg reaches it): on the ground, moving a few mm a frame.
    Only where steps are made (``replant``'s caller: a batch's render, not a live window's)."""
    if u < reach[3]:  # (not posed: no leg to reach with)
        return
    up, across2, allowed = _from_leg(out[u, f, 0], out[u, f, 1], out[u, f, 2], reach, f, u)
    # The squared distance across it reaches, the hips sunk by the bound (sink_within's rule); none
    # under them: lower than the leg reaches even there, moving it would not help.
    room = allowed * allowed - max(-up - reach[2], 0.0) ** 2
    if across2 <= room or room <= 0.0:
        return
    keep = math.sqrt(room / across2)  # of the way across from the upper joint
    leg = reach[0][u, f]
    for k in (0, 2):
        ankle = out[u, f, k] - leg[LEG_TOE + k] - leg[LEG_UP + k]
        out[u, f, k] -= (1.0 - keep) * ankle


@_jit()
def _in_turn(air: Any, f: int, a: int, b: int, t: int, step: int) -> int:
    """The frame foot f's step starts, its plant straying at frame b (and ending at t): the
    nearest to b (from a frame after a to half a step after b, room left for a step and a frame's plant) whose
    step leaves at least two other feet down throughout (``air``: the feet off the ground, so
    far as known) and the other foot of its pair down too (left and right step in turn); else
    the nearest leaving two down; else b (held on, the foot would hang out of reach longer)."""
    lo, hi = a + 1, min(b + step // 2, t - step - 1)
    fallback = -1
    for k in range(2 * max(b - lo, hi - b) + 1):
        c = b + ((k + 1) // 2) * (1 if k % 2 == 1 else -1)
        if c < lo or c > hi:
            continue
        two, pair = stood(air, f, c, c + step), True
        for u in range(c, c + step):
            pair = pair and not air[u, f ^ 1]
        if two and pair:
            return c
        if two and fallback < 0:
            fallback = c
    return fallback if fallback >= 0 else b


@_jit()
def stood(air: Any, f: int, a: int, b: int) -> bool:
    """Whether at least two feet but f are down (``air``: off the ground) on every frame of [a, b)."""
    for u in range(a, b):
        down = 0
        for g in range(4):
            if g != f and not air[u, g]:
                down += 1
        if down < 2:
            return False
    return True


@_jit()
def step_over(out: Any, f: int, a: int, b: int, height: float) -> None:
    """Foot f's targets over frames [a, b): from its plant before (frame a - 1) to the one after
    (frame b), lifted ``height`` at the middle (a sine), over the ground eased (smoothstep) once
    the foot is up: over the middle of the step, less STEP_LIFT of it at either end (a foot
    moving near the ground glides, the edge suite's glide ratio)."""
    n = b - a + 1
    for u in range(a, b):
        x = (u - a + 1) / n
        e = smoothstep((x - STEP_LIFT) / (1.0 - 2.0 * STEP_LIFT))  # up before it moves
        for k in range(3):
            out[u, f, k] = out[a - 1, f, k] + e * (out[b, f, k] - out[a - 1, f, k])
        out[u, f, 1] += height * math.sin(math.pi * x)


