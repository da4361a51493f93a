"""Each foot's path over a generated clip (:mod:`synth_core.builtin.generator`, step 3): plants
at the root's mid-stance place, swings between them planned relative to the body and eased in the
world, lifted by a rise-and-fall profile."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from synth_core.builtin.tracks import FPS, Floats, min_jerk, smoothstep
from synth_core.motion.contacts import runs

FULL_FLEX_SWING_S = 0.25  # swings at least this long flex the joints fully (every steady gait's do)


@dataclass(frozen=True)
class FootPlan:
    planted: NDArray[np.bool_]  # (T,)
    z: Floats  # (T,) world forward position of the toe
    y: Floats  # (T,) toe height
    stance_w: Floats  # (T,) progress through the current stance (0..1), NaN in swing
    swing_s: Floats  # (T,) progress through the current swing (0..1), NaN in stance
    swing_frames: Floats  # (T,) length of the current swing in frames, NaN in stance


# Share of the plan's speed a foot leaves the ground with, unless its gait says
# (``GaitSpec.lift_off_speed``): the horse's leg is at full stretch behind at lift-off, so a hoof
# lagging further would be out of its reach (a kink of the elbow or stifle).
LIFT_OFF_SPEED = 0.5


def plan_foot(planted: NDArray[np.bool_], root_z: Floats, neutral_z: float, lift: Floats,
              ease_down: Floats | float = 0.25, lift_fall: Floats | float = 1.2,
              lift_off: Floats | float = LIFT_OFF_SPEED) -> FootPlan:
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
    swings = _Swings(start, stop, prev_c, lo, td, span)
    z_swing = _eased_over_ground(z_body, swinging, planted, plant_z, swings, np.broadcast_to(ease_down, (T,)),
                                 np.broadcast_to(lift_off, (T,)))
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


@dataclass(frozen=True)
class _Swings:
    """A foot's stance runs ``[start, stop)`` (P,) and, per frame (T,): the run at or before it
    (``prev``, clipped), the swing it is in or follows (lift-off frame ``lo``, touchdown frame
    ``td``) and that swing's ``span`` in frames."""

    start: NDArray[np.int64]
    stop: NDArray[np.int64]
    prev: NDArray[np.int64]
    lo: NDArray[np.int64]
    td: NDArray[np.int64]
    span: NDArray[np.int64]


def _eased_over_ground(z_body: Floats, swinging: NDArray[np.bool_], planted: NDArray[np.bool_],
                       plant_z: Floats, swings: _Swings, ease_down: Floats,
                       lift_off: Floats) -> Floats:
    """Swing positions (T,) with the body-relative plan's per-frame advance eased in and out.

    The body-relative plan leaves and meets the ground at the body's speed: a foot sliding along
    as it peels off and sets down. Each frame's advance (into the touchdown frame included) is
    weighted by ramps from zero after lift-off and to zero before touchdown, and the swing's
    advances rescaled so it still spans its two plants. The foot lags the plan a little early in
    the swing and reaches a little beyond it late, as swing legs retract before touchdown.
    ``ease_down (T,)``: the share of the swing the foot slows down over (the gait's
    ``touchdown_ease``); ``lift_off (T,)``: the share of the plan's speed it leaves the ground
    with (the gait's ``lift_off_speed``, read at each swing's lift-off frame).
    """
    start, stop, prev_c, lo, td, span = (swings.start, swings.stop, swings.prev, swings.lo, swings.td,
                                         swings.span)
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
    start_speed = lift_off[np.clip(lo_k, 0, T - 1)]
    up = start_speed + (1 - start_speed) * up
    down = smoothstep((td_k - t + 1) / np.maximum(ease_down[np.clip(td_k, 0, T - 1)] * span_k, 1.0))
    weighted = np.cumsum(np.where(member, advance * up * down, 0.0))
    before = weighted[np.clip(lo_k - 1, 0, T - 1)]
    total = weighted[np.clip(td_k, 0, T - 1)] - before
    p0 = plan[np.clip(lo_k - 1, 0, T - 1)]
    p1 = plan[np.clip(td_k, 0, T - 1)]
    ok = np.abs(total) > 1e-9
    frac = np.where(ok, (weighted - before) / np.where(ok, total, 1.0), 0.0)
    return np.where(swinging & ok, p0 + (p1 - p0) * frac, z_body)
