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

from dataclasses import dataclass, fields, replace

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from synth_core import FOOT_NAMES
from synth_core.builtin.gaits import FOOT_LIFT, GaitSpec
from synth_core.builtin.limbs import MIN_DISTAL_FLEX, LegSolution, Limb, angle_of, limbs_of, solve_leg
from synth_core.motion import quat
from synth_core.motion.clip import Motion
from synth_core.motion.contacts import fill_gaps, runs
from synth_core.motion.skeleton import Skeleton, forward_kinematics

Floats = NDArray[np.float64]
FPS = 60.0
MIN_SWING_S = 0.05  # shorter swings are not taken (the foot stays planted)
MAX_EARLY_LIFT_FRAMES = 3  # a foot out of reach at the end of its stance lifts up to this early
REACH_TOLERANCE = 0.001  # m
MAX_EXTENSION = 0.985  # of the two main links' reach, on a stance's last frame
FULL_FLEX_SWING_S = 0.25  # swings at least this long flex the joints fully (every steady gait's do)
BREAKOVER_SHARE = 0.2  # of the stance: the hoof or paw rolls over its toe only in this last part
BROKEN_AT_LIFT = 0.4  # of the breakover angle reached at lift-off; the rest early in the swing
_X = np.array([1.0, 0.0, 0.0])
_Y = np.array([0.0, 1.0, 0.0])


# Standing zeroes what moves the body and loads the legs; how a foot swings (lift, flexion,
# breakover) stays ``like``'s, so the first and last steps of a start or stop are real steps.
_STILL = ("speed", "crouch", "bob", "pitch", "nod", "spine_flex", "fetlock_sink", "hock_load",
          "tail_lift", "tail_swing", "sway", "steady_head")


def static_spec(like: GaitSpec) -> GaitSpec:
    """Standing still: every foot planted, nothing oscillating; the stride clock keeps ``like``'s."""
    still: dict[str, object] = {name: 0.0 for name in _STILL}
    still.update(duty=1.0, name="static")
    return replace(like, **still)  # type: ignore[arg-type]


# --- parameter tracks ------------------------------------------------------------------------

_NUMERIC = [f.name for f in fields(GaitSpec) if f.type in ("float", "int") and f.name != "frames"]


@dataclass(frozen=True)
class Track:
    """Per-frame gait parameters: ``values[name] (T,)``, stride ``frequency (T,)`` Hz, ``phases (T, 4)``."""

    values: dict[str, Floats]
    frequency: Floats
    phases: Floats
    steady_head: Floats  # (T,) weight of the steady-head behaviour

    @property
    def length(self) -> int:
        return len(self.frequency)


def constant_track(spec: GaitSpec, length: int) -> Track:
    return blend_track(spec, spec, np.zeros(length))


def blend_track(a: GaitSpec, b: GaitSpec, weight: Floats) -> Track:
    """Parameters blended from ``a`` (weight 0) to ``b`` (weight 1); phases take the shorter way."""
    w = np.asarray(weight, dtype=np.float64)
    values = {n: (1 - w) * float(getattr(a, n)) + w * float(getattr(b, n)) for n in _NUMERIC}
    freq = (1 - w) * FPS / a.frames + w * FPS / b.frames
    # Blend the stance length (the ground a planted foot sweeps), not the duty factor: speed,
    # frequency and duty blended separately make mid-transition stances longer than either gait's
    # and beyond the legs' reach. Near standstill the duty factor is blended as it is.
    stance = (1 - w) * a.speed * a.duty / (FPS / a.frames) + w * b.speed * b.duty / (FPS / b.frames)
    stride = values["speed"] / freq
    moving = stride > 0.25 * max(a.speed / (FPS / a.frames), b.speed / (FPS / b.frames))
    values["duty"] = np.where(moving, np.clip(stance / np.maximum(stride, 1e-9), 0.0, 1.0), values["duty"])
    pa = np.array([a.phases[f] for f in FOOT_NAMES])
    pb = np.array([b.phases[f] for f in FOOT_NAMES])
    pb = pa + ((pb - pa + 0.5) % 1.0 - 0.5)  # continuous footfall order: nearest equivalent phase
    phases = (1 - w)[:, None] * pa + w[:, None] * pb
    steady = (1 - w) * float(a.steady_head) + w * float(b.steady_head)
    return Track(values, freq, phases, steady)


