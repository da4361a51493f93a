"""Stick-figure previews: a PNG contact sheet or an animated GIF (matplotlib, headless).

The sheet shows, top to bottom: a gait diagram (Hildebrand style: one bar per foot while it is
planted, time across, the sampled frames marked), one side view per sampled pose (planted feet
marked red, 25 cm ticks on the ground), and a top view of the root path with every plant. Left limbs are
blue, right limbs orange, the body black: a gait's rhythm reads at a glance.

Lives outside :mod:`synth_core` because it needs matplotlib; it only reads motions.
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless: no display on servers or CI

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from synth_core import FOOT_NAMES
from synth_core.motion import bvh
from synth_core.motion.clip import Motion  # noqa: E402
from synth_core.motion.contacts import contacts_from_json, detect_contacts  # noqa: E402

LEFT, RIGHT, BODY, PLANT = "#1f5fbf", "#e07b00", "#222222", "#d62728"
FOOT_COLORS = {"LF": "#1f5fbf", "RF": "#e07b00", "LH": "#6fa8ff", "RH": "#ffb347"}


def load_for_preview(source: str | Path, unit: str = "cm") -> Motion:
    """Read a BVH; contacts from a sibling ``<name>.contacts.json``, else detected."""
    path = Path(source)
    if path.suffix.lower() != ".bvh":
        raise ValueError(f"source: expected a .bvh file, got {path.name!r}")
    motion = bvh.read(path, unit=unit)
    sidecar = path.with_name(path.stem + ".contacts.json")
    if sidecar.exists():
        return motion.with_contacts(contacts_from_json(json.loads(sidecar.read_text()), motion.n_frames))
    if motion.skeleton.feet:
        return motion.with_contacts(detect_contacts(motion))
    return motion


def bone_colors(motion: Motion) -> list[str]:
    colors = [BODY] * motion.skeleton.n_joints
    for foot in motion.skeleton.feet:
        for j in foot.chain:
            colors[j] = LEFT if foot.name[0] == "L" else RIGHT
    return colors


def _travel_axes(pos: NDArray[np.floating], feet: NDArray[np.int64]) -> tuple[NDArray[np.float64],
                                                                              NDArray[np.float64]]:
    """Unit horizontal axes (along, across) of the clip's overall travel.

    An animal that barely moves is viewed along its body: hind feet to fore feet (any rig with
    feet), else +X.
    """
    delta = (pos[-1, 0] - pos[0, 0]).astype(np.float64)
    if np.hypot(delta[0], delta[2]) < 0.05 and len(feet) == 4:
        delta = (pos[0, feet[:2]].mean(axis=0) - pos[0, feet[2:]].mean(axis=0)).astype(np.float64)
    delta[1] = 0.0
    norm = np.linalg.norm(delta)
    along = delta / norm if norm > 1e-6 else np.array([1.0, 0.0, 0.0])
    across = np.cross(along, [0.0, 1.0, 0.0])
    return along, across


def draw_pose(ax: Axes, xy: NDArray[np.floating], parents: NDArray[np.int32],
               colors: list[str], alpha: float = 1.0, lw: float = 2.0) -> None:
    for j in range(1, len(parents)):
        p = parents[j]
        ax.plot([xy[p, 0], xy[j, 0]], [xy[p, 1], xy[j, 1]], color=colors[j], lw=lw, alpha=alpha,
                solid_capstyle="round")


class _Scene:
    """Positions projected once: side (along, up) and top (along, across) coordinates."""

    def __init__(self, motion: Motion, start: int, stop: int) -> None:
        self.motion = motion
        self.pos = motion.positions()[start:stop].astype(np.float64)
        self.contacts = motion.contacts[start:stop]
        self.start = start
        self.feet = motion.skeleton.foot_joints if motion.skeleton.feet else np.zeros(0, np.int64)
        along, across = _travel_axes(self.pos, self.feet)
        self.side = np.stack([self.pos @ along, self.pos[..., 1]], axis=-1)
        self.top = np.stack([self.pos @ along, self.pos @ across], axis=-1)
        self.colors = bone_colors(motion)
        self.parents = motion.skeleton.parents
        self.height = float(np.ptp(self.pos[..., 1])) or 1.0
        # Half-width of a side panel: the farthest any joint gets from the root along travel.
        self.reach = float(np.abs(self.side[..., 0] - self.side[:, :1, 0]).max()) + 0.1 * self.height

    def side_view(self, ax: Axes, f: int, follow: bool = True) -> None:
        half = self.reach
        cx = self.side[f, 0, 0]
        draw_pose(ax, self.side[f], self.parents, self.colors)
        for k, j in enumerate(self.feet):
            if self.contacts[f, k]:
                ax.plot(*self.side[f, j], "o", color=PLANT, ms=6, zorder=5)
        ax.axhline(0.0, color="#888", lw=1)
        grid = np.arange(np.floor((cx - half) * 4) / 4, cx + half, 0.25)
        ax.vlines(grid, -0.03 * self.height, 0.0, color="#aaa", lw=0.8)
        if follow:
            ax.set_xlim(cx - half, cx + half)
        ax.set_ylim(-0.08 * self.height, 1.15 * self.height)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])

    def top_view(self, ax: Axes, frames: NDArray[np.int64], follow: bool = False) -> None:
        """Path, plants and body poses from above; ``follow`` frames a window around frames[-1]."""
        ax.plot(self.top[:, 0, 0], self.top[:, 0, 1], color="#999", lw=1, label="root path")
        for k, j in enumerate(self.feet):
            planted = self.contacts[:, k]
            ax.plot(self.top[planted, j, 0], self.top[planted, j, 1], ".", ms=5,
                    color=FOOT_COLORS[FOOT_NAMES[k]], label=f"{FOOT_NAMES[k]} planted")
        # Body only (legs fold onto themselves from above and hide the path).
        body = [c if c == BODY else "none" for c in self.colors]
        for f in frames:
            draw_pose(ax, self.top[f], self.parents, body, alpha=0.6, lw=1.5)
        ax.set_aspect("equal")
        ax.grid(True, color="#eee")
        if follow:
            cx, cy = self.top[frames[-1], 0]
            half = 1.5 * self.reach
            ax.set_xlim(cx - half, cx + half)
            ax.set_ylim(cy - half, cy + half)
            ax.set_title("top view", fontsize=9)
        else:
            ax.legend(loc="upper left", fontsize=7, ncol=5, frameon=False)
            ax.set_title("top view (metres along / across travel)", fontsize=9)


def _frame_range(motion: Motion, start: int | None, stop: int | None) -> tuple[int, int]:
    start = 0 if start is None else start
    stop = motion.n_frames if stop is None else stop
    if not 0 <= start < stop <= motion.n_frames:
        raise ValueError(f"frames: [{start}, {stop}) is outside the clip's [0, {motion.n_frames})")
    return start, stop


def render(motion: Motion, out: str | Path, *, start: int | None = None, stop: int | None = None,
           panels: int = 8, gif_fps: int = 30) -> Path:
    """Write a PNG contact sheet or a GIF (by ``out``'s suffix); returns the path."""
    out = Path(out)
    start, stop = _frame_range(motion, start, stop)
    scene = _Scene(motion, start, stop)
    if out.suffix.lower() == ".png":
        _contact_sheet(scene, out, max(1, min(panels, stop - start)))
    elif out.suffix.lower() == ".gif":
        _gif(scene, out, gif_fps)
    else:
        raise ValueError(f"out: expected a .png or .gif file, got {out.name!r}")
    return out


def _contact_sheet(scene: _Scene, out: Path, panels: int) -> None:
    n = len(scene.pos)
    frames = np.unique(np.linspace(0, n - 1, panels).round().astype(np.int64))
    fig = plt.figure(figsize=(2.4 * max(len(frames), 4), 8.5), dpi=100)
    grid = fig.add_gridspec(3, len(frames), height_ratios=[0.7, 1.4, 1.0])
    diagram = fig.add_subplot(grid[0, :])
    _gait_diagram(diagram, scene, frames)
    for i, f in enumerate(frames):
        ax = fig.add_subplot(grid[1, i])
        scene.side_view(ax, f)
        planted = [FOOT_NAMES[k] for k in range(len(scene.feet)) if scene.contacts[f, k]]
        ax.set_title(f"f{scene.start + f} {' '.join(planted) or 'flight'}", fontsize=8)
    scene.top_view(fig.add_subplot(grid[2, :]), frames)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def _gait_diagram(ax: Axes, scene: _Scene, frames: NDArray[np.int64]) -> None:
    """Stance bars per foot over time (LF on top), with the sampled frames as dashed lines."""
    motion, n = scene.motion, len(scene.pos)
    t0 = scene.start
    for k in range(len(scene.feet)):
        planted = np.concatenate([[False], scene.contacts[:, k], [False]]).astype(np.int8)
        edges = np.flatnonzero(np.diff(planted)).reshape(-1, 2)
        ax.broken_barh([(t0 + a, b - a) for a, b in edges], (3 - k - 0.35, 0.7),
                       color=FOOT_COLORS[FOOT_NAMES[k]])
    for f in frames:
        ax.axvline(t0 + f, color="#888", lw=0.8, ls="--")
    ax.set_yticks(range(4), list(reversed(FOOT_NAMES)))
    ax.set_xlim(t0, t0 + n)
    ax.set_xlabel("frame", fontsize=8)
    speed = motion.slice(t0, t0 + n).speed_mps() if n > 1 else 0.0
    gait = f", {motion.gait}" if motion.gait else ""
    ax.set_title(f"{motion.name or 'motion'}{gait}: frames {t0}-{t0 + n - 1} at {motion.fps:g} fps, "
                 f"{speed:.2f} m/s; bars = foot planted", fontsize=10)


def _gif(scene: _Scene, out: Path, gif_fps: int) -> None:
    if gif_fps <= 0:
        raise ValueError(f"gif_fps: must be positive, got {gif_fps}")
    n = len(scene.pos)
    step = max(1, int(round(scene.motion.fps / gif_fps)))
    frames = np.arange(0, n, step)[:600]  # cap the file size: 20 s at 30 fps
    fig, (side, top) = plt.subplots(1, 2, figsize=(9, 4), dpi=80,
                                    gridspec_kw={"width_ratios": [1.6, 1.0]})

    def draw(f: int) -> None:
        side.clear()
        top.clear()
        scene.side_view(side, f)
        side.set_title(f"{scene.motion.name} frame {scene.start + f}", fontsize=9)
        scene.top_view(top, np.array([f]), follow=True)

    anim = FuncAnimation(fig, draw, frames=frames, interval=1000 / gif_fps)
    anim.save(out, writer=PillowWriter(fps=max(1, round(scene.motion.fps / step))))
    plt.close(fig)
