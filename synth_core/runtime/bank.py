"""A library laid out for run-time gathering: every clip frame in one pose table.

Synthesis picks, for every character and frame, a few rows of this table and blends them; so
every clip is put into one canonical frame first -- facing and travelling along +Z, its own
mean heading removed, the sideways sway dropped -- and its root split into what the warp needs:
height, and the forward *surge* (the root's lead or lag on steady progress within a stride).

Rows: the gait maps (clip by clip, frame by frame), then the idle, then each transition -- and
then all of them again, mirrored left for right (:mod:`synth_core.motion.mirror`: a character on
the other lead, issue 28), where the skeleton's sides pair up. For
every transition we also find where it joins its gaits: ``entry`` (the source gait's frame its
first pose matches) and ``exit`` (the target gait's frame its last pose matches), so a character
enters it at that phase of its stride and leaves it without a step doubled or skipped.

Transitions play by distance, not by time: a transition's speed ramps on its own schedule, the
caller's trajectory on another, so the clip frame shown is the one whose forward progress matches
the distance the character has covered since it began (both plus a small ``creep`` per frame,
so a clip's standing frames still play while the character stands). Its feet then keep pace
with its root, and the transition ends when the character has covered the clip's distance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from synth_core import UP_AXIS
from synth_core.build import ik
from synth_core.build.artifact import Library
from synth_core.build.motion_graph import HUBS
from synth_core.build.speed_map import cycle_displacement
from synth_core.motion import quat
from synth_core.motion.clip import Motion
from synth_core.motion.mirror import FOOT_SWAP, mirror_poses, skeleton_mirror
from synth_core.motion.skeleton import Skeleton, forward_kinematics

Floats = NDArray[np.float64]
STATIC = 0  # hub index of standing
CREEP = 0.25  # of the slowest clip's speed: the creep added to distances (see Bank.creep)


@dataclass(frozen=True)
class Piece:
    """Where one clip (a gait's map, the idle, a transition) sits in the table."""

    offset: int  # first row
    frames: int  # frames per clip
    clips: int = 1  # speed-map clips (gaits), else 1
    entry: int = 0  # transitions: source-gait frame they start from
    exit: int = 0  # transitions: target-gait frame their last frame matches


@dataclass(frozen=True, eq=False)
class Bank:
    skeleton: Skeleton
    fps: float
    poses: NDArray[np.float32]  # (K, J, 4) local rotations, root yaw canonical
    height: NDArray[np.float32]  # (K,) root height above the ground the feet plant on
    surge: NDArray[np.float32]  # (K,) forward lead of the root on steady progress, m
    contacts: NDArray[np.bool_]  # (K, 4)
    hubs: tuple[str, ...]  # HUBS present: "static" first
    gaits: dict[int, Piece]  # hub index -> its speed map
    speeds: dict[int, Floats]  # hub index -> clip speeds, m/s
    idle: Piece
    transitions: dict[tuple[int, int], Piece]  # (from hub, to hub) -> clip
    progress: dict[tuple[int, int], Floats]  # transition -> its frames' "distance" (see creep)
    creep: float  # m/frame added to distance on both sides so standing clip frames still play
    bends: Floats  # (4, 3) each leg's dominant bend axis in the root's frame (foot lock's IK)
    ground: float = 0.0  # the library clips' ground height (heights above are ``height``)
    # Row r + mirror is row r's mirror image (left and right swapped: the other lead), for
    # r < mirror; 0: no mirror rows (a skeleton without a sound left/right pairing). The pieces'
    # offsets are the first half's; a character on the other lead plays its rows + mirror.
    mirror: int = 0

    @property
    def top_speed(self) -> float:
        return float(max(s[-1] for s in self.speeds.values()))

    @property
    def own(self) -> int:
        """Rows of the library's own clips (their mirror images follow, if any)."""
        return self.mirror or len(self.poses)

    @property
    def mean_cycle(self) -> int:
        """m, the paper's segment length: the gaits' mean cycle in frames."""
        return int(round(np.mean([p.frames for p in self.gaits.values()])))


def _yaw(angle: Floats) -> NDArray[np.float64]:
    return np.asarray(quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), np.asarray(angle, np.float64)))