def concat(*tracks: Track) -> Track:
    return Track({n: np.concatenate([t.values[n] for t in tracks]) for n in tracks[0].values},
                 np.concatenate([t.frequency for t in tracks]),
                 np.concatenate([t.phases for t in tracks]),
                 np.concatenate([t.steady_head for t in tracks]))


def smoothstep(x: Floats) -> Floats:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def min_jerk(s: Floats) -> Floats:
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10 - 15 * s + 6 * s * s)


# --- feet ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class FootPlan:
    planted: NDArray[np.bool_]  # (T,)
    z: Floats  # (T,) world forward position of the toe
    y: Floats  # (T,) toe height
    stance_w: Floats  # (T,) progress through the current stance (0..1), NaN in swing
    swing_s: Floats  # (T,) progress through the current swing (0..1), NaN in stance
    swing_frames: Floats  # (T,) length of the current swing in frames, NaN in stance


def plan_foot(planted: NDArray[np.bool_], root_z: Floats, neutral_z: float, lift: Floats,
              ease_down: Floats | float = 0.25, lift_fall: Floats | float = 1.2) -> FootPlan:
    """Plants at the root's mid-stance place (square when open-ended) and swings between them."""
    T = len(planted)
    stance = runs(planted)
    if len(stance) == 0:
        raise ValueError("a foot never touches the ground in this clip")
    start, stop = stance[:, 0], stance[:, 1]
    mid = 0.5 * (root_z[start] + root_z[stop - 1])
    mid = np.where(start == 0, root_z[0], mid)  # open at the clip start: standing there
    mid = np.where(stop == T, root_z[-1], mid)  # open at the end: standing there
    plant_z = mid + neutral_z
    t = np.arange(T)
    # Index of the stance run at or before each frame (-1 before the first).
    prev = np.searchsorted(start, t, side="right") - 1
    prev_c = np.clip(prev, 0, len(stance) - 1)
    nxt = np.clip(prev + 1, 0, len(stance) - 1)
    lo = stop[prev_c]  # first swing frame after the previous plant
    td = start[nxt]
    span = np.maximum(td - lo + 1, 1)
    s = np.clip((t - lo + 1) / span, 0.0, 1.0)
    before_first, after_last = prev < 0, prev >= len(stance) - 1
    # The swing is planned relative to the body: the foot leaves from behind and is brought forward
    # to its next plant, never further ahead than that plant (a path planned in the world would
    # overtake the body mid-swing at a gallop, out of the leg's reach).
    behind = plant_z[prev_c] - root_z[np.clip(lo - 1, 0, T - 1)]
    ahead = plant_z[nxt] - root_z[np.clip(td, 0, T - 1)]
    z_body = root_z + behind + (ahead - behind) * min_jerk(s)
    swinging = ~planted & ~before_first & ~after_last
    z_swing = _eased_over_ground(z_body, swinging, planted, start, stop, plant_z, prev_c, lo, td, span,
                                 np.broadcast_to(ease_down, (T,)))
    z_swing = np.where(before_first, plant_z[0], np.where(after_last, plant_z[-1], z_swing))
    # Lifts steeply and comes down as steeply or a little less (``lift_fall``), peaking at or just
    # before mid-swing (a hoof's flight peaks around mid-swing, gait-reference table 4): the toe is
    # soon clear of the ground it would otherwise skim (the real dog's feet spend a frame or two
    # below 2.5 cm at each end). A short swing (the first steps of a start) lifts the foot less.
    bump = lift_profile(s, lift_fall)
    short = np.clip((span - 1.0) / (FULL_FLEX_SWING_S * FPS), 0.0, 1.0) ** 0.4
    y_swing = np.where(before_first | after_last, 0.0, lift * short * bump)
    z = np.where(planted, plant_z[prev_c], z_swing)
    y = np.where(planted, 0.0, y_swing)
    w = (t - start[prev_c] + 0.5) / (stop[prev_c] - start[prev_c])
    return FootPlan(planted, z, y, np.where(planted, w, np.nan), np.where(planted, np.nan, s),
                    np.where(planted, np.nan, span - 1.0))


