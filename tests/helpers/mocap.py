"""The real dog mocap in ../shared (tests skip with a reason when it is absent)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from synth_core.motion import bvh
from synth_core.motion.skeleton import Skeleton
from tests.helpers import REPO

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


MANN_FEET = {"LF": "LeftHand_end", "RF": "RightHand_end", "LH": "LeftFoot_end", "RH": "RightFoot_end"}


def mann_standing() -> tuple[Skeleton, np.ndarray]:
    """The real dog's skeleton read from BVH (its zero pose lies along +X) and a standing frame."""
    motion = bvh.read(mann_path("D1_ex01_KAN01_001"), unit="cm")
    return motion.skeleton.with_feet(MANN_FEET), motion.rotations[20]
