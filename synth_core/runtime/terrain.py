"""Ground that is not flat (issue 33): a height field, and what the render takes from it.

A :class:`HeightField` is a grid of ground heights ``heights (Nz, Nx)``: ``heights[i, j]`` is the
ground's y at ``x = origin[0] + j * spacing``, ``z = origin[1] + i * spacing`` (metres, Y up);
between grid points it is bilinear, outside the grid the nearest edge's height
(:func:`synth_core.compiled.ground_kernels.ground_at`).

With a height field, a character's trajectory's y is not read: the ground gives it. The render
(:mod:`synth_core.compiled.kernels`) then

1. fits a plane, per frame, to the ground under the four feet of the character's standing
   footprint (:func:`ground_plan`): the root stands on the plane's height under it and the
   body turns by the plane's tilt (pitch and roll: a horse climbing lifts its forehand);
2. measures the feet of that tilted body with the tilt taken back off (legs hang as gravity
   has them, not as the body leans) and relative to the ground under the body, plants them as
   on flat ground (:mod:`synth_core.runtime.footlock`), then puts each target on the terrain
   under it (:func:`synth_core.compiled.foot_kernels.ground_targets`): a planted foot stands on
   it, a swinging foot keeps its clip's height above the ground eased from lift-off to
   touchdown, raised to the tent over the terrain above that, and never below the terrain under
   it (it starts up a step or over a bump from lift-off, not as it gets there);
3. sinks the root where a leg cannot reach and solves the legs' IK as on flat ground.

The gait is chosen on the speed along the ground (:func:`along_ground`).
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from synth_core import UP_AXIS
from synth_core.compiled import ground_kernels
from synth_core.motion import quat
from synth_core.motion.skeleton import forward_kinematics

if TYPE_CHECKING:
    from synth_core.runtime.bank import Bank
    from synth_core.runtime.plan import Plan
    from synth_core.runtime.trajectory import Prepared

Floats = NDArray[np.float64]

MAX_CELLS = 4_194_304  # 2048 x 2048 heights (32 MB): a few km at a metre, or a field at 5 cm
MAX_HEIGHT = 10_000.0  # |height|, m
# The ground under a foot of the footprint is the mean of this pattern around it, in leg
# lengths: a hoof stands on a patch, not a point, and a body does not rock with every pebble.
FOOT_PAD = 0.15


class TerrainError(ValueError):
    """A height field that cannot be used: ``field`` (``ground.heights``, ...) and ``reason``
    (what was wrong and the limit); the message is both, "field: reason"."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")
        self.field, self.reason = field, reason


@dataclass(frozen=True, eq=False)
class HeightField:
    """Ground heights on a regular grid (see the module doc)."""

    heights: Floats  # (Nz, Nx) float64, C-contiguous
    origin: tuple[float, float]  # (x, z) of heights[0, 0], m
    spacing: float  # m between grid points, along x and z

    @classmethod
    def make(cls, heights: ArrayLike, origin: ArrayLike = (0.0, 0.0), spacing: float = 1.0) -> HeightField:
        """A checked height field, or :class:`TerrainError` naming what is wrong."""
        try:
            grid = np.ascontiguousarray(heights, dtype=np.float64)
            at = np.asarray(origin, dtype=np.float64)
            step = float(spacing)
        except (TypeError, ValueError) as exc:
            raise TerrainError("ground", f"not numbers ({exc})") from None
        if grid.ndim != 2 or grid.shape[0] < 2 or grid.shape[1] < 2:
            raise TerrainError("ground.heights", f"expected a grid of at least 2 x 2 rows (z) and "
                               f"columns (x), got shape {grid.shape}")
        if grid.size > MAX_CELLS:
            raise TerrainError("ground.heights", f"at most {MAX_CELLS} heights, got {grid.size} {grid.shape}")
        if not np.all(np.isfinite(grid)) or np.abs(grid).max() > MAX_HEIGHT:
            raise TerrainError("ground.heights", f"every height must be a finite number within "
                               f"+-{MAX_HEIGHT:g} m")
        if at.shape != (2,) or not np.all(np.isfinite(at)):
            raise TerrainError("ground.origin", f"expected two finite numbers (x, z), got {origin!r}")
        if not (np.isfinite(step) and 1e-3 <= step <= 1e4):
            raise TerrainError("ground.spacing", f"must be within [0.001, 10000] m, got {spacing!r}")
        return cls(grid, (float(at[0]), float(at[1])), step)

    def sample(self, x: ArrayLike, z: ArrayLike) -> Floats:
        """The ground's height at ``(x, z)`` (any matching shapes), bilinear."""
        return ground_kernels.ground_samples(self.heights, self.origin[0], self.origin[1], self.spacing,
                                             np.asarray(x, np.float64), np.asarray(z, np.float64))


def read(path: str | Path) -> HeightField:
    """A height field from ``FILE.npz`` (arrays ``heights``, ``origin`` (x, z), ``spacing``) or
    ``FILE.json`` (``{"heights": [[...], ...], "origin": [x, z], "spacing": s}``)."""
    path = Path(path)
    try:
        if path.suffix == ".json":
            spec = json.loads(path.read_text())
            if not isinstance(spec, dict) or "heights" not in spec:
                raise TerrainError("ground", f"{path} must hold an object with heights, origin, spacing")
            origin, spacing = spec.get("origin", (0.0, 0.0)), spec.get("spacing", 1.0)
            return HeightField.make(spec["heights"], origin, spacing)
        with np.load(path) as data:
            if "heights" not in data:
                raise TerrainError("ground", f"{path} has no 'heights' array (has {sorted(data.files)})")
            return HeightField.make(data["heights"], data["origin"] if "origin" in data else (0.0, 0.0),
                                    float(data["spacing"]) if "spacing" in data else 1.0)
    except (OSError, ValueError) as exc:
        if isinstance(exc, TerrainError):
            raise
        raise TerrainError("ground", f"cannot read {path}: {exc}") from None


