"""The render, written once: pose assembly, warp and foot lock (Sung 2011 section 6, steps 2-4,
and the foot lock beyond the paper: :mod:`synth_core.runtime.footlock`).

Character by character in parallel (``prange``), frame by frame in registers, so nothing the size
of (characters, frames, joints) is made more than once (the output). Numba compiles these
functions (:func:`synth_core.compiled.jit.render_jit`); :data:`REFERENCE` is the same source --
these and their helpers in the pose, foot, limb, vec and ground kernels' modules -- run by the
interpreter, as the planner's is (slow: for tests and for a machine without numba).
``compiled=False`` asks the wrappers for it; :mod:`synth_core.compiled.backend` names the two.

One character, in four passes over its frames:

1. blend the plan's table rows (and the piece fading out), turn the root to the heading, lean it
   into the turn, put it on the path, its surge along the path's way (:func:`.pose_kernels.assemble`);
   forward kinematics of the joints above the feet only, in the character's unit (its world
   divided by its scale h: the library skeleton's geometry);
2. plant targets per foot (:func:`~synth_core.compiled.foot_kernels.plant_targets`);
3. the root's sink where a target needs a leg straighter than ``REACH`` or than the animal's
   poses reach (eased, bounded);
4. limb IK (:func:`synth_core.build.ik.solve`, without the ground tipping) on the upper joint, hinge
   and ankle of each leg -- 16 frames at a time in SIMD lanes (:mod:`~synth_core.compiled.limb_kernels`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple, TypeVar

import numpy as np
from numpy.typing import NDArray

from synth_core import UP_AXIS
from synth_core.build.ik import leg_ranges, limb_rigs
from synth_core.compiled import (
    foot_kernels,
    ground_kernels,
    jump_kernels,
    limb_kernels,
    pose_kernels,
    replant_kernels,
    swing_kernels,
    vec_kernels,
)
from synth_core.compiled.foot_kernels import (
    LEG_WIDTH,
    NOWHERE,
    ease_sink,
    fold_room,
    ground_targets,
    held,
    lock_contexts,
    measure_feet,
    plant_targets,
    reach_sink,
)
from synth_core.compiled.jit import AVAILABLE as AVAILABLE  # callers ask kernels.AVAILABLE
from synth_core.compiled.jit import interpreted, prange, render_jit, threads
from synth_core.compiled.limb_kernels import LANES, fk, solve_legs
from synth_core.compiled.pose_kernels import assemble, clip_soles, root_only
from synth_core.compiled.posed import Posed as Posed  # callers ask kernels.Posed
from synth_core.compiled.posed import checked
from synth_core.compiled.scratch import Scratch
from synth_core.compiled.vec_kernels import (
    put,
    q4,
    qmul,
)
from synth_core.runtime.bank import standing_heights, table_positions
from synth_core.runtime.footlock import MAX_SINK, PAD, STEP_S, TERRAIN_MAX_SINK

if TYPE_CHECKING:
    from synth_core.runtime.bank import Bank
    from synth_core.runtime.plan import Plan
    from synth_core.runtime.terrain import Grounding

F = TypeVar("F", bound=Callable[..., Any])


_jit = render_jit


WHOLE_PLANT = 1 << 62  # plant_frames: a plant's target averages all its frames


# --- the four passes ---------------------------------------------------------------------------

@_jit()
def _character(poses: Any, height: Any, surge: Any, paws: Any, rows: Any, weights: Any, yaw: Any, lean: Any,
               path: Any, way: Any, h: float, contacts: Any, parents: Any, offsets: Any, fk_joints: Any,
               rigs: Any, bends: Any, sink_limit: float, foot_lock: bool, out_rot: Any, out_root: Any,
               world: Any, feet: Any, legs: Any, targets: Any, sink: Any, eased: Any, keep_from: int,
               keep_to: int, known_feet: Any, known: int, recent: Any, recent_known: bool, tilt: Any,
               tilt_at: int, heights: Any, ground_x0: float, ground_z0: float, spacing: float,
               plant_frames: int, pins: Any, pinned: Any, steps: bool, sent: Any, sides: Any,
               kept: Any) -> bool:
    """All four passes for one character (scratch arrays given). Only frames ``[keep_from, keep_to)``
    are wanted (a window over its foot lock's context): the legs' IK is solved for those alone.
    ``known_feet (T, 4, 3)``: the feet of frames ``[0, known)`` made already (a live session's
    earlier windows), read there, not posed again, and written for the frames posed (an empty
    array: none kept). ``recent (PAD, 4, LEG_WIDTH)``: what the sink reads of the PAD frames before
    ``keep_from``, if ``recent_known`` (then ``known >= keep_from``; not posed either); on return
    the same of the PAD frames before ``keep_to``: True if it does; ``kept``: its contacts, foot_kernels.held
    ``heights (Nz, Nx)``: the terrain (``(0, 0)``: none), grid origin, spacing; the body tilted by
    ``tilt[tilt_at + t]`` (``(T', 4)``) on frame t, its feet planted on the terrain (measure_feet).
    ``plant_frames``: plant_targets' ``most`` (feet kept: its pins, sent too); ``steps``: render_window's;
    ``sides``: solve_legs' ``before``."""
    terrain, T = heights.shape[0] > 0, out_rot.shape[0]
    if not foot_lock:
        kept[...] = contacts[keep_from:keep_to]  # (no feet held: the plan's)
        keep_from, keep_to, known, recent_known = 0, T, 0, False  # no context
    # Posed from a; the sink from s, the first frame the wanted frames' eased sink reads.
    if recent_known:
        s, a = keep_from - PAD, keep_from
        legs[s:a] = recent
    else:
        s = a = max(min(known, keep_from - PAD), 0)
    assemble(poses, height, surge, rows[a:], weights[a:], yaw[a:], lean[a:], path[a:], way[a:], h,
             out_rot[a:], out_root[a:])
    if terrain:
        for t in range(a, T):
            put(out_rot[t, 0], qmul(q4(tilt[tilt_at + t]), q4(out_rot[t, 0])))
    if not foot_lock:
        return False
    # The world's origin: a block from the first wanted frame (a window up to LANES frames: one IK block).
    o = keep_from - LANES * ((keep_from - a + LANES - 1) // LANES)
    fk(out_rot, out_root, h, parents, offsets, fk_joints, world, a, T, o)
    feet[:a] = known_feet[:a]
    measure_feet(world, out_root, yaw, lean, path, tilt, tilt_at, terrain, rigs, h, a, T, o, feet, legs)
    if known_feet.shape[0] > 0:
        known_feet[a:] = feet[a:]
    last = -1 if plant_frames == WHOLE_PLANT or known_feet.shape[0] == 0 else keep_to - 1
    body = (bends, legs, sink_limit, a, path, terrain / h, yaw, out_root, h, steps, keep_from, sent)
    soles = clip_soles(paws, rows, weights, path, terrain, h)
    air = plant_targets(feet, soles, contacts, targets, plant_frames, pins, pinned, last, body)
    if terrain:
        ground_targets(targets, contacts, heights, ground_x0, ground_z0, spacing, h, sink, plant_frames)
    reach_sink(targets, legs, bends, path, h, terrain, s, T, sink)
    # Eased from frame s on: the wanted frames, PAD or more after it, read nothing before it.
    ease_sink(sink[s:], sink_limit, eased[s:])
    fold_room(targets, legs, bends, sink_limit, s, T, eased, sink)  # the sink read: its frames free
    out_root[a:, 1] = (out_root[a:, 1] / h - eased[a:]) * h
    held(air, targets, legs, bends, eased, h, keep_from, keep_to, kept)
    solve_legs(world, targets, eased, rigs, parents, offsets, bends, out_rot, keep_from, keep_to, o, sides)
    if keep_to - PAD >= s:
        recent[...] = legs[keep_to - PAD:keep_to]
    return keep_to - PAD >= s


@_jit(parallel=True)
def _render_all(poses: Any, height: Any, surge: Any, paws: Any, rows: Any, weights: Any, yaw: Any, lean: Any,
                path: Any, way: Any, scales: Any, contacts: Any, parents: Any, offsets: Any, fk_joints: Any,
                rigs: Any, bends: Any, sink_limit: float, foot_lock: bool, out_rot: Any, out_root: Any,
                w_world: Any, w_feet: Any, w_legs: Any, w_targets: Any, w_sink: Any, w_eased: Any, tilt: Any,
                heights: Any, ground_x0: float, ground_z0: float, spacing: float, pose: Any,
                kept: Any) -> None:
    """``w_*``: one working set per worker (first axis), reused for its characters: a fresh
    megabyte per character would cost more in page faults than the lock's arithmetic.
    ``pose (C,)``: the characters posed; the others get their root alone (:func:`root_only`)
    and their rotations are left as they were in ``out_rot``, their ``kept (C, T, 4)`` the plan's contacts."""
    C = out_rot.shape[0]
    workers = min(C, w_world.shape[0])
    none_known = np.empty((0, 4, 3))
    no_pins, unpinned, no_sent = np.empty((4, 3)), np.full(4, NOWHERE), np.empty((2, 4, 3))
    for worker in prange(workers):
        world, feet, legs, targets = w_world[worker], w_feet[worker], w_legs[worker], w_targets[worker]
        sink, eased = w_sink[worker], w_eased[worker]
        recent, no_sides = np.empty((PAD, 4, LEG_WIDTH)), np.zeros((4, 4))  # (a whole plan: no frame before)
        for c in range(worker, C, workers):
            no_sides[:, 3] = 0.0
            if not pose[c]:
                root_only(height, surge, rows[c], weights[c], path[c], way[c], scales[c], out_root[c])
                kept[c] = contacts[c]
                continue
            own_tilt = tilt[c] if heights.shape[0] > 0 else tilt[0]
            _character(poses, height, surge, paws, rows[c], weights[c], yaw[c], lean[c], path[c], way[c],
                       scales[c], contacts[c], parents, offsets, fk_joints, rigs, bends, sink_limit,
                       foot_lock, out_rot[c], out_root[c], world, feet, legs, targets, sink, eased, 0,
                       out_rot.shape[1], none_known, 0, recent, False, own_tilt, 0, heights, ground_x0,
                       ground_z0, spacing, WHOLE_PLANT, no_pins, unpinned, True, (no_sent, NOWHERE),
                       no_sides, kept[c])


@_jit(parallel=True)
def _render_windows(poses: Any, height: Any, surge: Any, paws: Any, rows: Any, weights: Any, yaw: Any,
                    lean: Any, path: Any, way: Any, scales: Any, contacts: Any, parents: Any, offsets: Any,
                    fk_joints: Any, rigs: Any, bends: Any, sink_limit: float, foot_lock: bool, workers: int,
                    begin: Any, end: Any, start: int, out_rot: Any, out_root: Any, tilt: Any, heights: Any,
                    ground_x0: float, ground_z0: float, spacing: float, pose: Any, known_feet: Any,
                    known: Any, known_legs: Any, legs_at: Any, pins: Any, pinned: Any, sent: Any,
                    sent_at: Any, sides: Any, plant_frames: int, steps: bool, kept: Any, c0: int,
                    c1: int) -> None:
    """Frames ``[start, start + out.shape[1])`` of characters ``[c0, c1)``, each rendered over its own context
    ``[begin[c], end[c])`` of the plan (see :func:`render_window`); ``known_feet`` (``(0, C, 4, 3)``: none) to
    ``sides``: a :class:`Posed`'s, moved on (``known`` to ``end``, ``legs_at`` to the window's end, pins to
    its last frame's plants, ``sent`` to its last two frames, ``sides`` to its last). Calls for disjoint
    character ranges may run side by side. ``pose (C,)``: the characters posed; the others get their root
    alone (:func:`root_only`), rotations untouched; ``kept (C, n, 4)``: feet planted (far: the plan's)."""
    n, J = out_rot.shape[1], out_rot.shape[2]
    longest = 0
    for c in range(c0, c1):
        longest = max(longest, end[c] - begin[c])
    workers = min(c1 - c0, workers)
    keep = known_feet.shape[0] > 0
    for worker in prange(workers):
        rot, root = np.empty((longest, J, 4), np.float32), np.empty((longest, 3))
        # See fk: from an origin up to LANES - 1 frames before the first posed.
        world = np.empty(((longest + 2 * LANES - 2) // LANES, 7 * J, LANES))
        feet, targets = np.empty((longest, 4, 3)), np.empty((longest, 4, 3))
        legs, no_recent = np.empty((longest, 4, LEG_WIDTH)), np.empty((PAD, 4, LEG_WIDTH))
        sink, eased = np.empty(longest), np.empty(longest)
        for c in range(c0 + worker, c1, workers):
            if not pose[c]:
                root_only(height, surge, rows[c, start:start + n], weights[c, start:start + n],
                          path[c, start:start + n], way[c, start:start + n], scales[c], out_root[c])
                kept[c] = contacts[c, start:start + n]
                if keep:
                    legs_at[c] = sent_at[c] = NOWHERE
                continue
            b, e = begin[c], end[c]
            k = e - b
            kn = min(max(known[c] - b, 0), k) if keep else 0  # frames with their feet known
            recent_known = keep and legs_at[c] == start and start - b >= PAD and kn >= start - b
            own_tilt = tilt[c] if heights.shape[0] > 0 else tilt[0]
            own_legs = known_legs[c] if keep else no_recent
            pinned[c] -= b  # in the context's frames
            sides[c, :, 3] *= sent_at[c] == start - 1  # (the frame before not sent: no side to keep)
            made = _character(poses, height, surge, paws, rows[c, b:e], weights[c, b:e], yaw[c, b:e],
                              lean[c, b:e], path[c, b:e], way[c, b:e], scales[c], contacts[c, b:e], parents,
                              offsets, fk_joints, rigs, bends, sink_limit, foot_lock, rot[:k], root[:k],
                              world, feet[:k], legs[:k], targets[:k], sink[:k], eased[:k], start - b,
                              start - b + n, known_feet[b:e, c], kn, own_legs, recent_known, own_tilt, b,
                              heights, ground_x0, ground_z0, spacing, plant_frames, pins[c], pinned[c], steps,
                              (sent[c], sent_at[c] - b), sides[c], kept[c])
            pinned[c] += b
            sent_at[c] = start + n - 1  # sent[c]: the targets of its last two frames (none kept: not read)
            out_rot[c] = rot[start - b:start - b + n]
            out_root[c] = root[start - b:start - b + n]
            if keep and foot_lock:
                legs_at[c] = start + n if made else NOWHERE
                # Frames [0, e) known now -- or, after a gap (the character not posed for a
                # while: at root_gait), [b, e), posed whole here: no later context begins before b.
                known[c] = max(known[c], e) if known[c] >= b else e


def lock_context(contacts: NDArray[np.bool_], start: int, stop: int, compiled: bool = True
                 ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Per character ``(begin, end)``: the frames the foot lock of ``[start, stop)`` reads -- from
    the start of the plant (or the plant before the swing) ``PAD`` frames before ``start`` to the
    end of the plant (or the plant after the swing) ``PAD`` frames after ``stop``. A scan from the
    window's ends over the runs each foot is in (every frame's run bounds cost a live session's
    every window 20 ms per 4,000 characters). ``compiled``: else the reference."""
    C = contacts.shape[0]
    begin, end = np.empty(C, np.int64), np.empty(C, np.int64)
    (COMPILED if compiled else REFERENCE).lock_contexts(contacts, start, stop, PAD, begin, end)
    return begin, end


def _terrain_arrays(ground: Grounding | None) -> tuple[Any, Any, float, float, float]:
    """tilt, heights, grid origin x and z, spacing; no terrain: empty arrays (one layout each,
    so the kernels are compiled once for both)."""
    if ground is None:
        return np.empty((1, 0, 4)), np.empty((0, 0)), 0.0, 0.0, 1.0
    f = ground.field
    return (np.ascontiguousarray(ground.tilt, np.float64), np.ascontiguousarray(f.heights, np.float64),
            f.origin[0], f.origin[1], f.spacing)


def _plan_arrays(plan: Plan) -> tuple[Any, ...]:
    """rows, weights, yaw, lean, path, way, scales, contacts: C-contiguous, whatever view it holds.

    One memory layout, so each kernel is compiled once: numba compiles a view ('A' layout) and a
    contiguous array ('C') separately, and fastmath code for the two may round differently --
    a window of a batch would then differ from the whole in the last bits."""
    c = np.ascontiguousarray
    return (c(plan.rows), c(plan.weights), c(plan.yaw), c(plan.lean, np.float64), c(plan.path),
            c(plan.way), c(plan.scales, np.float64), c(plan.contacts))


@functools.lru_cache(maxsize=8)
def _bank_tables(bank: Bank) -> tuple[tuple[Any, Any, Any, Any], tuple[Any, Any, Any, Any, Any, float]]:
    """The bank's arrays as the kernels take them (made once per bank: a small batch's call
    would otherwise spend a third of its time here): (pose table, heights, surges, each row's feet's
    standing heights: pose_kernels.clip_soles) and (parents,
    offsets, the joints above the feet (FK needs no others), the legs' rig table, bend axes and
    ranges (``(4, 6)``: the axis for limb_kernels.solve_legs, the furthest fold's cosine and the
    longest reach (ik.leg_ranges) for the sink and the IK's reach, the frames of a step replanting a
    foot the body carries out of reach: foot_kernels._replant), the sink limit)."""
    sk = bank.skeleton
    rigs = limb_rigs(sk)
    rig_table = np.array([[r.upper, r.hinge, r.ankle, r.effector] for r in rigs], np.int64)
    needed = np.zeros(sk.n_joints, bool)
    for r in rigs:
        j = r.effector
        while j >= 0:
            needed[j] = True
            j = int(sk.parents[j])
    poses, pos = np.ascontiguousarray(bank.poses.transpose(0, 2, 1)), table_positions(bank)  # (nlerp_into)
    return ((poses, bank.height.astype(np.float64), bank.surge.astype(np.float64),
             np.ascontiguousarray(standing_heights(bank, pos), np.float64)),
            (sk.parents.astype(np.int64), sk.offsets.astype(np.float64),
             np.flatnonzero(needed).astype(np.int64), rig_table,
             np.concatenate([bank.bends, leg_ranges(pos, rigs),
                             np.full((4, 1), max(round(STEP_S * bank.fps), 1))], axis=1),
             MAX_SINK * sk.leg_length()))


def _sink_limit(bank: Bank, ground: Grounding | None
                ) -> tuple[tuple[Any, Any, Any, Any], tuple[Any, Any, Any, Any, Any, float]]:
    """:func:`_bank_tables`, the sink limit that on a terrain (footlock.TERRAIN_MAX_SINK)."""
    table, skeleton = _bank_tables(bank)
    if ground is None:
        return table, skeleton
    return table, (*skeleton[:5], TERRAIN_MAX_SINK * bank.skeleton.leg_length())


# Parts of a shared window's characters (see render_window): enough that a thread done with its own
# work takes a part of another's and the two end near together, few enough that each call's
# overhead stays small.
SHARED_PARTS = 8


def _run_windows(kernels: RenderKernels, args: tuple[Any, ...], C: int,
                 share: Callable[[list[Callable[[], None]]], None] | None) -> None:
    """``kernels.render_windows`` of every character: at once, or in parts ``share`` runs."""
    if share is None:
        kernels.render_windows(*args, 0, C)
        return
    cuts = np.linspace(0, C, SHARED_PARTS + 1).round().astype(np.int64).tolist()
    share([functools.partial(kernels.render_windows, *args, a, b)
           for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a])


def _contacts_out(C: int, T: int, contacts: NDArray[np.bool_] | None) -> NDArray[np.bool_]:
    """Where a render writes the feet planted: ``contacts`` if given (checked), else new."""
    kept = np.empty((C, T, 4), np.bool_) if contacts is None else contacts
    assert kept.shape == (C, T, 4) and kept.dtype == np.bool_ and kept.flags.c_contiguous
    return kept


def render_window(bank: Bank, plan: Plan, start: int, stop: int, begin: NDArray[np.int64],
                  end: NDArray[np.int64], foot_lock: bool = True, known: Posed | None = None,
                  out: NDArray[np.float32] | None = None,
                  share: Callable[[list[Callable[[], None]]], None] | None = None,
                  ground: Grounding | None = None, pose: NDArray[np.bool_] | None = None,
                  compiled: bool = True, plant_frames: int | None = None, steps: bool = True,
                  contacts: NDArray[np.bool_] | None = None
                  ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Root ``(C, stop - start, 3)`` and rotations of frames ``[start, stop)`` only, each character rendered
    over its context ``[begin, end)`` of ``plan`` (from :func:`lock_context`): :func:`render`'s numbers (with
    ``known``: to rounding, tests/test_live.py, but an ankle bent against the last sent frame's: Posed.sides).

    ``known``: what earlier windows over the same plan posed (a live session's windows share
    most of their context). Frames whose feet are known are not posed again but where wanted;
    nor, after a window that ended at ``start``, the PAD frames before it (their sink read from
    ``known.legs``). What the frames posed give is written there, ``frames`` to ``sides`` moved on.
    ``out``: the rotations are written there (C-contiguous ``(C, stop - start, J, 4)`` float32).
    ``share``: SHARED_PARTS one-thread parts, which ``share`` runs (render_pool.shared: idle threads
    take some), so renders side by side finish together though one has more to pose. ``ground``:
    the plan stands on a terrain (:func:`synth_core.runtime.terrain.ground_plan`).

    ``pose (C,)``: the characters whose rotations are wanted (None: all); the others (far, at
    root_gait) get the plan's root alone (no foot lock, no sink), their rotations not written.
    ``plant_frames``: a plant's target averages its first so many frames only (None: all): what
    a live session sends of a plant before its end is planned then stays where it was sent (by
    ``known``'s pins, :class:`Posed`, once its first frames have left the context).

    ``steps``: a plant the body carries out of its leg's reach is stepped (``replant_kernels``),
    as :func:`render` does, where the contexts hold the plants whole (a batch's windows). False
    for a live session's: a plant runs on past what is planned and what was sent stays sent, so
    where it is split would be decided anew each window (each plant held whole, as sent).
    ``compiled``: else the reference (:data:`REFERENCE`, one thread). ``contacts (C, stop - start,
    4)``: the feet planted as posed are written there, as :func:`render`."""
    kernels = COMPILED if compiled else REFERENCE
    C = plan.yaw.shape[0]
    pose = np.ones(C, np.bool_) if pose is None else np.ascontiguousarray(pose, np.bool_)
    assert pose.shape == (C,)
    # Only the frames some context reads are made contiguous.
    cb, ce = int(np.min(begin)), int(np.max(end))
    posed = checked(known, plan)
    for frames in (posed.frames, posed.legs_at, posed.pinned, posed.sent_at):  # in the window's frames
        frames[...] -= cb
    out_root = np.empty((C, stop - start, 3), np.float64)
    out_rot = np.empty((C, stop - start, bank.skeleton.n_joints, 4), np.float32) if out is None else out
    assert out_rot.shape == (C, stop - start, bank.skeleton.n_joints, 4) and out_rot.dtype == np.float32
    assert out_rot.flags.c_contiguous
    kept = _contacts_out(C, stop - start, contacts)
    table, skeleton = _sink_limit(bank, ground)
    args = (*table, *_plan_arrays(plan.window(cb, ce)), *skeleton, foot_lock,
            1 if share or not compiled else threads(), np.asarray(begin, np.int64) - cb,
            np.asarray(end, np.int64) - cb, start - cb, out_rot, out_root,
            *_terrain_arrays(None if ground is None else ground.window(cb, ce)), pose,
            posed.feet[cb:ce] if known is not None else posed.feet, posed.frames, posed.legs, posed.legs_at,
            *posed[4:], WHOLE_PLANT if plant_frames is None else max(int(plant_frames), 1), steps, kept)
    try:
        _run_windows(kernels, args, C, share)
    finally:
        for frames in (posed.frames, posed.legs_at, posed.pinned, posed.sent_at):  # moved back
            frames[...] += cb
    return out_root.astype(np.float32), out_rot


def render(bank: Bank, plan: Plan, foot_lock: bool = True,
           out: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
           scratch: Scratch | None = None, ground: Grounding | None = None, compiled: bool = True,
           pose: NDArray[np.bool_] | None = None, contacts: NDArray[np.bool_] | None = None
           ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Root ``(C, T, 3)`` and local rotations ``(C, T, J, 4)`` of a plan (the four passes of the
    module doc); into ``out`` (root, rotations) if given.
    ``scratch``: where the workers' working sets are kept between calls (a small chunk's call
    would otherwise spend a fifth of its time faulting them in). ``ground``: the plan stands on
    a terrain (:func:`synth_core.runtime.terrain.ground_plan`). ``compiled``: else the reference
    (:data:`REFERENCE`, one thread). ``pose (C,)``: the characters whose rotations are wanted
    (None: all); the others (far characters, at root_gait) get the plan's root alone, as in
    :func:`render_window`, and their rows of the rotations are not written. ``contacts (C, T, 4)``:
    each frame a foot stands on its plant is set there (foot_kernels.held: the foot lock's steps
    off); far characters' (not posed) and, without the foot lock, everyone's are the plan's."""
    C, T = plan.yaw.shape
    pose = np.ones(C, np.bool_) if pose is None else np.ascontiguousarray(pose, np.bool_)
    assert pose.shape == (C,)
    J = bank.skeleton.n_joints
    W = min(C, threads() if compiled else 1)
    scratch = Scratch() if scratch is None else scratch
    work = [scratch.array(f"render.{name}", shape, np.float64)
            for name, shape in (("world", (W, -(-T // LANES), 7 * J, LANES)), ("feet", (W, T, 4, 3)),
                                ("legs", (W, T, 4, LEG_WIDTH)),
                                ("targets", (W, T, 4, 3)), ("sink", (W, T)), ("eased", (W, T)),
                                ("root", (C, T, 3)))]
    out_root = work.pop()
    out_rot = np.empty((C, T, J, 4), np.float32) if out is None else out[1]
    table, skeleton = _sink_limit(bank, ground)
    w_world, w_feet, w_legs, w_targets, w_sink, w_eased = work
    kept = _contacts_out(C, T, contacts)
    kernels = COMPILED if compiled else REFERENCE
    kernels.render_all(*table, *_plan_arrays(plan), *skeleton, foot_lock, out_rot, out_root, w_world, w_feet,
                       w_legs, w_targets, w_sink, w_eased, *_terrain_arrays(ground), pose, kept)
    assert UP_AXIS == 1  # the kernels index Y directly
    if out is None:
        return out_root.astype(np.float32), out_rot
    out[0][...] = out_root
    return out


class RenderKernels(NamedTuple):
    """The render's entry points; :data:`COMPILED` and :data:`REFERENCE` have the same signatures."""

    name: str
    render_all: Callable[..., None]
    render_windows: Callable[..., None]
    lock_contexts: Callable[..., None]


# The reference: this source (and its helpers' in the other kernel modules) run by the
# interpreter, as the planner's (synth_core.compiled.plan_kernels.REFERENCE). Here at the end, so
# every kernel of the module is in the scope it runs in.
_HELPERS = (vars(foot_kernels), vars(pose_kernels), vars(limb_kernels), vars(vec_kernels),
            vars(ground_kernels), vars(replant_kernels), vars(jump_kernels), vars(swing_kernels))
_PLAIN = {**interpreted(vars(foot_kernels), *_HELPERS[1:]), **interpreted(globals(), *_HELPERS)}
REFERENCE = RenderKernels("numpy", *(_PLAIN.get(name, globals()[name])
                                     for name in ("_render_all", "_render_windows", "lock_contexts")))
COMPILED = RenderKernels("numba", _render_all, _render_windows, lock_contexts) if AVAILABLE else REFERENCE