# Swing height profile s^LIFT_RISE (1 - s)^fall (fall: the gait's ``lift_fall``), scaled to peak at 1.
LIFT_RISE = 1.0  # rises steeply: the toe is clear of the ground within a frame or two


def lift_profile(s: Floats, fall: Floats | float = 1.2) -> Floats:
    fall = np.asarray(fall, dtype=np.float64)
    peak = LIFT_RISE / (LIFT_RISE + fall)
    return np.asarray(s**LIFT_RISE * (1 - s) ** fall / (peak**LIFT_RISE * (1 - peak) ** fall))
# The foot's world speed ramps up over this share of its swing after lift-off (and down to rest
# over the gait's ``touchdown_ease`` before touchdown): lift quickly, slow before touchdown, as
# the MANN dog's feet do.
SPEED_RAMP_UP = 0.25
# Share of the plan's speed a foot leaves the ground with: the leg is at full stretch behind at
# lift-off, so a foot lagging further would be out of its reach (a kink of the elbow or stifle).
LIFT_OFF_SPEED = 0.5


def _eased_over_ground(z_body: Floats, swinging: NDArray[np.bool_], planted: NDArray[np.bool_],
                       start: NDArray[np.int64], stop: NDArray[np.int64], plant_z: Floats,
                       prev_c: NDArray[np.int64], lo: NDArray[np.int64], td: NDArray[np.int64],
                       span: NDArray[np.int64], ease_down: Floats) -> Floats:
    """Swing positions (T,) with the body-relative plan's per-frame advance eased in and out.

    The body-relative plan leaves and meets the ground at the body's speed: a foot sliding along
    as it peels off and sets down. Each frame's advance (into the touchdown frame included) is
    weighted by ramps from zero after lift-off and to zero before touchdown, and the swing's
    advances rescaled so it still spans its two plants. The foot lags the plan a little early in
    the swing and reaches a little beyond it late, as swing legs retract before touchdown.
    ``ease_down (T,)``: the share of the swing the foot slows down over (the gait's
    ``touchdown_ease``).
    """
    T = len(z_body)
    t = np.arange(T)
    landing = planted & np.isin(t, start) & (t > start[0])  # touchdown frames ending a swing
    member = swinging | landing
    # Each member frame's swing, by its lift-off frame lo_k and touchdown frame td_k.
    prev_run = np.searchsorted(start, t, side="right") - 1
    lo_k = np.where(landing, stop[np.clip(prev_run - 1, 0, len(stop) - 1)], lo)
    td_k = np.where(landing, t, td)
    span_k = np.where(landing, td_k - lo_k + 1, span).astype(np.float64)
    plan = np.where(swinging, z_body, plant_z[prev_c])  # stance frames: on their plant
    advance = np.diff(plan, prepend=plan[0])
    up = smoothstep((t - lo_k + 1) / np.maximum(SPEED_RAMP_UP * span_k, 1.0))
    up = LIFT_OFF_SPEED + (1 - LIFT_OFF_SPEED) * up
    down = smoothstep((td_k - t + 1) / np.maximum(ease_down[np.clip(td_k, 0, T - 1)] * span_k, 1.0))
    weighted = np.cumsum(np.where(member, advance * up * down, 0.0))
    before = weighted[np.clip(lo_k - 1, 0, T - 1)]
    total = weighted[np.clip(td_k, 0, T - 1)] - before
    p0 = plan[np.clip(lo_k - 1, 0, T - 1)]
    p1 = plan[np.clip(td_k, 0, T - 1)]
    ok = np.abs(total) > 1e-9
    frac = np.where(ok, (weighted - before) / np.where(ok, total, 1.0), 0.0)
    return np.where(swinging & ok, p0 + (p1 - p0) * frac, z_body)


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


