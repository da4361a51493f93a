"""Herd preview GIF: a top view of every character plus side-view close-ups of a few.

Top view: each character's body from above (spine and head, coloured by gait) with the herd's
paths faint behind; close-ups: stick figures of the first ``close_ups`` characters, planted feet
red, following each one. Frames are sampled to ``gif_fps`` and capped at 20 s.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from quadsynth.preview import bone_colors, draw_pose  # noqa: E402
from synth_core.export.character import character_motion  # noqa: E402
from synth_core.motion.skeleton import Skeleton  # noqa: E402
from synth_core.runtime.synthesis import Result  # noqa: E402

GAIT_COLORS = ["#777777", "#2ca02c", "#1f77b4", "#ff7f0e", "#d62728"]  # static, walk, trot, canter, gallop
MAX_TOP = 2000  # characters drawn in the top view


def _draw_side(ax: Any, skeleton: Skeleton, result: Result, view: tuple[int, NDArray[np.float64], float],
               colors: Any, hubs: tuple[str, ...], f: int) -> None:
    """Character ``c``'s close-up at frame ``f``, seen from its side (along its heading), ``half``
    metres either side of its root; planted feet marked."""
    c, pos, half = view
    T = result.root_pos.shape[1]
    ax.clear()
    heading = result.root_pos[c, min(f + 1, T - 1)] - result.root_pos[c, max(f - 1, 0)]
    heading[1] = 0
    along = heading / n if (n := np.linalg.norm(heading)) > 1e-6 else np.array([1.0, 0.0, 0.0])
    xy = np.stack([pos[f] @ along, pos[f, :, 1]], axis=-1)
    draw_pose(ax, xy, skeleton.parents, colors)
    for k, j in enumerate(skeleton.foot_joints):
        if result.contacts[c, f, k]:
            ax.plot(*xy[j], "o", color="#d62728", ms=5)
    cx, size = xy[0, 0], float(np.ptp(pos[..., 1])) or 1.0
    ax.axhline(result.path[c, f, 1], color="#888", lw=1)
    ax.set_xlim(cx - half, cx + half)
    ax.set_ylim(result.path[c, f, 1] - 0.1 * size, result.path[c, f, 1] + 1.2 * size)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(f"#{c} {hubs[int(result.gait[c, f])]} h={result.scales[c]:.2f}", fontsize=8)


def render_herd(skeleton: Skeleton, result: Result, out: str | Path, fps: float, hubs: tuple[str, ...],
                close_ups: int = 3, gif_fps: int = 15) -> Path:
    """A GIF (``out`` ending .gif), or a PNG contact sheet (.png, :func:`herd_sheet`)."""
    out = Path(out)
    if out.suffix.lower() == ".png":
        return herd_sheet(skeleton, result, out, fps, hubs)
    if gif_fps <= 0:
        raise ValueError(f"gif_fps: must be positive, got {gif_fps}")
    C, T = result.root_pos.shape[:2]
    step = max(1, int(round(fps / gif_fps)))
    frames = np.arange(0, T, step)[:20 * gif_fps]
    shown = np.linspace(0, C - 1, min(C, MAX_TOP)).astype(int)
    picks = list(range(min(close_ups, C)))
    side, reach = [], []
    for c in picks:  # side view: along the character's own heading
        pos = character_motion(skeleton, result, c, fps).positions().astype(np.float64)
        side.append(pos)
        reach.append(float(np.linalg.norm((pos - pos[:, :1])[..., [0, 2]], axis=-1).max()) * 1.1)
    colors = bone_colors(character_motion(skeleton, result, 0, fps))
    fig = plt.figure(figsize=(4.5 + 3.2 * len(picks), 3.4), dpi=80)
    grid = fig.add_gridspec(1, 1 + len(picks), width_ratios=[1.4] + [1.0] * len(picks))
    top = fig.add_subplot(grid[0, 0])
    axes = [fig.add_subplot(grid[0, 1 + k]) for k in range(len(picks))]
    fig.subplots_adjust(left=0.04, right=0.99, top=0.9, bottom=0.08, wspace=0.08)
    xz = result.root_pos[shown][..., [0, 2]]
    lo, hi = xz.reshape(-1, 2).min(axis=0) - 2, xz.reshape(-1, 2).max(axis=0) + 2

    def draw(f: int) -> None:
        top.clear()
        top.plot(xz[:, :, 0].T, xz[:, :, 1].T, color="#e5e5e5", lw=0.5, zorder=0)
        gait = result.gait[shown, f].astype(int)
        top.scatter(xz[:, f, 0], xz[:, f, 1], s=6, c=[GAIT_COLORS[g % 5] for g in gait], zorder=2)
        for c in picks:
            top.plot(*result.root_pos[c, f, [0, 2]], "o", mfc="none", mec="k", ms=9)
        top.set_xlim(lo[0], hi[0])
        top.set_ylim(lo[1], hi[1])
        top.set_aspect("equal")
        counts = np.bincount(gait, minlength=len(hubs))
        top.set_title(f"frame {f}: " + ", ".join(f"{h} {n}" for h, n in zip(hubs, counts, strict=False) if n),
                      fontsize=8)
        for ax, c, pos, half in zip(axes, picks, side, reach, strict=True):
            _draw_side(ax, skeleton, result, (c, pos, half), colors, hubs, f)

    anim = FuncAnimation(fig, draw, frames=frames, interval=1000 / gif_fps)
    out.parent.mkdir(parents=True, exist_ok=True)
    anim.save(out, writer=PillowWriter(fps=max(1, round(fps / step))))
    plt.close(fig)
    return out


SHEET_ROWS = 6  # characters on a contact sheet
SHEET_COLUMNS = 8  # moments


def herd_sheet(skeleton: Skeleton, result: Result, out: str | Path, fps: float, hubs: tuple[str, ...],
               rows: int = SHEET_ROWS, columns: int = SHEET_COLUMNS) -> Path:
    """A PNG contact sheet: ``rows`` characters spread over the herd, each drawn from the side
    (along its own heading) at ``columns`` moments spread over the run, planted feet red, the
    ground under it grey; each panel titled with the time, gait and the character's size."""
    out = Path(out)
    C, T = result.root_pos.shape[:2]
    picks = np.unique(np.linspace(0, C - 1, min(rows, C)).astype(int))
    frames = np.linspace(0, T - 1, columns + 2).astype(int)[1:-1]
    colors = bone_colors(character_motion(skeleton, result, 0, fps))
    fig, axes = plt.subplots(len(picks), columns, figsize=(2.6 * columns, 1.6 * len(picks)), dpi=80,
                             squeeze=False)
    fig.subplots_adjust(left=0.01, right=0.99, top=0.95, bottom=0.01, wspace=0.04, hspace=0.3)
    for row, c in zip(axes, picks, strict=True):
        pos = character_motion(skeleton, result, int(c), fps).positions().astype(np.float64)
        size = float(np.ptp(pos[..., 1])) or 1.0
        half = float(np.linalg.norm((pos - pos[:, :1])[..., [0, 2]], axis=-1).max()) * 1.1
        for ax, f in zip(row, frames, strict=True):
            heading = result.root_pos[c, min(f + 3, T - 1)] - result.root_pos[c, max(f - 3, 0)]
            heading[1] = 0.0
            norm = float(np.linalg.norm(heading))
            along = heading / norm if norm > 1e-6 else np.array([1.0, 0.0, 0.0])
            xy = np.stack([pos[f] @ along, pos[f, :, 1]], axis=-1)
            draw_pose(ax, xy, skeleton.parents, colors, lw=1.6)
            for k, j in enumerate(skeleton.foot_joints):
                if result.contacts[c, f, k]:
                    ax.plot(*xy[j], "o", color="#d62728", ms=4)
            ground = float(result.path[c, f, 1])
            ax.axhline(ground, color="#888", lw=1)
            ax.set_xlim(xy[0, 0] - half, xy[0, 0] + half)
            ax.set_ylim(ground - 0.1 * size, ground + 1.1 * size)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"#{c} {f / fps:.1f}s {hubs[int(result.gait[c, f])]} h={result.scales[c]:.2f}",
                         fontsize=7)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out
