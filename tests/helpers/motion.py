"""Test motion: a toy quadruped, random motion on it, synthetic footfall patterns, joint speed limits."""

from __future__ import annotations

import numpy as np

from synth_core import FOOT_NAMES
from synth_core.build.animals import map_positions
from synth_core.build.artifact import Library
from synth_core.build.speed_map import cycle_displacement
from synth_core.builtin.clips import GAITS
from synth_core.builtin.gaits import GAIT_SPECS
from synth_core.motion import quat
from synth_core.motion.clip import Motion
from synth_core.motion.skeleton import Skeleton
from synth_core.quality import metrics as M
from synth_core.runtime.bank import Bank
from synth_core.runtime.footlock import LIFTED_PLANT, MAX_SINK
from synth_core.runtime.terrain import HeightField


def toy_skeleton() -> Skeleton:
    """A small quadruped: hips, spine, head, and four 3-bone legs ending in end sites (metres)."""
    names, parents, offsets, ends = [], [], [], []

    def add(name: str, parent: int, offset: tuple[float, float, float], end: bool = False) -> int:
        names.append(name)
        parents.append(parent)
        offsets.append(offset)
        ends.append(end)
        return len(names) - 1

    hips = add("Hips", -1, (0, 0, 0))
    chest = add("Chest", hips, (0.5, 0.0, 0.0))
    head = add("Head", chest, (0.2, 0.2, 0.0))
    add("Head_end", head, (0.15, 0.0, 0.0), end=True)
    for side, z in (("Left", 0.1), ("Right", -0.1)):
        for limb, root, kind in (("Arm", chest, "Hand"), ("UpLeg", hips, "Foot")):
            upper = add(f"{side}{limb}", root, (0.0, -0.05, z))
            lower = add(f"{side}{limb}Lower", upper, (0.0, -0.2, 0.0))
            foot = add(f"{side}{kind}", lower, (0.0, -0.2, 0.0))
            add(f"{side}{kind}_end", foot, (0.03, -0.05, 0.0), end=True)
    skel = Skeleton(tuple(names), np.array(parents), np.array(offsets, np.float32),
                    np.array(ends), name="toy")
    return skel.with_feet({"LF": "LeftHand_end", "RF": "RightHand_end",
                           "LH": "LeftFoot_end", "RH": "RightFoot_end"})


def random_motion(rng: np.random.Generator, frames: int = 40, skeleton: Skeleton | None = None,
                  spread: float = 0.6) -> Motion:
    skeleton = skeleton or toy_skeleton()
    J = skeleton.n_joints
    rot = quat.from_rotvec(rng.normal(scale=spread, size=(frames, J, 3)))
    rot[:, skeleton.end_site] = quat.identity()
    root = np.cumsum(rng.normal(scale=0.02, size=(frames, 3)), axis=0) + [0, 0.5, 0]
    return Motion(skeleton, root, rot, fps=60.0, name="random")


def synthetic_gait(phases: dict[str, float], duty: float, stride: int = 40, strides: int = 4) -> np.ndarray:
    # Start half a stride in, so LH's first touchdown falls inside the clip.
    frames = np.arange(stride * strides) + stride // 2
    out = np.zeros((len(frames), 4), bool)
    for k, foot in enumerate(FOOT_NAMES):
        out[:, k] = ((frames / stride - phases[foot]) % 1.0) < duty
    return out


TEMPLATES = {
    "walk": ({"LH": 0.0, "LF": 0.25, "RH": 0.5, "RF": 0.75}, 0.65),
    "trot": ({"LH": 0.0, "RF": 0.0, "RH": 0.5, "LF": 0.5}, 0.4),
    "pace": ({"LH": 0.0, "LF": 0.0, "RH": 0.5, "RF": 0.5}, 0.55),
    "canter-transverse": ({"RH": 0.9, "LH": 0.0, "RF": 0.0, "LF": 0.15}, 0.35),
    "gallop-transverse": ({"RH": 0.9, "LH": 0.0, "RF": 0.1, "LF": 0.25}, 0.25),
    "gallop-rotary": ({"RH": 0.85, "LH": 0.0, "LF": 0.15, "RF": 0.3}, 0.25),
}


# Fastest any joint may turn (deg/s). The real dog (../shared/mocap, its SOURCE.md cycles) peaks
# at 1250 walking, 1560-2210 trotting and 1810-2030 in its 3.7-4.2 m/s gallop; our dog gallops
# faster (4.6 m/s), hence 2500. Joint angular speeds scale with stride frequency: the horse's
# limit is the dog's times the largest horse-to-dog stride frequency ratio of any gait.
_FREQUENCY_RATIO = max(GAIT_SPECS["dog"][g].frames / GAIT_SPECS["horse"][g].frames for g in GAITS)


