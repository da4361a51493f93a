"""Generate gait clips by planning foot paths and solving the legs (issue 3).

One event-based generator serves cyclic gaits, the idle and the transitions. Every gait parameter
is a per-frame array (a transition blends two gaits' parameters over time), and:

1. the root advances at the speed, and a stride clock runs at the stride frequency;
2. each foot's phase is the clock minus its footfall offset; it is planted while the phase's
   fraction is below the duty factor. Each plant sits at the foot's neutral place under the body
   at the root's mid-stance position (or, for a plant open at the clip's start or end, at the
   root's position there, so standing is square);
3. a swinging foot travels from one plant to the next on a minimum-jerk path relative to the
   body, eased in the world so it peels off slowly and slows to rest before touchdown (issue 27),
   lifted steeply by its own step height (``FOOT_LIFT``: no two feet alike);
4. the trunk bobs, pitches and flexes, the neck nods (the head partly or wholly held level), the
   neck and tail sway, the tail follows;
5. the legs are solved in the sagittal plane (:mod:`synth_core.builtin.limbs`) with the carpus
   and hock flexing in swing, the fetlock sinking under load and the hoof standing flat until it
   breaks over the toe in the last fifth of the stance (issue 28); mid-swing, where the folded
   leg's solution turns fastest, the angles are smoothed in time.

Cyclic clips are generated with two strides of padding on each side and cut, so they loop
exactly; transitions are cut from a timeline padded with the gaits they join.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from synth_core import FOOT_NAMES
from synth_core.builtin.foot_paths import FootPlan, plan_foot
from synth_core.builtin.gaits import FOOT_LIFT, GaitSpec
from synth_core.builtin.leg_motion import leg_rotations, rest_protraction, rot_x, solve_limb
from synth_core.builtin.limbs import LegSolution, Limb, limbs_of
from synth_core.builtin.tracks import (
    FPS,
    NUMERIC,
    Floats,
    Track,
    blend_track,
    concat,
    constant_track,
    smoothstep,
)
from synth_core.motion import quat
from synth_core.motion.clip import Motion
from synth_core.motion.contacts import fill_gaps, runs
from synth_core.motion.skeleton import Skeleton, forward_kinematics

MIN_SWING_S = 0.05  # shorter swings are not taken (the foot stays planted)
MAX_EARLY_LIFT_FRAMES = 3  # a foot out of reach at the end of its stance lifts up to this early
REACH_TOLERANCE = 0.001  # m
MAX_EXTENSION = 0.985  # of the two main links' reach, on a stance's last frame
_Y = np.array([0.0, 1.0, 0.0])


# --- the whole body --------------------------------------------------------------------------


def rest_root_height(skeleton: Skeleton) -> float:
    pos, _ = forward_kinematics(skeleton, np.zeros(3), quat.identity((skeleton.n_joints,)))
    return float(-pos[skeleton.foot_joints, 1].min())


def rest_positions(skeleton: Skeleton) -> Floats:
    """World joint positions (J, 3) of the standing rest pose, feet on the ground."""
    pos, _ = forward_kinematics(skeleton, np.array([0.0, rest_root_height(skeleton), 0.0]),
                                quat.identity((skeleton.n_joints,)))
    return np.asarray(pos, dtype=np.float64)


def _global_pitch(skeleton: Skeleton, local: Floats, root_pitch: Floats | float) -> Floats:
    """World pitch (F, J) of every joint: local X-rotations summed from the root (all about X)."""
    pitch = np.zeros_like(local)
    pitch[:, 0] = root_pitch
    for j in range(1, skeleton.n_joints):  # joints, in parent order
        pitch[:, j] = pitch[:, skeleton.parents[j]] + local[:, j]
    return pitch


def _joints(skeleton: Skeleton, prefix: str) -> list[int]:
    return [j for j, n in enumerate(skeleton.names) if n.startswith(prefix) and not skeleton.end_site[j]]


def _wave(clock: Floats, per_stride: Floats | float, at: Floats | float) -> Floats:
    """cos wave that peaks (= 1) when the stride clock is at phase ``at``."""
    return np.cos(2 * np.pi * np.asarray(per_stride) * (clock - at))


def footfalls(track: Track, clock: Floats | None = None) -> NDArray[np.bool_]:
    """Planted feet (T, 4) of a track: each foot while its phase's fraction is below the duty."""
    if clock is None:
        clock = np.round(np.concatenate([[0.0], np.cumsum(track.frequency[1:]) / FPS]), 9)
    phases = np.round(clock[:, None] - track.phases, 9)  # strides since each foot's reference touchdown
    planted = np.mod(phases, 1.0) < track.values["duty"][:, None] - 1e-9
    # Near standstill (a start or stop) the duty factor nears 1 and swings shrink to a frame or
    # two: a foot cannot step in 30 ms, so such steps are skipped and the plant held.
    return fill_gaps(planted, int(MIN_SWING_S * FPS))