def _rot_x(angle: Floats) -> NDArray[np.floating]:
    return quat.from_axis_angle(_X, angle)


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
    height = rest_root_height(skeleton)
    leg_length = skeleton.leg_length()
    rest_pos = rest_positions(skeleton)

    # Trunk: root bob and pitch, spine flexion, neck nod, steady head, tail.
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

    rot = _rot_x(angles)
    rot[:, 0] = _rot_x(pitch)
    # Neck and tail sway side to side once a stride, the tail lagging (the legs hang from the
    # trunk, which stays in its sagittal plane, so the feet are untouched).
    for chain, lag in ((neck, 0.0), (tail, 0.25)):
        for k, j in enumerate(chain):
            sway = np.radians(v["sway"]) / len(chain) * np.sin(2 * np.pi * (clock - lag - 0.08 * k))
            rot[:, j] = quat.mul(rot[:, j], quat.from_axis_angle(_Y, sway))
    root_pos = np.stack([np.zeros(T), root_y, root_z], axis=1)
    trunk_pos = forward_kinematics(skeleton, root_pos, rot)[0].astype(np.float64)

    # Legs.
    planted = footfalls(track, clock)
    if max_alone is not None:
        planted = land_sooner(planted, max_alone)
    contacts = np.zeros((T, 4), bool)
    for k, limb in enumerate(limbs_of(skeleton)):
        end = limb.chain[-1]
        neutral = rest_pos[end, 2] - rest_pos[0, 2]
        foot_planted = planted[:, k]
        for _ in range(MAX_EARLY_LIFT_FRAMES + 1):
            lift = v["step_height"] * leg_length * FOOT_LIFT[limb.foot]
            plan = plan_foot(foot_planted, root_z, neutral, lift, v["touchdown_ease"], v["lift_fall"])
            solution = _solve_limb(skeleton, limb, plan, trunk_pos, global_pitch, v,
                                   _rest_protraction(limb, rest_pos))
            # A foot left behind at (or beyond) the leg's full reach on its last stance frame lifts
            # a frame early: a straight leg's knee angle changes fastest (a pop), and beyond reach
            # the foot would hang in the air while called planted.
            last = foot_planted & ~np.append(foot_planted[1:], True)
            early = last & ((solution.miss > REACH_TOLERANCE) | (solution.extension > MAX_EXTENSION))
            if not early.any():
                break
            foot_planted = foot_planted & ~early
        contacts[:, k] = plan.planted
        rot[:, list(limb.chain[:-1])] = _leg_rotations(skeleton, limb, solution.angles, global_pitch)
    motion = Motion(skeleton, root_pos.astype(np.float32), rot.astype(np.float32), FPS,
                    contacts=contacts, name=name, gait=gait)
    return motion


def _rest_protraction(limb: Limb, rest_pos: NDArray[np.floating]) -> float:
    """Standing angle (from straight down) of the line from the limb root to the toe."""
    return float(angle_of(rest_pos[limb.chain[-1], [2, 1]] - rest_pos[limb.chain[0], [2, 1]]))


