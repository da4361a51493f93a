"""The edge scenario suite: root trajectories a crowd simulator really sends (issue 27).

``quadsynth eval --suite edge`` synthesizes each and measures the output after FK
(:mod:`synth_core.quality.evaluate`). Every scenario is a small herd (a few characters, a few hundred
frames) of paths made here -- pure numpy, seeded -- from two pieces:

- a **speed profile** ``v(t)``: piecewise linear between knots (stand, cruise, brake, pause);
- a **curve** by arc length: straight, with turns of a given angle on arcs of a given radius
  (heading changing at ``1 / radius`` per metre), integrated on a fine grid.

A path is the curve sampled at the distance the speed profile has covered, so speed and shape
are exact by construction: a stop stops, a corner has the stated radius. Speeds are per gait,
from the library (``gait_speeds``), so the same suite asks a horse and a dog for their own walk,
trot, canter and gallop; creeps and the jitter's noise are absolute.

Shapes: ``positions (C, F, 3)`` float32 metres, Y up (the ground at 0), at ``fps``.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter

from synth_core.runtime.terrain import HeightField

Floats = NDArray[np.float64]
# A turn: (distance along the path where it starts (m), angle (rad, + left), radius (m)).
Turn = tuple[float, float, float]

SPACING = 4.0  # metres between the herd's characters, sideways
GRID_M = 0.002  # arc-length step of the curve integration
BRAKE = 3.0  # m/s^2: a brisk stop an animal manages
SPEED_UP = 3.0  # m/s^2: the start of a run, up to cruising speed
TOO_FAST = 1.5  # the too-fast character: this times the library's fastest clip
JITTER_HZ = 10.0  # a simulator ticking at 10 Hz, sampled at the output rate (sample and hold)
JITTER_M = 0.02  # ... plus this much noise (sd, metres) on each tick's position


@dataclass(frozen=True, eq=False)
class Scenario:
    name: str
    positions: NDArray[np.float32]  # (C, F, 3) what the simulator sends
    scales: Floats  # (C,)
    reference: NDArray[np.float32]  # (C, F, 3) the path meant (positions without jitter noise)
    about: str
    ground: HeightField | None = None  # the terrain walked on (None: flat, at the paths' y)
    sampled: NDArray[np.int64] | None = None  # (F,) the frame each point sent was sampled at (held ticks)

    def velocity(self, fps: float) -> Floats:
        """``(C, F, 2)`` the ground velocity (x, z, m/s) a simulator would send with each point: its
        path meant's, at the frame the point was sampled at (a held tick holds it too)."""
        v = np.gradient(self.reference[..., [0, 2]].astype(np.float64), axis=1) * fps
        return v if self.sampled is None else v[:, self.sampled]


GaitSpeeds = Mapping[str, tuple[float, float]]  # gait -> (slowest, fastest) clip speed, m/s at scale 1


def cruise(gaits: GaitSpeeds, gait: str) -> float:
    """A gait's middle speed."""
    low, high = gaits[gait]
    return 0.5 * (low + high)


def speed_profile(frames: int, fps: float, knots: Sequence[tuple[float, float]]) -> Floats:
    """Speed per frame (m/s), linear between ``knots`` (time s, speed m/s), held past the ends."""
    t, v = np.array(knots, np.float64).T
    return np.asarray(np.interp(np.arange(frames) / fps, t, v))


def ramp(v0: float, v1: float, at: float, rate: float) -> list[tuple[float, float]]:
    """Knots of a change from ``v0`` to ``v1`` starting at ``at`` s, at ``rate`` m/s^2."""
    return [(at, v0), (at + abs(v1 - v0) / rate, v1)]


