"""Motion: a clip as arrays (root positions, local rotations, contacts) over one skeleton.

Shapes follow the glossary in :mod:`synth_core`. A Motion is immutable; edits make new ones.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from synth_core import FOOT_NAMES
from synth_core.motion import quat
from synth_core.motion.skeleton import Skeleton, forward_kinematics

GAITS = ("static", "walk", "trot", "canter", "gallop")


@dataclass(frozen=True, eq=False)
class Motion:
    skeleton: Skeleton
    root_pos: NDArray[np.float32]  # (F, 3) metres
    rotations: NDArray[np.float32]  # (F, J, 4) xyzw, local
    fps: float
    contacts: NDArray[np.bool_] = field(default=None)  # type: ignore[arg-type]  # (F, 4); None: none planted
    name: str = ""
    gait: str | None = None

    def __post_init__(self) -> None:
        root_pos = np.asarray(self.root_pos, dtype=np.float32)
        rotations = np.asarray(self.rotations, dtype=np.float32)
        J = self.skeleton.n_joints
        if rotations.ndim != 3 or rotations.shape[1:] != (J, 4):
            raise ValueError(f"Expected `rotations` to have shape (F, {J}, 4), got {rotations.shape}")
        F = rotations.shape[0]
        if root_pos.shape != (F, 3):
            raise ValueError(f"Expected `root_pos` to have shape ({F}, 3), got {root_pos.shape}")
        if not (np.all(np.isfinite(root_pos)) and np.all(np.isfinite(rotations))):
            raise ValueError("`root_pos` and `rotations` must be finite (no NaN or Inf)")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"`fps` must be a positive number, got {self.fps}")
        contacts = (np.zeros((F, len(FOOT_NAMES)), bool) if self.contacts is None
                    else np.asarray(self.contacts, dtype=bool))
        if contacts.shape != (F, len(FOOT_NAMES)):
            raise ValueError(f"Expected `contacts` to have shape ({F}, 4), got {contacts.shape}")
        object.__setattr__(self, "root_pos", root_pos)
        object.__setattr__(self, "rotations", quat.normalize(rotations).astype(np.float32))
        object.__setattr__(self, "contacts", contacts)

    @property
    def n_frames(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def duration(self) -> float:
        return self.n_frames / self.fps

    def fk(self) -> tuple[NDArray[np.floating], NDArray[np.floating]]:
        """World joint positions (F, J, 3) and rotations (F, J, 4)."""
        return forward_kinematics(self.skeleton, self.root_pos, self.rotations)

    def positions(self) -> NDArray[np.floating]:
        """World joint positions (F, J, 3)."""
        return self.fk()[0]

    def foot_positions(self) -> NDArray[np.floating]:
        """World positions of the four foot end effectors (F, 4, 3), in FOOT_NAMES order."""
        return self.positions()[:, self.skeleton.foot_joints]

    def speed(self) -> float:
        """The paper's speed s = l / n: ground-projected root path length per frame, in metres.

        Multiply by ``fps`` for metres per second (see :meth:`speed_mps`).
        """
        step = np.diff(self.root_pos[:, [0, 2]].astype(np.float64), axis=0)
        return float(np.linalg.norm(step, axis=-1).sum() / max(self.n_frames - 1, 1))

    def speed_mps(self) -> float:
        return self.speed() * self.fps

    def slice(self, start: int, stop: int) -> Motion:
        """Frames ``[start, stop)``; raises if the range is empty or out of bounds."""
        if not 0 <= start < stop <= self.n_frames:
            raise ValueError(f"frame range [{start}, {stop}) is outside [0, {self.n_frames})")
        return replace(self, root_pos=self.root_pos[start:stop], rotations=self.rotations[start:stop],
                       contacts=self.contacts[start:stop])

    def with_contacts(self, contacts: NDArray[np.bool_]) -> Motion:
        return replace(self, contacts=contacts)
