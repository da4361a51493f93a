"""Shared fixtures: the real dog mocap (skipped when ../shared is absent), a toy quadruped and the
built-in horse's synthesis tables."""

from __future__ import annotations

import os

import numpy as np
import pytest

from synth_core.build.animals import build_builtin
from synth_core.motion.skeleton import Skeleton
from synth_core.runtime.bank import Bank, build_bank
from tests.helpers import REPO
from tests.helpers.motion import toy_skeleton

# Library files built by this checkout's code, as ./scripts/serve and ./scripts/test use (the
# installed default is a per-user directory, which another checkout's code may have filled).
os.environ.setdefault("QUADSYNTH_LIBRARY_DIR", str(REPO / "library"))


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