def longest_alone(planted: NDArray[np.bool_]) -> int:
    """The most frames one foot carries the body alone in ``planted (T, 4)``."""
    alone = planted & (planted.sum(axis=1, keepdims=True) == 1)
    return max((int(np.diff(r, axis=1).max(initial=0)) for r in map(runs, alone.T)), default=0)


def land_sooner(planted: NDArray[np.bool_], limit: int) -> NDArray[np.bool_]:
    """``planted (T, 4)`` where no foot carries the body alone past ``limit`` frames: the foot
    (or pair) landing at the end of a longer lone stance lands ``limit`` frames into it.

    Blending two gaits' footfall phases and duty factors separately, a transition passes through
    patterns neither gait has: trot to canter, the trailing hind landed before the lead fore
    lifted and carried the dog alone for 10 frames until the diagonal pair came down (the
    canter's lone support: 7; issue 27: no foot alone past its gait's longest stance, 9). The
    animal puts its next foot down sooner instead (its swing a few frames shorter). A lone
    stance ended by the foot lifting (a flight follows) is left as it is."""
    planted = planted.copy()
    T = len(planted)
    for _ in range(len(FOOT_NAMES) * 2):  # a landing moved changes the supports after it: redo
        alone = planted & (planted.sum(axis=1, keepdims=True) == 1)
        moved = False
        for k, stances in enumerate(map(runs, alone.T)):  # four feet, a few stances each
            for start, stop in stances:
                if stop - start <= limit or stop >= T:
                    continue
                landing = planted[stop] & ~planted[stop - 1]
                landing[k] = False
                if landing.any():
                    planted[start + limit:stop, landing] = True
                    moved = True
        if not moved:
            break
    return planted


def synthesize(skeleton: Skeleton, track: Track, name: str, gait: str | None,
               max_alone: int | None = None) -> Motion:
    """Generate a motion from a parameter track; ``max_alone``: no foot carries the body alone
    longer than this many frames (:func:`land_sooner`)."""
    T = track.length
    v = track.values
    root_z = np.concatenate([[0.0], np.cumsum(v["speed"][1:]) / FPS])
    # Strides. Rounded so that touchdowns falling exactly on a frame (LF at 0.25 of an 80-frame
    # stride) resolve the same way in every cycle despite the cumulative sum's rounding.
    clock = np.round(np.concatenate([[0.0], np.cumsum(track.frequency[1:]) / FPS]), 9)
    rest_pos = rest_positions(skeleton)
    root_pos, rot, global_pitch = _trunk(skeleton, track, clock, root_z)
    trunk_pos = forward_kinematics(skeleton, root_pos, rot)[0].astype(np.float64)

    # Legs.
    planted = footfalls(track, clock)
    if max_alone is not None:
        planted = land_sooner(planted, max_alone)
    contacts = np.zeros((T, 4), bool)
    for k, limb in enumerate(limbs_of(skeleton)):
        plan, solution = _plant_and_solve(skeleton, limb, planted[:, k], v, root_z, trunk_pos, global_pitch,
                                          rest_pos)
        contacts[:, k] = plan.planted
        rot[:, list(limb.chain[:-1])] = leg_rotations(skeleton, limb, solution.angles, global_pitch)
    motion = Motion(skeleton, root_pos.astype(np.float32), rot.astype(np.float32), FPS,
                    contacts=contacts, name=name, gait=gait)
    return motion


