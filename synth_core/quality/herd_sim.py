"""A small herd simulator (in the spirit of OpenSteer's pedestrians), for tests and benchmarks.

Agents follow a looped control path (an ellipse) as a herd: each keeps a place in a jittered
grid formation around a leader point -- rows along the path, columns across it, one body length
and more apart, so they keep their separation -- and drifts slowly within its place. The herd
starts standing, speeds up from a walk toward a gallop and slows back down, with accelerations
an animal manages (so the motion graph's transitions can keep up).

Output: ``positions (C, F, 3)`` float32 metres, Y up, at ``fps``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

STAND_SECONDS = 1.0
ACCELERATION = 2.0  # m/s^2, up and down (a horse manages 3-5 from standing)
DRIFT_RAMP_M = 10.0  # distance over which an agent's drift within its place grows to full


def speed_profile(frames: int, fps: float, top: float) -> NDArray[np.float64]:
    """Leader speed per frame: stand, speed up to ``top``, slow to a walk; limited acceleration."""
    t = np.arange(frames) / fps
    duration = max(t[-1], 1e-9)
    # Wanted speed: up to top over the first half after standing, then down to 15% of it.
    moving = np.clip((t - STAND_SECONDS) / max(duration - STAND_SECONDS, 1e-9), 0.0, 1.0)
    wanted = top * np.where(moving < 0.6, moving / 0.6, 1.0 - 0.85 * (moving - 0.6) / 0.4)
    wanted[t < STAND_SECONDS] = 0.0
    # Acceleration limit, forward then backward (so the herd can also stop in time):
    # speed[i] = min over j <= i of wanted[j] + (i - j) limit, a running minimum; then mirrored.
    limit = ACCELERATION / fps
    i = np.arange(frames) * limit
    speed = i + np.minimum.accumulate(wanted - i)
    speed = np.minimum.accumulate((speed + i)[::-1])[::-1] - i
    return np.asarray(speed, np.float64)


def simulate(characters: int, frames: int, seed: int = 0, fps: float = 60.0, top: float = 7.0,
             spacing: float = 3.0) -> NDArray[np.float32]:
    if characters < 1 or frames < 2:
        raise ValueError(f"crowd: need at least 1 character and 2 frames, got {characters}, {frames}")
    rng = np.random.default_rng(seed)
    cols = int(np.ceil(np.sqrt(characters / 2)))
    rows = int(np.ceil(characters / cols))
    lateral = (np.arange(characters) % cols - (cols - 1) / 2) * spacing
    along = -(np.arange(characters) // cols) * spacing * 1.3
    lateral = lateral + rng.uniform(-0.25, 0.25, characters) * spacing
    along = along + rng.uniform(-0.2, 0.2, characters) * spacing
    # The loop is large next to the herd, so inner agents never run backwards on its curves.
    width = cols * spacing
    a, b = max(120.0, 6 * width), max(80.0, 4 * width)
    speed = speed_profile(frames, fps, top)
    distance = np.cumsum(speed) / fps  # (F,)
    # Standing agents stand still; the drift grows with the distance covered, not with speed, so
    # it never outruns the herd (grown with speed, it pushed agents backwards as they started).
    moving = np.clip(distance / DRIFT_RAMP_M, 0.0, 1.0)[None, :]
    drift_phase = rng.uniform(0, 2 * np.pi, (characters, 2))
    t = np.arange(frames) / fps
    drift = moving * 0.15 * spacing * np.sin(0.3 * t[None, :] + drift_phase[:, :1])  # slow, in place
    s = distance[None, :] + along[:, None] + drift + rows * spacing  # arc length on the loop
    # An ellipse parameterised by angle; arc length ~ angle * mean radius (good enough here).
    angle = s / (0.5 * (a + b))
    x, z = a * np.sin(angle), b * (1 - np.cos(angle))
    dx, dz = a * np.cos(angle), b * np.sin(angle)
    norm = np.hypot(dx, dz)
    nx, nz = dz / norm, -dx / norm  # the path's left-hand normal
    side = lateral[:, None] + moving * 0.1 * spacing * np.sin(0.2 * t[None, :] + drift_phase[:, 1:])
    pos = np.stack([x + side * nx, np.zeros_like(x), z + side * nz], axis=-1)
    return pos.astype(np.float32)