def _leg_rotations(skeleton: Skeleton, limb: Limb, bone_angles: Floats,
                   global_pitch: Floats) -> NDArray[np.floating]:
    """Local rotations (F, B, 4) of a leg's chain joints from its bones' world sagittal angles."""
    parent_pitch = global_pitch[:, skeleton.parents[limb.chain[0]]]
    bone_global = limb.rest_angles[None] - bone_angles  # X-rotation of each chain joint in the world
    return _rot_x(np.diff(np.concatenate([parent_pitch[:, None], bone_global], axis=1), axis=1))


def _solve_limb(skeleton: Skeleton, limb: Limb, plan: FootPlan, trunk_pos: Floats,
                global_pitch: Floats, v: dict[str, Floats], rest_protraction: float) -> LegSolution:
    in_stance = plan.planted
    w = np.nan_to_num(plan.stance_w)
    s = np.nan_to_num(plan.swing_s)
    # Flexion rises from zero slope at lift-off (no pop) and peaks early in swing; a short swing
    # (the first steps of a start) flexes less, as a joint can only fold so fast.
    short = np.clip(np.nan_to_num(plan.swing_frames) / (FULL_FLEX_SWING_S * FPS), 0.0, 1.0)
    swing_bump = np.where(in_stance, 0.0, short * np.sin(np.pi * s**0.75) ** 2)
    load = np.where(in_stance, np.sin(np.pi * w), 0.0)
    fore = limb.girdle is not None
    distal = np.radians(np.where(fore, v["carpus_flex"], v["hock_flex"])) * swing_bump
    if not fore:
        distal = distal + np.radians(v["hock_load"]) * load
    # Digits: the fetlock sinks under load; the hoof breaks over the toe; the digits fold in swing.
    # The hoof (paw) stands flat through the stance and breaks over its toe in the last
    # BREAKOVER_SHARE of it (issue 28: a hoof rolling on its toe all stance long reads wrong).
    # Part of it by lift-off (easing in), the rest early in the swing as the heel rises further,
    # then it unwinds: a quick stance (a gallop's 8 frames) breaks over without a snap. The bones
    # above the hoof (the pastern) turn from mid-stance on, as the fetlock rises off its sink:
    # that moves the fetlock, not the hoof, and leaves the leg the reach it has at lift-off.
    over = np.clip((w - 1.0 + BREAKOVER_SHARE) / BREAKOVER_SHARE, 0.0, 1.0)
    after = np.where(s < 0.25, BROKEN_AT_LIFT + (1 - BROKEN_AT_LIFT) * np.sin(0.5 * np.pi * s / 0.25),
                     1.0 - smoothstep((s - 0.25) / 0.4))
    hoof = np.where(in_stance, BROKEN_AT_LIFT * over**2, after)
    pastern = np.where(in_stance, smoothstep((w - 0.5) / 0.5), 1.0 - smoothstep(s / 0.5))
    digits = list(limb.digits)
    breakover = np.radians(v["breakover"])[:, None] * np.concatenate(
        [np.repeat(pastern[:, None], len(digits) - 1, axis=1), hoof[:, None]], axis=1)
    digit_angles = limb.rest_angles[digits][None] - breakover \
        - np.radians(v["digit_flex"])[:, None] * swing_bump[:, None]
    if len(digits) > 1:  # the pastern sinks; a lone digit bone is the paw itself, kept flat
        digit_angles[:, 0] += np.radians(v["fetlock_sink"]) * load
    root = trunk_pos[:, limb.chain[0]][:, [2, 1]]
    foot = np.stack([plan.z, plan.y], axis=1)
    girdle = None
    if fore:
        # The scapula rides with the trunk's pitch and swings with the leg: about a third of the
        # leg's protraction from standing (the shoulder blade's share of forelimb swing).
        trunk = global_pitch[:, skeleton.parents[limb.chain[0]]]
        girdle = limb.rest_angles[limb.girdle] - trunk + 0.35 * (angle_of(foot - root) - rest_protraction)
    # Reach adaptation: full in stance, fading out over the first and in over the last 30% of swing.
    adapt = np.where(in_stance, 1.0, np.maximum(1.0 - smoothstep(s / 0.3), smoothstep((s - 0.7) / 0.3)))
    first = solve_leg(limb, root, foot, girdle, distal, digit_angles, adapt=adapt)
    if girdle is not None:
        girdle = girdle + _ease(first.angles[:, limb.girdle] - girdle)
    # (Eased, the opening may reach frames whose own flexion is smaller: keep the joint's limit.)
    distal = np.maximum(distal + _ease(first.distal_flex - distal),
                        np.minimum(MIN_DISTAL_FLEX[limb.flex_sign], distal))
    solution = solve_leg(limb, root, foot, girdle, distal, digit_angles, adapt=adapt)
    return replace(solution, angles=_smooth_swing(solution.angles, in_stance, s))