def _trunk(skeleton: Skeleton, track: Track, clock: Floats,
           root_z: Floats) -> tuple[Floats, NDArray[np.floating], Floats]:
    """The trunk's motion: root positions (T, 3), local rotations (T, J, 4) (the legs' still the
    rest pose's) and every joint's world pitch (T, J): root bob and pitch, spine flexion, neck
    nod, steady head, tail, the neck and tail swaying."""
    T = track.length
    v = track.values
    height = rest_root_height(skeleton)
    angles = np.zeros((T, skeleton.n_joints))  # local rotation about +X per joint (rad)
    root_y = height - v["crouch"] - v["bob"] * _wave(clock, v["bob_per_stride"], v["bob_low"])
    pitch = np.radians(v["pitch"]) * _wave(clock, 1, v["pitch_down"])
    spine = _joints(skeleton, "Spine")
    flex = np.radians(v["spine_flex"]) * _wave(clock, 1, v["spine_arched"])
    for j in spine:
        angles[:, j] = flex / len(spine)
    neck = _joints(skeleton, "Neck")
    nod = np.radians(v["nod"]) * _wave(clock, v["nod_per_stride"], v["nod_down"])
    for j in neck:
        angles[:, j] = nod / len(neck)
    head = skeleton.index("Head")
    angles[:, head] = -track.steady_head * (pitch + flex + nod)  # head level in the world
    tail = _joints(skeleton, "Tail")
    for k, j in enumerate(tail):
        lag = 0.12 * (k + 1)
        angles[:, j] = np.radians(v["tail_lift"] / len(tail)
                                  + v["tail_swing"] / len(tail) * _wave(clock, v["bob_per_stride"],
                                                                        v["bob_low"] + lag))
    global_pitch = _global_pitch(skeleton, angles, pitch)

    rot = rot_x(angles)
    rot[:, 0] = rot_x(pitch)
    # Neck and tail sway side to side once a stride, the tail lagging (the legs hang from the
    # trunk, which stays in its sagittal plane, so the feet are untouched).
    for chain, lag in ((neck, 0.0), (tail, 0.25)):
        for k, j in enumerate(chain):
            sway = np.radians(v["sway"]) / len(chain) * np.sin(2 * np.pi * (clock - lag - 0.08 * k))
            rot[:, j] = quat.mul(rot[:, j], quat.from_axis_angle(_Y, sway))
    root_pos = np.stack([np.zeros(T), root_y, root_z], axis=1)
    return root_pos, rot, global_pitch


def _plant_and_solve(skeleton: Skeleton, limb: Limb, foot_planted: NDArray[np.bool_], v: dict[str, Floats],
                     root_z: Floats, trunk_pos: Floats, global_pitch: Floats,
                     rest_pos: Floats) -> tuple[FootPlan, LegSolution]:
    """One foot's path and its leg's solution; a stance whose last frame leaves the leg out of
    reach ends up to ``MAX_EARLY_LIFT_FRAMES`` early."""
    leg_length = skeleton.leg_length()
    end = limb.chain[-1]
    neutral = rest_pos[end, 2] - rest_pos[0, 2]
    for _ in range(MAX_EARLY_LIFT_FRAMES + 1):
        lift = v["step_height"] * leg_length * FOOT_LIFT[limb.foot]
        plan = plan_foot(foot_planted, root_z, neutral, lift, v["touchdown_ease"], v["lift_fall"],
                         v["lift_off_speed"])
        solution = solve_limb(skeleton, limb, plan, trunk_pos, global_pitch, v,
                              rest_protraction(limb, rest_pos))
        # A foot left behind at (or beyond) the leg's full reach on its last stance frame lifts
        # a frame early: a straight leg's knee angle changes fastest (a pop), and beyond reach
        # the foot would hang in the air while called planted.
        last = foot_planted & ~np.append(foot_planted[1:], True)
        early = last & ((solution.miss > REACH_TOLERANCE) | (solution.extension > MAX_EXTENSION))
        if not early.any():
            break
        foot_planted = foot_planted & ~early
    return plan, solution


# --- clips ---------------------------------------------------------------------------------


def _at_origin(motion: Motion, name: str, gait: str | None) -> Motion:
    root = motion.root_pos.copy()
    root[:, 2] -= root[0, 2]
    return Motion(motion.skeleton, root, motion.rotations, FPS, motion.contacts, name, gait)