def distance(speed: Floats, fps: float) -> Floats:
    """Distance covered at each frame (m): 0 at frame 0, then the trapezoid sum."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1])) / fps])


def curve(s: Floats, turns: Sequence[Turn], heading: float = 0.0) -> Floats:
    """Ground points ``(n, 2)`` (x, z) at arc lengths ``s`` of a path from the origin, first
    heading ``heading`` (rad about +Y, 0 = +Z), turning by each ``(start, angle, radius)``."""
    grid = np.arange(0.0, float(np.max(s)) + 2 * GRID_M, GRID_M)
    yaw = np.full_like(grid, heading)
    for start, angle, radius in turns:
        yaw += angle * np.clip((grid - start) / max(abs(angle) * radius, 1e-9), 0.0, 1.0)
    mid = 0.5 * (yaw[1:] + yaw[:-1])
    x = np.concatenate([[0.0], np.cumsum(np.sin(mid)) * GRID_M])
    z = np.concatenate([[0.0], np.cumsum(np.cos(mid)) * GRID_M])
    return np.stack([np.interp(s, grid, x), np.interp(s, grid, z)], axis=-1)


def herd(paths: Sequence[Floats], scales: Sequence[float] | None = None, name: str = "",
         about: str = "", positions: Sequence[Floats] | None = None,
         sampled: NDArray[np.int64] | None = None) -> Scenario:
    """A scenario from ground paths ``(F, 2)`` each, set side by side ``SPACING`` apart.
    ``positions``: what the simulator sends, when it differs from the paths (jitter), each point
    the path's at frame ``sampled``."""
    def lift(xz: Sequence[Floats]) -> NDArray[np.float32]:
        out = np.zeros((len(xz), len(xz[0]), 3), np.float32)
        for c, p in enumerate(xz):  # a few characters
            out[c, :, 0] = p[:, 0] + c * SPACING
            out[c, :, 2] = p[:, 1]
        return out

    reference = lift(paths)
    sent = reference if positions is None else lift(positions)
    h = np.ones(len(paths)) if scales is None else np.asarray(scales, np.float64)
    return Scenario(name, sent, h, reference, about, sampled=sampled)


def run(frames: int, fps: float, knots: Sequence[tuple[float, float]], turns: Sequence[Turn] = (),
        heading: float = 0.0) -> Floats:
    """One character's ground path: ``knots`` speed profile along a curve with ``turns``."""
    return curve(distance(speed_profile(frames, fps, knots), fps), turns, heading)


def start_at(v: float, stand: float = 0.5) -> list[tuple[float, float]]:
    """Knots: stand ``stand`` s, then speed up to ``v``."""
    return [(0.0, 0.0), *ramp(0.0, v, stand, SPEED_UP)]


def frames_for(seconds: float, fps: float) -> int:
    return int(round(seconds * fps))


# --- the scenarios -----------------------------------------------------------------------------