SWING_SMOOTHING = 1.5  # frames (Gaussian sigma) over the middle of a swing


def _smooth_swing(angles: Floats, in_stance: NDArray[np.bool_], s: Floats) -> Floats:
    """Bone angles (F, B) smoothed in time in mid-swing, untouched near and in stance.

    Mid-swing the leg is folded high, where the two-link solution turns fastest as the fetlock
    nears the shoulder or hip (a one-frame kink of the elbow or stifle); there the toe path is
    only a guide, so its curve may give a little. Near lift-off and touchdown nothing changes.
    """
    smoothed = gaussian_filter1d(angles, SWING_SMOOTHING, axis=0, mode="nearest")
    weight = np.where(in_stance, 0.0, smoothstep((np.minimum(s, 1.0 - s) - 0.15) / 0.2))
    return np.asarray(angles + weight[:, None] * (smoothed - angles))


def _ease(correction: Floats, frames: int = 9) -> Floats:
    """A reach correction spread out in time: at least as large where it was needed, no step.

    Corrections found frame by frame switch on where the foot first runs out of reach, so the
    girdle or hock would jump. A running maximum of each sign's magnitude, then a Gaussian, starts
    them earlier and eases them in and out.
    """
    up = gaussian_filter1d(maximum_filter1d(np.maximum(correction, 0.0), frames, mode="nearest"),
                           frames / 4, mode="nearest")
    down = gaussian_filter1d(maximum_filter1d(np.maximum(-correction, 0.0), frames, mode="nearest"),
                             frames / 4, mode="nearest")
    return np.asarray(up - down)


# --- clips -----------------------------------------------------------------------------------


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
    ``end``, up to a stride later, one frame before ``end`` frames into a stride of ``b``.
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
    rot = _rot_x(angles)
    head = skeleton.index("Head")
    yaw = quat.from_axis_angle(_Y, np.radians(12.0) * np.sin(cycle + 1.0))  # looks left and right
    rot[:, head] = quat.mul(yaw, rot[:, head])
    global_pitch = _global_pitch(skeleton, angles, 0.0)
    trunk_pos, _ = forward_kinematics(skeleton, root_pos, rot)
    rest_pos = rest_positions(skeleton)
    v = {n: np.zeros(T) for n in _NUMERIC}  # standing: no flexion, sink or breakover
    for limb in limbs_of(skeleton):
        foot_z = np.full(T, float(rest_pos[limb.chain[-1], 2]))
        plan = FootPlan(np.ones(T, bool), foot_z, np.zeros(T), np.full(T, 0.5), np.full(T, np.nan),
                        np.full(T, np.nan))
        solution = _solve_limb(skeleton, limb, plan, trunk_pos.astype(np.float64), global_pitch,
                               v, _rest_protraction(limb, rest_pos))
        rot[:, list(limb.chain[:-1])] = _leg_rotations(skeleton, limb, solution.angles, global_pitch)
    return Motion(skeleton, root_pos.astype(np.float32), rot.astype(np.float32), FPS,
                  contacts=np.ones((T, 4), bool), name="idle", gait="static")