def _forward_local(library: Library) -> Floats:
    """The root joint's own axis that points where the animal travels (from the walk)."""
    walk = next(iter(library.maps.values()))
    travel = cycle_displacement(walk.root_pos).mean(axis=0)
    travel = travel / max(np.linalg.norm(travel), 1e-9)
    local = quat.rotate(quat.inv(walk.rotations[:, :, 0].astype(np.float64)), travel)
    mean = local.reshape(-1, 3).mean(axis=0)
    return np.asarray(mean / np.linalg.norm(mean))


def _heading(root_rot: NDArray[np.floating], forward: Floats) -> float:
    """Mean yaw (about +Y, 0 = +Z) a clip faces."""
    f = quat.rotate(np.asarray(root_rot, np.float64), forward)
    return float(np.arctan2(f[:, 0].mean(), f[:, 2].mean()))


def _canonical(root_pos: NDArray[np.floating], rotations: NDArray[np.floating], yaw: float,
               cyclic: bool) -> tuple[Floats, Floats, Floats]:
    """Rotations with the clip's yaw removed; root height; root surge on steady progress (a
    cyclic clip) or, for a one-off clip, its forward progress."""
    turn = _yaw(np.array(-yaw))
    rot = np.array(rotations, dtype=np.float64)
    rot[:, 0] = quat.mul(turn, rot[:, 0])
    pos = quat.rotate(turn, np.asarray(root_pos, np.float64) - root_pos[0])
    F = len(pos)
    if cyclic:  # steady progress: the loop's advance spread evenly over its frames
        steady = np.arange(F) * (cycle_displacement(pos)[2] / F)
        surge = pos[:, 2] - steady
        surge -= surge.mean()
    else:
        surge = pos[:, 2]
    return rot, np.asarray(root_pos, np.float64)[:, UP_AXIS], surge


def canonical_cycle(root_pos: NDArray[np.floating],
                    rotations: NDArray[np.floating]) -> tuple[Floats, Floats, Floats]:
    """A cyclic clip's table rows: rotations facing +Z, root height, surge (see :func:`_canonical`)."""
    yaw = float(np.arctan2(*cycle_displacement(root_pos)[[0, 2]]))
    return _canonical(root_pos, rotations, yaw, cyclic=True)


def library_ground(library: Library) -> float:
    """The height the library's gait clips plant their feet at."""
    return min(float(m.clip(0).foot_positions()[..., UP_AXIS].min()) for m in library.maps.values())


def nearest_poses(poses: NDArray[np.floating], contacts: NDArray[np.bool_], queries: NDArray[np.floating],
                  query_contacts: NDArray[np.bool_]) -> NDArray[np.int64]:
    """``(Q,)``: for each of ``queries (Q, J, 4)`` (feet down ``query_contacts (Q, 4)``) the row of
    ``poses (F, J, 4)`` nearest it, feet agreeing first, then the joints below the root (each
    ``1 - |q . p|``): ties the first."""
    dots = np.einsum("qjc,fjc->qfj", queries[:, 1:], poses[:, 1:])
    distance = (1.0 - np.abs(dots)).sum(axis=-1)  # (Q, F), >= 0
    disagree = (query_contacts[:, None] != contacts[None]).sum(axis=-1)
    return np.asarray(np.argmin(disagree * (distance.max(initial=0.0) + 1.0) + distance, axis=1), np.int64)


def nearest_pose(poses: NDArray[np.floating], contacts: NDArray[np.bool_], pose: NDArray[np.floating],
                 contact: NDArray[np.bool_]) -> int:
    """The row of ``poses (F, J, 4)`` nearest ``pose (J, 4)``, feet agreeing first (:func:`nearest_poses`)."""
    return int(nearest_poses(poses, contacts, pose[None], contact[None])[0])


Table = tuple[NDArray[np.float32], Floats, Floats, NDArray[np.bool_]]  # poses, height, surge, contacts