def cruise_straight(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    """The baseline: each gait's middle speed on a straight line (after a run-up), so a figure
    missed in a turn can be told from one the gait misses anyway."""
    order = [g for g in ("walk", "trot", "canter", "gallop") if g in gaits]
    F = frames_for(0.5 + max(cruise(gaits, g) for g in order) / SPEED_UP + 5.0, fps)
    speeds = [cruise(gaits, g) for g in order]
    return herd([run(F, fps, start_at(v)) for v in speeds], name="cruise_straight",
                about=f"straight at each gait's middle speed {[round(v, 2) for v in speeds]} m/s")


def stop_and_stand(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    speeds = [cruise(gaits, g) for g in ("walk", "trot", "canter") if g in gaits]
    F = frames_for(8.0, fps)
    paths = []
    for v in speeds:
        brake_at = 0.5 + v / SPEED_UP + 1.5 + rng.uniform(0, 0.3)
        paths.append(run(F, fps, [*start_at(v), *ramp(v, 0.0, brake_at, BRAKE)]))
    return herd(paths, name="stop_and_stand",
                about="run at a walk, trot and canter, brake at 3 m/s^2, stand 3+ s")


def stop_go(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    pauses = [0.3, float(rng.uniform(0.8, 1.8)), 3.0]
    gait = [g for g in ("walk", "trot", "trot") if g in gaits]
    F = frames_for(9.0, fps)
    paths = []
    for pause, g in zip(pauses, gait, strict=False):
        v = cruise(gaits, g)
        stop = 0.5 + v / SPEED_UP + 1.0
        halt = stop + v / BRAKE
        knots = [*start_at(v), *ramp(v, 0.0, stop, BRAKE), *ramp(0.0, v, halt + pause, SPEED_UP)]
        paths.append(run(F, fps, knots))
    return herd(paths, name="stop_go", about=f"run, stop, pause {[round(p, 2) for p in pauses]} s, go again")


CREEP_RANGE = (0.05, 0.4)
CREEP_SPEEDS = (0.05, 0.15, 0.25, 0.4)  # fixed, not drawn: whether a creep floats depends on its speed


def creep(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    speeds = list(CREEP_SPEEDS)
    # 12 s: long enough for a slow root to glide past feet pinned where it stood (0.6-4.8 m).
    F = frames_for(12.0, fps)
    return herd([run(F, fps, start_at(v)) for v in speeds], name="creep",
                about=f"creep at {[round(float(v), 2) for v in speeds]} m/s")


def turn_on_spot(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    """Arrive at a walk, stop, leave in another direction (90 and 180 deg: the turn happens
    standing); and one pivoting on a 0.2 m circle at 0.15 m/s (a simulator's idea of turning)."""
    v = cruise(gaits, "walk") if "walk" in gaits else 1.0
    F = frames_for(7.0, fps)
    stop = 0.5 + v / SPEED_UP + 1.0
    halt = stop + v / BRAKE
    knots = [*start_at(v), *ramp(v, 0.0, stop, BRAKE), *ramp(0.0, v, halt + 1.0, SPEED_UP)]
    s = distance(speed_profile(F, fps, knots), fps)
    at = float(s[frames_for(halt, fps)])
    paths = [curve(s, [(at, angle, 1e-4)]) for angle in (np.pi / 2, -np.pi)]
    pivot = distance(speed_profile(F, fps, start_at(0.15)), fps)
    paths.append(curve(pivot, [(0.0, pivot[-1] / 0.2, 0.2)]))
    return herd(paths, name="turn_on_spot", about="arrive, stop, leave at 90 / 180 deg; pivot on r 0.2 m")


RADII = (0.5, 2.0, 5.0)


def bend(gait: str, angle: float, name: str) -> Callable[[GaitSpeeds, float, np.random.Generator], Scenario]:
    """Corners (``angle`` 90 deg) or U-turns (180 deg) at a gait's speed, radii 0.5, 2 and 5 m,
    after a run up to that speed; left and right alternate."""
    def make(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
        v = cruise(gaits, gait)
        run_up = 0.5 + v / SPEED_UP + 1.0
        s0 = float(distance(speed_profile(frames_for(run_up, fps), fps, start_at(v)), fps)[-1])
        # Long enough for the widest turn and 2 s after it.
        F = frames_for(run_up + abs(angle) * max(RADII) / v + 2.0, fps)
        paths = [run(F, fps, start_at(v), [(s0, (1 if k % 2 == 0 else -1) * angle, r)])
                 for k, r in enumerate(RADII)]
        return herd(paths, name=name,
                    about=f"{round(np.degrees(angle))} deg at {gait} speed {v:.2f} m/s, "
                          f"radii {list(RADII)} m")
    return make


def zigzag(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    """Heading swinging +-45 deg about the mean every leg (90 deg turns on 0.5-1 m arcs)."""
    F = frames_for(8.0, fps)
    paths = []
    for g in [g for g in ("walk", "trot", "canter") if g in gaits]:
        v = cruise(gaits, g)
        leg = float(rng.uniform(1.0, 1.6)) * v  # 1-1.6 s a leg
        r = float(rng.uniform(0.5, 1.0))
        s = distance(speed_profile(F, fps, start_at(v)), fps)
        starts = np.arange(leg, s[-1], leg)
        turns = [(float(a), (np.pi / 2) * (1 if i % 2 else -1), r) for i, a in enumerate(starts)]
        paths.append(curve(s, turns, heading=np.pi / 4))
    return herd(paths, name="zigzag", about="zig-zags: 90 deg turns every 1-1.6 s at walk, trot, canter")


def small_circles(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    F = frames_for(8.0, fps)
    paths = []
    for g, r in zip([g for g in ("walk", "trot", "trot") if g in gaits], (1.0, 2.0, 3.0), strict=False):
        v = cruise(gaits, g)
        s = distance(speed_profile(F, fps, start_at(v)), fps)
        paths.append(curve(s, [(0.5, s[-1] / r, r)]))
    return herd(paths, name="small_circles", about="circles of radius 1, 2, 3 m at walk and trot")


def accel_brake(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    top = cruise(gaits, max(gaits, key=lambda g: gaits[g][1]))
    F = frames_for(9.0, fps)
    paths = []
    for a in (4.0, 6.0, 8.0):
        go = 0.5 + top / a + 1.0
        paths.append(run(F, fps, [(0.0, 0.0), *ramp(0.0, top, 0.5, a), *ramp(top, 0.0, go, a)]))
    return herd(paths, name="accel_brake",
                about=f"stand, to {top:.2f} m/s and back to 0 at 4, 6 and 8 m/s^2")


def brake_to_crawl(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    """Run at the canter's and the gallop's speed, brake at 3 or 6 m/s^2 to a crawl (0.15-0.5
    m/s: an agent held up in a jam), crawl on. A crawl is no stop: the animal must walk it, not
    stand, not play the transition it was in at a crawl's pace."""
    F = frames_for(8.0, fps)
    paths = []
    for g, a, crawl in (("canter", BRAKE, 0.3), ("canter", BRAKE, 0.5), ("gallop", 2 * BRAKE, 0.15),
                        ("gallop", BRAKE, 0.3)):
        v = cruise(gaits, g if g in gaits else max(gaits, key=lambda h: gaits[h][1]))
        paths.append(run(F, fps, [*start_at(v), *ramp(v, crawl, 0.5 + v / SPEED_UP + 1.5, a)]))
    return herd(paths, name="brake_to_crawl",
                about="canter, canter, gallop, gallop braking at 3, 3, 6, 3 m/s^2 to 0.3, 0.5, 0.15, 0.3 m/s")


def jitter_10hz(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    """A gentle curve (r 15 m) at walk, trot and canter speed, as a 10 Hz simulator sends it at
    the output rate: each tick's position held until the next, plus 2 cm noise a tick."""
    F = frames_for(7.0, fps)
    clean, sent = [], []
    hold = max(1, int(round(fps / JITTER_HZ)))
    for g in [g for g in ("walk", "trot", "canter") if g in gaits]:
        s = distance(speed_profile(F, fps, start_at(cruise(gaits, g))), fps)
        path = curve(s, [(0.0, s[-1] / 15.0, 15.0)])
        tick = (np.arange(F) // hold) * hold
        noise = rng.normal(0.0, JITTER_M, (F // hold + 1, 2))[np.arange(F) // hold]
        clean.append(path)
        sent.append(path[tick] + noise)
    return herd(clean, name="jitter_10hz", positions=sent, sampled=(np.arange(F) // hold) * hold,
                about="10 Hz sample-and-hold + 2 cm noise on a r 15 m curve (path measured to the "
                      "clean curve)")


def too_fast(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    """Four characters at a trot and canter, one at 1.5x the library's fastest clip."""
    fastest = max(high for _, high in gaits.values())
    gait = [g for g in ("trot", "canter") if g in gaits] or list(gaits)
    speeds = [cruise(gaits, gait[k % len(gait)]) for k in range(4)] + [TOO_FAST * fastest]
    F = frames_for(7.0, fps)
    return herd([run(F, fps, start_at(v), [(5.0, np.pi / 3, 20.0)]) for v in speeds], name="too_fast",
                about=f"4 at trot/canter, one at {TOO_FAST}x the fastest clip ({TOO_FAST * fastest:.1f} m/s)")


def mixed_sizes(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    """Scales 0.5, 0.8, 1.25 and 2 on one path: speeding up to the scale-1 canter and back to a
    walk through a bend."""
    scales = [0.5, 0.8, 1.25, 2.0]
    fast = cruise(gaits, "canter" if "canter" in gaits else max(gaits, key=lambda g: gaits[g][1]))
    slow = cruise(gaits, "walk" if "walk" in gaits else min(gaits, key=lambda g: gaits[g][0]))
    F = frames_for(9.0, fps)
    knots = [*start_at(fast), *ramp(fast, slow, 5.0, BRAKE)]
    path = run(F, fps, knots, [(8.0, np.pi / 2, 6.0)])
    return herd([path] * len(scales), scales, name="mixed_sizes",
                about=f"scales {scales} on one path up to {fast:.2f} m/s and back to {slow:.2f}")


def moving_start(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    """Paths already moving at frame 0 -- an agent spawned, or taken over, at speed -- at each
    gait's middle speed on a gentle curve, each heading its own way."""
    order = [g for g in ("walk", "trot", "canter", "gallop") if g in gaits]
    F = frames_for(5.0, fps)
    paths = [run(F, fps, [(0.0, cruise(gaits, g))], [(0.0, float(rng.choice([-1, 1])) * 0.5, 20.0)],
                 heading=float(rng.uniform(-np.pi, np.pi))) for g in order]
    return herd(paths, name="moving_start", about="at each gait's middle speed from frame 0, r 20 m curves")


# --- ground that is not flat (issue 33) ---------------------------------------------------------

TERRAIN_SPACING = 0.05  # m between the scenarios' height-field points
TERRAIN_MARGIN = 10.0  # m of terrain around the paths


def on_terrain(sc: Scenario, heights: Callable[[Floats, Floats], Floats], name: str, about: str) -> Scenario:
    """``sc`` on the ground ``heights(x, z)`` (metres, vectorized), sampled on a grid around its
    paths; the paths' y (which the render does not read on a terrain) the ground's under them."""
    lo = sc.positions[..., [0, 2]].min(axis=(0, 1)) - TERRAIN_MARGIN
    hi = sc.positions[..., [0, 2]].max(axis=(0, 1)) + TERRAIN_MARGIN
    xs = np.arange(lo[0], hi[0] + TERRAIN_SPACING, TERRAIN_SPACING)
    zs = np.arange(lo[1], hi[1] + TERRAIN_SPACING, TERRAIN_SPACING)
    x, z = np.meshgrid(xs, zs)
    field = HeightField.make(heights(x, z), (float(xs[0]), float(zs[0])), TERRAIN_SPACING)

    def grounded(p: NDArray[np.float32]) -> NDArray[np.float32]:
        out = p.copy()
        out[..., 1] = field.sample(p[..., 0], p[..., 2])
        return out

    return Scenario(name, grounded(sc.positions), sc.scales, grounded(sc.reference), about, field, sc.sampled)


def _gaits_straight(gaits: GaitSpeeds, fps: float, seconds: float = 6.0,
                    turns: Sequence[Turn] = ()) -> Scenario:
    """Walk, trot and canter side by side at their middle speeds, heading +Z after a run-up."""
    order = [g for g in ("walk", "trot", "canter") if g in gaits]
    speeds = [cruise(gaits, g) for g in order]
    F = frames_for(0.5 + max(speeds) / SPEED_UP + seconds, fps)
    return herd([run(F, fps, start_at(v), turns) for v in speeds])


def slope(grade: float, direction: str) -> Callable[[GaitSpeeds, float, np.random.Generator], Scenario]:
    """A plane rising ``grade`` (rise over run) up (+Z, the way the herd goes), down or across."""
    def make(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
        k = {"up": (0.0, grade), "down": (0.0, -grade), "across": (grade, 0.0)}[direction]
        return on_terrain(_gaits_straight(gaits, fps), lambda x, z: k[0] * x + k[1] * z,
                          f"slope_{direction}_{round(grade * 100)}",
                          f"walk, trot and canter straight {direction} a {grade:.0%} slope")
    return make


def step_20cm(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    return on_terrain(_gaits_straight(gaits, fps), lambda x, z: np.where(z > 6.0, 0.2, 0.0), "step_20cm",
                      "walk, trot and canter up a 20 cm step 6 m along the path")


def rolling_hills(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    return on_terrain(_gaits_straight(gaits, fps, turns=[(5.0, 0.6, 12.0)]),
                      lambda x, z: 0.6 * np.sin(2 * np.pi * z / 16.0) * np.cos(2 * np.pi * x / 22.0),
                      "rolling_hills", "walk, trot and canter over hills 1.2 m from trough to crest "
                      "(up to 24% steep), bending left")


def bumpy(gaits: GaitSpeeds, fps: float, rng: np.random.Generator) -> Scenario:
    sc = _gaits_straight(gaits, fps)
    lo = sc.positions[..., [0, 2]].min(axis=(0, 1)) - TERRAIN_MARGIN
    hi = sc.positions[..., [0, 2]].max(axis=(0, 1)) + TERRAIN_MARGIN
    shape = (int((hi[1] - lo[1]) / TERRAIN_SPACING) + 2, int((hi[0] - lo[0]) / TERRAIN_SPACING) + 2)
    noise = gaussian_filter(rng.normal(0.0, 1.0, shape), 3.0)  # bumps ~15 cm across
    noise *= 0.03 / noise.std()

    def heights(x: Floats, z: Floats) -> Floats:
        return np.asarray(noise[:x.shape[0], :x.shape[1]])

    return on_terrain(sc, heights, "bumpy", "walk, trot and canter over bumps of 3 cm (sd), ~15 cm across")


TERRAIN_MAKERS: dict[str, Callable[[GaitSpeeds, float, np.random.Generator], Scenario]] = {
    **{f"slope_up_{g}": slope(g / 100, "up") for g in (10, 20, 30)},
    "slope_down_30": slope(0.3, "down"),
    "slope_across_30": slope(0.3, "across"),
    "step_20cm": step_20cm,
    "rolling_hills": rolling_hills,
    "bumpy": bumpy,
}


MAKERS: dict[str, Callable[[GaitSpeeds, float, np.random.Generator], Scenario]] = {
    "cruise_straight": cruise_straight,
    "stop_and_stand": stop_and_stand,
    "stop_go": stop_go,
    "creep": creep,
    "turn_on_spot": turn_on_spot,
    **{f"corner_{g}": bend(g, np.pi / 2, f"corner_{g}") for g in ("walk", "trot", "canter", "gallop")},
    **{f"uturn_{g}": bend(g, np.pi, f"uturn_{g}") for g in ("walk", "trot", "canter", "gallop")},
    "zigzag": zigzag,
    "small_circles": small_circles,
    "accel_brake": accel_brake,
    "brake_to_crawl": brake_to_crawl,
    "jitter_10hz": jitter_10hz,
    "too_fast": too_fast,
    "mixed_sizes": mixed_sizes,
    "moving_start": moving_start,
    **TERRAIN_MAKERS,
}


def needs(name: str) -> str | None:
    """The gait a scenario is about (corners and U-turns), if any."""
    return name.split("_", 1)[1] if name.startswith(("corner_", "uturn_")) else None


def scenarios(gaits: GaitSpeeds, fps: float = 60.0, seed: int = 0,
              names: Sequence[str] | None = None) -> list[Scenario]:
    """The suite for a library with ``gaits`` (those it lacks are left out), each scenario
    drawing from its own stream of ``seed``, keyed by its name (one scenario's draws never
    shift another's, nor does adding a scenario)."""
    chosen = list(MAKERS) if names is None else list(names)
    unknown = [n for n in chosen if n not in MAKERS]
    if unknown:
        raise ValueError(f"scenario: unknown {unknown}; the suite has {list(MAKERS)}")
    out = []
    for name in MAKERS:
        if name in chosen and (needs(name) is None or needs(name) in gaits):
            out.append(MAKERS[name](gaits, fps, np.random.default_rng([seed, zlib.crc32(name.encode())])))
    return out
