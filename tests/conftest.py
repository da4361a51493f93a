"""Shared fixtures: the real dog mocap (skipped when ../shared is absent), a toy quadruped and the
built-in horse's synthesis tables."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from synth_core.build.animals import build_builtin
from synth_core.motion import quat
from synth_core.motion.clip import Motion
from synth_core.motion.skeleton import Skeleton
from synth_core.runtime.bank import Bank, build_bank

REPO = Path(__file__).resolve().parents[1]
# Library files built by this checkout's code, as ./scripts/serve and ./scripts/test use (the
# installed default is a per-user directory, which another checkout's code may have filled).
os.environ.setdefault("QUADSYNTH_LIBRARY_DIR", str(REPO / "library"))
MANN_DIR = REPO.parent / "shared" / "mocap" / "mann_dog"
MANN_FILES = sorted(MANN_DIR.glob("*.bvh")) if MANN_DIR.is_dir() else []

# Clean cycles from ../shared/mocap/mann_dog/SOURCE.md: file -> (start, stop, SOURCE gait, duty).
MANN_CYCLES = {
    "D1_007_KAN01_001": (208, 245, "pace", 0.57),
    "D1_ex01_KAN01_001": (252, 292, "pace", 0.57),
    "D1_025_KAN01_001": (460, 501, "pace", 0.57),
    "D1_053_KAN01_002": (793, 824, "pace", 0.57),
    "D1_009_KAN01_002": (296, 326, "trot", 0.42),
    "D1_031_KAN01_001": (596, 624, "trot", 0.42),
    "D1_045_KAN01_001": (252, 281, "trot", 0.42),
    "D1_010_KAN01_001": (487, 515, "canter", 0.30),
    "D1_010_KAN01_003": (141, 167, "canter", 0.30),
    "D1_010_KAN01_002": (67, 92, "canter", 0.27),  # 4.2 m/s: between SOURCE's 0.30 and 0.24
    "D1_053_KAN01_001": (805, 853, "walk", 0.62),
}


def mann_path(name: str) -> Path:
    path = MANN_DIR / f"{name}.bvh"
    if not path.exists():
        pytest.skip(f"real dog mocap not found at {MANN_DIR} (tests need ../shared beside the repo)")
    return path


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


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


@pytest.fixture
def toy() -> Skeleton:
    return toy_skeleton()


@pytest.fixture(scope="session")
def bank() -> Bank:
    """The built-in horse's synthesis tables (built once for the whole run)."""
    return build_bank(build_builtin("horse"))