def mirrored(skeleton: Skeleton, poses: NDArray[np.float32], height: Floats, surge: Floats,
              contacts: NDArray[np.bool_]) -> tuple[*Table, int]:
    """The table's rows followed by their mirror images (root height and surge are the same,
    each foot's contact is its partner's), and where the mirror rows start (0: none, the rows
    as they were: no left/right pairing)."""
    mirror = skeleton_mirror(skeleton)
    if mirror is None:
        return poses, height, surge, contacts, 0
    flipped = quat.normalize(mirror_poses(mirror, poses)).astype(np.float32)
    return (np.concatenate([poses, flipped]), np.concatenate([height, height]),
            np.concatenate([surge, surge]), np.concatenate([contacts, contacts[:, FOOT_SWAP]]), len(poses))


def build_bank(library: Library, mirror: bool = True) -> Bank:
    """The library's table; ``mirror``: with the mirror rows (where the skeleton pairs up)."""
    forward = _forward_local(library)
    rows: list[tuple[Floats, Floats, Floats, NDArray[np.bool_]]] = []
    offset = 0
    gaits: dict[int, Piece] = {}
    speeds: dict[int, Floats] = {}
    middle: dict[int, int] = {}  # hub -> rows index of its middle clip (transitions join there)
    for gait, m in library.maps.items():
        hub = HUBS.index(gait)
        middle[hub] = len(rows) + m.n_clips // 2
        for i in range(m.n_clips):
            rows.append((*canonical_cycle(m.root_pos[i], m.rotations[i]), m.contacts))
        gaits[hub] = Piece(offset, m.n_frames, m.n_clips)
        speeds[hub] = np.asarray(m.speeds, np.float64)
        offset += m.n_clips * m.n_frames

    def add(clip: Motion) -> Piece:
        nonlocal offset
        travel = clip.root_pos[-1] - clip.root_pos[0]
        moving = np.hypot(travel[0], travel[2]) > 0.1 * library.skeleton.leg_length()
        yaw = float(np.arctan2(travel[0], travel[2])) if moving else _heading(clip.rotations[:, 0], forward)
        rot, height, forward_progress = _canonical(clip.root_pos, clip.rotations, yaw, cyclic=False)
        # A one-off clip plays by distance, not time: the root stays on the path, no surge.
        rows.append((rot, height, np.zeros(clip.n_frames), clip.contacts))
        progress.append(np.maximum.accumulate(forward_progress))
        piece = Piece(offset, clip.n_frames)
        offset += clip.n_frames
        return piece

    progress: list[Floats] = []
    idle = add(library.idle)
    poses = np.concatenate([r[0] for r in rows])
    transitions: dict[tuple[int, int], Piece] = {}
    distance: dict[tuple[int, int], Floats] = {}
    creep = CREEP * min(float(s[0]) for s in speeds.values()) / library.fps
    for name, clip in library.transitions.items():
        source, target = (HUBS.index(h) for h in name.split("2"))
        piece = add(clip)
        rot, contacts = rows[-1][0], rows[-1][3]
        entry = exit_ = 0
        if source in middle:
            gait_rot, gait_contacts = rows[middle[source]][0], rows[middle[source]][3]
            entry = nearest_pose(gait_rot, gait_contacts, rot[0], contacts[0])
        if target in middle:
            gait_rot, gait_contacts = rows[middle[target]][0], rows[middle[target]][3]
            exit_ = nearest_pose(gait_rot, gait_contacts, rot[-1], contacts[-1])
        transitions[(source, target)] = Piece(piece.offset, piece.frames, 1, entry, exit_)
        distance[(source, target)] = progress[-1] + creep * np.arange(clip.n_frames)
    poses = quat.normalize(np.concatenate([r[0] for r in rows])).astype(np.float32)
    gait_rows = sum(p.clips * p.frames for p in gaits.values())
    ground = library_ground(library)
    bends = np.asarray(ik.bend_axes(library.skeleton, poses[:gait_rows]), np.float64)
    table = (poses, np.concatenate([r[1] for r in rows]) - ground, np.concatenate([r[2] for r in rows]),
             np.concatenate([r[3] for r in rows]).astype(bool))
    poses, height, surge, contacts, half = mirrored(library.skeleton, *table) if mirror else (*table, 0)
    return Bank(library.skeleton, library.fps, poses, height.astype(np.float32), surge.astype(np.float32),
                contacts, tuple(h for h in HUBS if h == "static" or h in library.maps),
                gaits, speeds, idle, transitions, distance, creep, bends, ground, half)


