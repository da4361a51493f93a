"""The paper's baseline: the same synthesis without prebuilt speed maps.

Everything is as in :func:`synth_core.runtime.synthesis.synthesize` -- the same schedule, stitches, warp
and foot lock -- except where a gait plays: instead of blending the two prebuilt clips around
the speed, each segment's clip is made at run time for its exact speed, by the speed map's own
root relocation and IK (:func:`synth_core.build.speed_map.build_speed_map`) from the gait's source
cycle. All the clips a batch needs are made in one vectorized call per gait, so the comparison
measures the run-time IK, not Python overhead.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from synth_core.build.artifact import Library
from synth_core.build.motion_graph import HUBS
from synth_core.build.speed_map import build_speed_map
from synth_core.compiled import kernels
from synth_core.motion import quat
from synth_core.runtime.bank import Bank, Table, canonical_cycle, mirrored
from synth_core.runtime.plan import character_leads
from synth_core.runtime.synthesis import Options, Plan, Result, compiled_backend, plan, prepare_batch

DEFAULT_OPTIONS = Options()
CHUNK = 512  # clips made per IK call (bounds memory)


def _remap(bank: Bank, p: Plan, segment: NDArray[np.int64], speeds: NDArray[np.float64],
           library: Library) -> tuple[Bank, Plan]:
    """A bank extended with the clips made for each (gait, character, segment), and the plan's
    gait rows pointed at them."""
    rows = p.rows.copy()
    weights = p.weights.copy()
    poses, height, surge, contacts = [bank.poses], [bank.height], [bank.surge], [bank.contacts]
    offset = len(bank.poses)
    C = rows.shape[0]
    character = np.broadcast_to(np.arange(C)[:, None], segment.shape)
    lead = (rows >= bank.own) * bank.mirror  # a character on the other lead: the mirror rows
    for hub, piece in bank.gaits.items():
        gait_rows = (rows - lead >= piece.offset) & (rows - lead < piece.offset + piece.clips * piece.frames)
        if not gait_rows.any():
            continue
        # Every (character, segment) showing this gait gets one clip at its segment's speed.
        pair = np.broadcast_to((character * speeds.shape[1] + segment)[..., None], rows.shape)
        needed, slot = np.unique(pair[gait_rows], return_inverse=True)
        lo, hi = bank.speeds[hub][0], bank.speeds[hub][-1]
        want = np.clip(speeds.ravel()[needed], lo, hi)
        source_map = library.maps[HUBS[hub]]
        source = source_map.clip(int(np.abs(source_map.speeds - source_map.source_speed).argmin()))
        order = np.argsort(want, kind="stable")
        made_rot, made_height, made_surge = [], [], []
        for a in range(0, len(order), CHUNK):
            m = build_speed_map(source, want[order[a:a + CHUNK]])
            for i in range(m.n_clips):
                rot, ht, sg = canonical_cycle(m.root_pos[i], m.rotations[i])
                made_rot.append(rot)
                made_height.append(ht - bank.ground)
                made_surge.append(sg)
        rank = np.empty(len(order), np.int64)
        rank[order] = np.arange(len(order))
        frame = (rows[gait_rows] - lead[gait_rows] - piece.offset) % piece.frames
        # The clips made, then their mirror images (bank.mirror) for the characters on the other lead.
        block = len(order) * piece.frames
        rows[gait_rows] = offset + (lead[gait_rows] > 0) * block + rank[slot] * piece.frames + frame
        table: Table = (quat.normalize(np.concatenate(made_rot)).astype(np.float32),
                        np.concatenate(made_height), np.concatenate(made_surge),
                        np.tile(source.contacts, (len(order), 1)))
        made = mirrored(bank.skeleton, *table) if bank.mirror else (*table, 0)
        poses.append(made[0])
        height.append(made[1].astype(np.float32))
        surge.append(made[2].astype(np.float32))
        contacts.append(made[3])
        offset += len(made[0])
    # Exact speed: the pair blended is one clip (both rows the same, weight 0).
    exact = rows[..., 0] >= len(bank.poses)
    rows[..., 1] = np.where(exact, rows[..., 0], rows[..., 1])
    weights[..., 0] = np.where(exact, 0.0, weights[..., 0])
    fading = rows[..., 2] >= len(bank.poses)
    rows[..., 3] = np.where(fading, rows[..., 2], rows[..., 3])
    weights[..., 1] = np.where(fading, 0.0, weights[..., 1])
    extended = replace(bank, poses=np.concatenate(poses), height=np.concatenate(height),
                       surge=np.concatenate(surge), contacts=np.concatenate(contacts))
    return extended, replace(p, rows=rows, weights=weights)


def synthesize_onthefly(bank: Bank, library: Library, positions: ArrayLike, fps: float | None = None,
                        scales: ArrayLike | None = None, options: Options = DEFAULT_OPTIONS,
                        ids: list[str] | None = None) -> Result:
    """:func:`synth_core.runtime.synthesis.synthesize`, each gait segment's clip made at run time."""
    prep, h, keys = prepare_batch(bank, positions, fps, scales, options, ids)
    p = plan(bank, prep, h, keys, options.margin, compiled=compiled_backend(options))
    T = p.rows.shape[1]
    segment = np.minimum(np.arange(T) // prep.segment, prep.segment_speeds.shape[1] - 1)
    segment = np.broadcast_to(segment[None, :], p.rows.shape[:2])
    extended, p = _remap(bank, p, segment, prep.segment_speeds / h[:, None], library)
    contacts = np.empty(p.contacts.shape, np.bool_)
    root, rotations = kernels.render(extended, p, options.foot_lock, compiled=compiled_backend(options),
                                     contacts=contacts)
    return Result(root, rotations, p.gait, contacts, p.stitches, h, p.path,
                  prep.resample_rate, prep.kept, prep.rejected, prep.warnings,
                  character_leads(bank, keys) > 0)