@dataclass(frozen=True, eq=False)
class Grounding:
    """What the render takes of the ground for one plan: the field, and each frame's tilt of the
    body ``(C, T, 4)`` float64 xyzw (world rotation applied on top of the heading)."""

    field: HeightField
    tilt: Floats

    def window(self, start: int, stop: int) -> Grounding:
        return Grounding(self.field, self.tilt[:, start:stop])


@functools.lru_cache(maxsize=8)
def footprint(bank: Bank) -> Floats:
    """``(4, 2)``: each foot's median (side, forward) place under the root over the library's
    poses, in the library's unit (root yaw canonical: forward +Z, side +X)."""
    sk = bank.skeleton
    pos, _ = forward_kinematics(sk, np.zeros((bank.own, 3)), bank.poses[:bank.own])
    feet = np.asarray(pos, np.float64)[:, sk.foot_joints]
    return np.asarray(np.median(feet[..., [0, 2]], axis=0))


def _pad_pattern(bank: Bank) -> Floats:
    r = FOOT_PAD * bank.skeleton.leg_length()
    return np.array([[0.0, 0.0], [r, 0.0], [-r, 0.0], [0.0, r], [0.0, -r]])


def ground_pose(bank: Bank, field: HeightField, path: Floats, yaw: Floats,
                h: Floats) -> tuple[Floats, Floats]:
    """``(C, T)`` the ground plane's height under the root point of ``path (C, T, 3)`` and
    ``(C, T, 4)`` the body's tilt: the smallest rotation taking up onto the plane's normal, the
    plane fitted (least squares) to the ground under the footprint's four feet."""
    foot = footprint(bank)  # (4, 2) side, forward
    side = np.stack([np.cos(yaw), -np.sin(yaw)], axis=-1)  # (C, T, 2) in world (x, z)
    fwd = np.stack([np.sin(yaw), np.cos(yaw)], axis=-1)
    hs = np.asarray(h, np.float64)[:, None, None, None, None]
    place = foot[None, None, :, :, None] + _pad_pattern(bank).T[None, None, None]  # (1,1,4,2,P)
    across, along = place[:, :, :, :1], place[:, :, :, 1:]
    sideways, ahead = side[:, :, None, :, None], fwd[:, :, None, :, None]
    at = path[:, :, None, [0, 2], None] + hs * (across * sideways + along * ahead)
    under = field.sample(at[..., 0, :], at[..., 1, :]).mean(axis=-1)  # (C, T, 4)
    design = np.concatenate([np.ones((4, 1)), foot], axis=1)  # height = a + b side + c forward
    coef = under @ np.linalg.pinv(design).T  # (C, T, 3), slopes per library unit
    slope_side, slope_fwd = coef[..., 1] / hs[:, :, 0, 0, 0], coef[..., 2] / hs[:, :, 0, 0, 0]
    normal = np.zeros((*yaw.shape, 3))
    normal[..., UP_AXIS] = 1.0
    normal[..., [0, 2]] -= slope_side[..., None] * side + slope_fwd[..., None] * fwd
    up = np.zeros(3)
    up[UP_AXIS] = 1.0
    return np.asarray(coef[..., 0]), np.asarray(quat.between(up, normal), np.float64)


def ground_plan(bank: Bank, p: Plan, field: HeightField) -> tuple[Plan, Grounding]:
    """The plan standing on ``field`` (its path's y: the ground plane under the root) and the
    body's tilt per frame; a frame's numbers depend on that frame's path point alone, so any
    window of the plan gets the same as the whole."""
    ground, tilt = ground_pose(bank, field, p.path, p.yaw, p.scales)
    path = p.path.copy()
    path[..., UP_AXIS] = ground
    return replace(p, path=path), Grounding(field, tilt)


def on_ground(bank: Bank, p: Plan, field: HeightField, start: int, stop: int) -> tuple[Plan, Grounding]:
    """:func:`ground_plan` of frames ``[start, stop)`` of ``p`` alone (a live session's window
    reads no others: its buffer's other frames keep their y, and no tilt)."""
    part, ground = ground_plan(bank, p.window(start, stop), field)
    path = p.path.copy()
    path[:, start:stop] = part.path
    tilt = np.zeros((*p.yaw.shape, 4))
    tilt[..., 3] = 1.0
    tilt[:, start:stop] = ground.tilt
    return replace(p, path=path), Grounding(field, tilt)


def laid(positions: Floats, field: HeightField) -> Floats:
    """``positions (..., 3)`` with their y the ground's under them (a new array)."""
    out = np.array(positions, np.float64)
    out[..., UP_AXIS] = field.sample(out[..., 0], out[..., 2])
    return out


def along_ground(prep: Prepared, field: HeightField, fps: float) -> Prepared:
    """``prep`` on the ground: its paths' y the terrain's under them, the segment speeds those
    along the ground (a 30% slope's 2 m/s over the map are 2.09 m/s of stride)."""
    # Here, not at the top: trajectory imports the compiled kernels, which import footlock and this.
    from synth_core.runtime.trajectory import segment_speeds
    positions = laid(prep.positions, field)
    facing = None if prep.facing is None else laid(prep.facing, field)
    # On the positions smoothed, as on flat ground (trajectory's step 2: not the noise's zig-zag).
    speeds = segment_speeds(positions if facing is None else facing, prep.segment, fps, along_ground=True)
    return replace(prep, positions=positions, facing=facing, segment_speeds=speeds)