def table_positions(bank: Bank, rows: slice = slice(None)) -> Floats:
    """``(K, J, 3)`` the joints of the table's ``rows`` (float64), each root at ``height`` over its
    feet's ground."""
    height = bank.height[rows]
    root = np.zeros((len(height), 3))
    root[:, UP_AXIS] = height
    return np.asarray(forward_kinematics(bank.skeleton, root, bank.poses[rows].astype(np.float64))[0])


def turn_lever(bank: Bank) -> float:
    """How far the body's turn sweeps the feet: the farthest foot from the root over the ground in
    the idle's first pose (library metres). The root is at the hips, so it is the forehand's (the
    horse's forefeet 1.2 m ahead of it, its hind feet 0.2 m behind)."""
    rows = slice(bank.idle.offset, bank.idle.offset + 1)
    feet = table_positions(bank, rows)[0, bank.skeleton.foot_joints]
    return float(np.hypot(feet[:, 0], feet[:, 2]).max())


def standing_heights(bank: Bank, positions: Floats) -> Floats:
    """``(K, 4)`` each row's feet's standing heights over the ground they plant on: per plant of
    each clip (a speed map's, the idle, a transition; their mirror images apart), the foot's low
    tenth of its heights over the plant (``positions``: :func:`table_positions`; a paw rolling on
    its pad, its toe's end site rises); a row between plants, its clip's nearest plant's. A mocap
    paw stands higher in one take than in another (the real dog's right hind: 0.9 cm over its
    clips, 2 cm in its walk), and a transition goes from one take's to the other's. Rows past the
    pieces (the on-the-fly baseline's clips made at run time) are read as one clip."""
    raw = np.asarray(positions[:, bank.skeleton.foot_joints, UP_AXIS], np.float64)
    starts = np.zeros(len(raw), bool)  # each clip's first row
    starts[0] = True
    for piece in [bank.idle, *bank.gaits.values(), *bank.transitions.values()]:
        for half in ({0, bank.mirror} if bank.mirror else {0}):
            starts[half + piece.offset + piece.frames * np.arange(piece.clips)] = True
    return np.stack([_stand(raw[:, f], bank.contacts[:, f], starts) for f in range(4)], axis=1)


def _stand(heights: Floats, down: NDArray[np.bool_], starts: NDArray[np.bool_]) -> Floats:
    """One foot over the table: each plant (a run of ``down`` within a clip) at the low tenth of
    its ``heights`` (as np.percentile), a row between plants at its clip's nearest plant's (the
    earlier on a tie), a clip where the foot is never down at its own heights."""
    if not down.any():
        return heights.copy()
    rows = np.arange(len(heights))
    begins = down & (starts | ~np.concatenate([[False], down[:-1]]))
    run = np.cumsum(begins) - 1
    ids, values = run[down], heights[down]
    ordered = values[np.lexsort((values, ids))]
    counts = np.bincount(ids)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    at = 0.1 * (counts - 1)
    low = np.floor(at).astype(np.int64)
    high = np.minimum(low + 1, counts - 1)
    level = ordered[first + low] + (at - low) * (ordered[first + high] - ordered[first + low])
    clip = np.cumsum(starts) - 1
    before = np.maximum.accumulate(np.where(down, rows, -1))
    after = np.minimum.accumulate(np.where(down, rows, len(rows))[::-1])[::-1]
    has_before = (before >= 0) & (clip[np.maximum(before, 0)] == clip)
    has_after = (after < len(rows)) & (clip[np.minimum(after, len(rows) - 1)] == clip)
    use_before = has_before & (~has_after | (rows - before <= after - rows))
    out = heights.copy()
    out[use_before] = level[run[before[use_before]]]
    use_after = has_after & ~use_before
    out[use_after] = level[run[after[use_after]]]
    return out