def loop_start(period: Motion) -> int:
    """Where a loop should start in one stride (``period``: N + 1 frames of a periodic motion).

    A loop of an exactly periodic motion is seamless wherever it is cut, but if the cut falls on a
    joint's fastest step, the step from the last frame to the first is (by construction) the
    largest, and a checker cannot tell it from a jump. So cut where, for every joint, the step into
    the first frame is furthest below that joint's fastest step.
    """
    N = period.n_frames - 1
    pos = period.positions().astype(np.float64)
    q = period.rotations.astype(np.float64)
    steps = np.concatenate([np.linalg.norm(np.diff(pos, axis=0), axis=-1),
                            quat.angle(quat.mul(quat.inv(q[:-1]), q[1:]))], axis=1)  # (N, 2J)
    # Each step against the fastest *other* step of its joint: the second fastest for the fastest.
    top = np.sort(steps, axis=0)
    others = np.where(steps == top[-1], top[-2], top[-1])
    worst = (steps / np.maximum(others, 1e-9)).max(axis=1)  # (N,) if this step were the seam
    return int((worst.argmin() + 1) % N)  # the loop starting at frame c has step c - 1 -> c on its seam


def cyclic_clip(skeleton: Skeleton, spec: GaitSpec) -> tuple[Motion, int]:
    """One stride of a gait that loops exactly (generated padded, then cut), and the stride frame
    it starts at (:func:`loop_start`; transitions from this gait start there too)."""
    N = spec.frames
    motion = synthesize(skeleton, constant_track(spec, 5 * N), spec.name, spec.name)
    start = loop_start(motion.slice(2 * N, 3 * N + 1))
    return _at_origin(motion.slice(2 * N + start, 3 * N + start), spec.name, spec.name), start


STILL_FRAMES = 12  # standing kept at either end of a start or stop, 0.2 s