PEAK_JOINT_SPEED = {"dog": 2500.0, "horse": 2500.0 * _FREQUENCY_RATIO}


def _hills(x: np.ndarray, z: np.ndarray) -> np.ndarray:
    return np.asarray(0.5 * np.sin(x / 3.0) * np.cos(z / 4.0) + 0.1 * z)


def herd_on_hills() -> tuple[np.ndarray, HeightField]:
    """Three characters (1.5, 3 and 5 m/s, bending) over rolling hills, and the hills."""
    xs = np.arange(-15.0, 40.0, 0.1)
    x, z = np.meshgrid(xs, xs)
    field = HeightField.make(_hills(x, z), origin=(-15.0, -15.0), spacing=0.1)
    T = 360
    s = np.linspace(0.0, 1.0, T)
    paths = np.zeros((3, T, 3))
    for c, (speed, bend) in enumerate(((1.5, 0.3), (3.0, -0.4), (5.0, 0.2))):
        yaw = 0.5 + bend * s
        step = np.stack([np.sin(yaw), np.zeros(T), np.cos(yaw)], -1) * speed / 60.0
        paths[c] = np.cumsum(step, axis=0) + [c * 3.0, 0.0, 0.0]
    return paths, field


def assert_far_root(bank: Bank, far: np.ndarray, full: np.ndarray, scales: np.ndarray) -> None:
    """A far character's root (root_gait: not posed, so no foot lock) against the same
    character posed: across the ground exactly the posed root (to float32); in height the plan's,
    which the posed character's foot lock lowers where a leg cannot reach its plant (its sink) or
    raises where a leg would fold further than the animal's poses (foot_kernels.fold_room), by at
    most its bound either way."""
    np.testing.assert_allclose(far[..., [0, 2]], full[..., [0, 2]], rtol=0, atol=1e-5)
    sink = far[..., 1] - full[..., 1]
    bound = MAX_SINK * bank.skeleton.leg_length() * np.asarray(scales, np.float64).reshape(-1, 1)
    assert (np.abs(sink) <= bound + 1e-5).all()


def plant_stands(frames: np.ndarray, h: float = 1.0, whole: bool = True) -> np.ndarray:
    """Where foot_kernels._plants stands a plant of these frames of its foot ``(n, 3)`` (the
    library's unit; ``h`` the scale): their average place, at their average height unless that is
    more than footlock.LIFTED_PLANT (world) over their heights' lower quartile, then at that --
    where every frame is free (``whole``: a batch or the exact live mode; not the low-latency one)."""
    place = frames.mean(axis=0)
    low = np.sort(frames[:, 1])[len(frames) // 4]
    if whole and place[1] - low > LIFTED_PLANT / h:
        place[1] = low
    return place


def looped(positions: np.ndarray, root: np.ndarray) -> np.ndarray:
    """A speed map's clips ``(N, F, J, 3)`` with their first two frames again, a loop on."""
    advance = np.stack([cycle_displacement(r) for r in root])[:, None, None]
    return np.concatenate([positions, positions[:, :2] + advance], axis=1)


def clip_flips(library: Library, skip: int) -> dict[str, int]:
    """Limb flips (the edge figure: every joint along each leg, the wrist too) of every speed-map
    clip (looped) and transition, showing every ``skip``-th clip frame from each start (a
    character playing it ``skip`` times as fast)."""
    flips = {}
    clips = {g: looped(map_positions(m), m.root_pos) for g, m in library.maps.items()}
    clips |= {n: np.asarray(c.positions(), np.float64)[None] for n, c in library.transitions.items()}
    for name, positions in clips.items():
        shown = (positions[:, k::skip] for k in range(skip))
        flips[name] = sum(int(M.limb_flips(p, library.skeleton).sum()) for p in shown)
    return flips


def stops(positions: np.ndarray) -> list[tuple[int, int, int]]:
    """Per character of the input, each stop: (the first frame the path stands still, the frame
    it moves again or its end)."""
    step = np.linalg.norm(np.diff(positions[..., [0, 2]], axis=1), axis=-1) > 1e-6
    out: list[tuple[int, int, int]] = []
    for c in range(len(step)):
        moving = np.flatnonzero(step[c])
        for s in moving[np.diff(np.append(moving, step.shape[1])) > 1] + 1:
            again = moving[moving >= s]
            out.append((c, int(s), int(again[0]) if len(again) else positions.shape[1]))
    return out
