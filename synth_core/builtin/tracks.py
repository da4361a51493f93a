"""Gait parameters as per-frame tracks (:mod:`synth_core.builtin.generator` plays them): a gait's
constants held, two gaits blended over a transition, standing; and the easing curves they use."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np
from numpy.typing import NDArray

from synth_core import FOOT_NAMES
from synth_core.builtin.gaits import GaitSpec

Floats = NDArray[np.float64]
FPS = 60.0  # the generated clips' frame rate


# Standing zeroes what moves the body and loads the legs; how a foot swings (lift, flexion,
# breakover) stays ``like``'s, so the first and last steps of a start or stop are real steps.
_STILL = ("speed", "crouch", "bob", "pitch", "nod", "spine_flex", "fetlock_sink", "hock_load",
          "tail_lift", "tail_swing", "sway", "steady_head")


def static_spec(like: GaitSpec) -> GaitSpec:
    """Standing still: every foot planted, nothing oscillating; the stride clock keeps ``like``'s."""
    still: dict[str, object] = {name: 0.0 for name in _STILL}
    still.update(duty=1.0, name="static")
    return replace(like, **still)  # type: ignore[arg-type]



# The gait parameters a track holds per frame (every numeric field but the stride's length).
NUMERIC = [f.name for f in fields(GaitSpec) if f.type in ("float", "int") and f.name != "frames"]


@dataclass(frozen=True)
class Track:
    """Per-frame gait parameters: ``values[name] (T,)``, stride ``frequency (T,)`` Hz, ``phases (T, 4)``."""

    values: dict[str, Floats]
    frequency: Floats
    phases: Floats
    steady_head: Floats  # (T,) weight of the steady-head behaviour

    @property
    def length(self) -> int:
        return len(self.frequency)


def constant_track(spec: GaitSpec, length: int) -> Track:
    return blend_track(spec, spec, np.zeros(length))


def blend_track(a: GaitSpec, b: GaitSpec, weight: Floats) -> Track:
    """Parameters blended from ``a`` (weight 0) to ``b`` (weight 1); phases take the shorter way."""
    w = np.asarray(weight, dtype=np.float64)
    values = {n: (1 - w) * float(getattr(a, n)) + w * float(getattr(b, n)) for n in NUMERIC}
    freq = (1 - w) * FPS / a.frames + w * FPS / b.frames
    # Blend the stance length (the ground a planted foot sweeps), not the duty factor: speed,
    # frequency and duty blended separately make mid-transition stances longer than either gait's
    # and beyond the legs' reach. Near standstill the duty factor is blended as it is.
    stance = (1 - w) * a.speed * a.duty / (FPS / a.frames) + w * b.speed * b.duty / (FPS / b.frames)
    stride = values["speed"] / freq
    moving = stride > 0.25 * max(a.speed / (FPS / a.frames), b.speed / (FPS / b.frames))
    values["duty"] = np.where(moving, np.clip(stance / np.maximum(stride, 1e-9), 0.0, 1.0), values["duty"])
    pa = np.array([a.phases[f] for f in FOOT_NAMES])
    pb = np.array([b.phases[f] for f in FOOT_NAMES])
    pb = pa + ((pb - pa + 0.5) % 1.0 - 0.5)  # continuous footfall order: nearest equivalent phase
    phases = (1 - w)[:, None] * pa + w[:, None] * pb
    steady = (1 - w) * float(a.steady_head) + w * float(b.steady_head)
    return Track(values, freq, phases, steady)


def concat(*tracks: Track) -> Track:
    return Track({n: np.concatenate([t.values[n] for t in tracks]) for n in tracks[0].values},
                 np.concatenate([t.frequency for t in tracks]),
                 np.concatenate([t.phases for t in tracks]),
                 np.concatenate([t.steady_head for t in tracks]))


def smoothstep(x: Floats) -> Floats:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def min_jerk(s: Floats) -> Floats:
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10 - 15 * s + 6 * s * s)