def transition_clip(skeleton: Skeleton, a: GaitSpec, b: GaitSpec, name: str,
                    strides: float = 2.0, start: int = 0, end: int | None = None) -> Motion:
    """A blend from ``a`` to ``b`` over ``strides`` strides.

    Short, as an animal changes gait within a stride or so, and as synthesis wants: a character
    in a transition cannot follow its trajectory's speed until the transition ends. The clip
    starts ``start`` frames into a stride of ``a`` (pass ``a``'s cyclic clip's loop start, and it
    plays seamlessly after that loop). It ends where the blend does, at whatever phase of ``b``
    that is (the motion graph carries on from the matching frame of ``b``'s cycle); or, given
    ``end``, up to a stride later, one frame before ``end`` frames into a stride of ``b``. Where
    its own end would be a flight of ``b`` (no foot planted), it ends at :func:`steadiest_frame`.
    Starting or ending to stand, it keeps ``STILL_FRAMES`` of standing, so it clearly begins or
    ends at rest.
    """
    lead = STILL_FRAMES if a.name == "static" else 0  # standing has no phase to keep
    settle = STILL_FRAMES if b.name == "static" else 0
    pad = a.frames * -(-2 * max(a.frames, b.frames) // a.frames) + start  # whole strides of a, then start
    ramp = int(round(strides * 0.5 * (a.frames + b.frames)))
    head = constant_track(a, pad + a.frames)
    middle = blend_track(a, b, smoothstep(np.linspace(0.0, 1.0, ramp)))
    tail = constant_track(b, 2 * b.frames + pad)
    track = concat(head, middle, tail)
    # End where b's stride clock reads end / b.frames; the nearest frame is off by part of a frame,
    # which a slightly faster or slower stride frequency over the ramp makes up exactly.
    clock = np.concatenate([[0.0], np.cumsum(track.frequency[1:]) / FPS])
    nominal = pad + a.frames + ramp + settle
    stop = nominal
    if end is None and b.name != "static" and _in_flight(b, clock[nominal - 1]):
        end = steadiest_frame(b) + 1
    if end is not None:
        later = np.arange(nominal, nominal + b.frames)
        off = (clock[later] - end / b.frames + 0.5) % 1.0 - 0.5
        stop = int(later[np.abs(off).argmin()])
        ramp_frames = slice(pad + a.frames, pad + a.frames + ramp)
        track.frequency[ramp_frames] -= off[stop - nominal] * FPS / ramp
    # No foot alone longer than in either gait (a lone support as short as a swing is footfall
    # timing, not a foot carrying the body).
    alone = max(longest_alone(footfalls(constant_track(g, 3 * g.frames))) for g in (a, b))
    motion = synthesize(skeleton, track, name, None, max(alone, int(MIN_SWING_S * FPS)))
    return _at_origin(motion.slice(pad + a.frames - lead, stop), name, None)


def _in_flight(spec: GaitSpec, clock: float) -> bool:
    """Whether ``spec``'s stride has no foot planted at stride clock ``clock``."""
    planted = footfalls(constant_track(spec, spec.frames))
    return not planted[int(round(clock * spec.frames)) % spec.frames].any()


def steadiest_frame(spec: GaitSpec) -> int:
    """The frame of ``spec``'s stride a transition into it ends on where its own end would be a
    flight: the middle of the longest run of frames with the most feet planted. A finished
    transition's last frame is held while it fades out under the gait (plan_kernels._arrive);
    ended in a flight (the dog's walk2trot, on the trot's suspension, every paw 1-3 cm up), its
    low paws were dragged along the ground at the body's speed over the fade's first frames
    (issue 27's glide: 0.066 of the dog's accel_brake 0.165). Planted, the foot lock holds them;
    the other feet are mid-swing, at their highest."""
    planted = footfalls(constant_track(spec, spec.frames)).sum(axis=1)
    best = planted == planted.max()
    doubled = np.concatenate([best, best])  # a run may wrap around the stride's end
    length = np.zeros(len(doubled), np.int64)
    for i in range(len(doubled)):
        length[i] = length[i - 1] + 1 if doubled[i] and i > 0 else int(doubled[i])
    last = int(length.argmax())
    return (last - int(length[last]) // 2) % spec.frames


def idle_clip(skeleton: Skeleton, seconds: float = 10.0) -> Motion:
    """Standing: breathing, slow fore-aft weight shifts, the head looking about; feet planted.

    Periodic over the clip (every oscillation completes whole cycles), so it loops. A resting
    horse breathes 8-16 times a minute (Back & Clayton 2013); we use 12 (0.2 Hz).
    """
    T = int(round(seconds * FPS))
    t = np.arange(T) / FPS
    cycle = 2 * np.pi * t / seconds  # one weight shift per clip
    breath = np.sin(2 * np.pi * 0.2 * t)
    height = rest_root_height(skeleton)
    leg_length = skeleton.leg_length()
    root_pos = np.stack([np.zeros(T), height - 0.004 * leg_length * (1 + breath),
                         0.012 * leg_length * np.sin(cycle)], axis=1)
    angles = np.zeros((T, skeleton.n_joints))
    spine = _joints(skeleton, "Spine")
    for j in spine:
        angles[:, j] = np.radians(0.4) * breath / len(spine)
    neck = _joints(skeleton, "Neck")
    for j in neck:  # lower and raise the head slowly
        angles[:, j] = np.radians(6.0) * np.sin(2 * cycle + 0.5) / len(neck)
    tail = _joints(skeleton, "Tail")
    for k, j in enumerate(tail):
        angles[:, j] = np.radians(3.0) * np.sin(3 * cycle - 0.6 * k) / len(tail)
    rot = rot_x(angles)
    head = skeleton.index("Head")
    yaw = quat.from_axis_angle(_Y, np.radians(12.0) * np.sin(cycle + 1.0))  # looks left and right
    rot[:, head] = quat.mul(yaw, rot[:, head])
    global_pitch = _global_pitch(skeleton, angles, 0.0)
    trunk_pos, _ = forward_kinematics(skeleton, root_pos, rot)
    rest_pos = rest_positions(skeleton)
    v = {n: np.zeros(T) for n in NUMERIC}  # standing: no flexion, sink or breakover
    for limb in limbs_of(skeleton):
        foot_z = np.full(T, float(rest_pos[limb.chain[-1], 2]))
        plan = FootPlan(np.ones(T, bool), foot_z, np.zeros(T), np.full(T, 0.5), np.full(T, np.nan),
                        np.full(T, np.nan))
        solution = solve_limb(skeleton, limb, plan, trunk_pos.astype(np.float64), global_pitch,
                               v, rest_protraction(limb, rest_pos))
        rot[:, list(limb.chain[:-1])] = leg_rotations(skeleton, limb, solution.angles, global_pitch)
    return Motion(skeleton, root_pos.astype(np.float32), rot.astype(np.float32), FPS,
                  contacts=np.ones((T, 4), bool), name="idle", gait="static")
