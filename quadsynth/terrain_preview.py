"""Pictures of characters on a terrain (issue 33): side views with the ground's profile under
them, planted feet marked, for looking at before claiming feet stand on the ground.

``python -m quadsynth.terrain_preview OUT.png [SCENARIO ...]`` renders edge-suite terrain
scenarios (default: slope_up_30, slope_down_30, rolling_hills, step_20cm) of the horse, a row
each: its walking and trotting characters at a few frames."""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from quadsynth.preview import BODY, LEFT, PLANT, RIGHT, draw_pose  # noqa: E402
from synth_core.motion.skeleton import Skeleton  # noqa: E402
from synth_core.runtime.terrain import HeightField  # noqa: E402

DEFAULT = ("slope_up_30", "slope_down_30", "rolling_hills", "step_20cm")


def side_panel(ax: Axes, pos: NDArray[np.floating], contacts: NDArray[np.bool_], sk: Skeleton,
               colors: list[str], field: HeightField, title: str, front: bool = False) -> None:
    """One pose ``pos (J, 3)`` of ``sk`` seen from its side (``front``: from behind, looking
    along its heading), on the ground's profile through its root."""
    feet, parents = sk.foot_joints, sk.parents
    fwd = pos[feet[:2]].mean(axis=0) - pos[feet[2:]].mean(axis=0)
    fwd[1] = 0.0
    fwd /= max(float(np.linalg.norm(fwd)), 1e-9)
    if front:
        fwd = np.array([fwd[2], 0.0, -fwd[0]])  # the view's horizontal axis: across the body
    centre = pos[0]
    along = (pos - centre) @ fwd
    xy = np.stack([along, pos[:, 1]], axis=-1)
    s = np.linspace(-2.0, 2.0, 200)
    ground = field.sample(centre[0] + s * fwd[0], centre[2] + s * fwd[2])
    ax.fill_between(s, ground, ground.min() - 0.3, color="#d8cfc0", lw=0)
    ax.plot(s, ground, color="#7a6a55", lw=1.2)
    draw_pose(ax, xy, parents, colors)
    for k, j in enumerate(feet):
        if contacts[k]:
            ax.plot(*xy[j], "o", color=PLANT, ms=5, zorder=5)
    ax.set_xlim(-1.8, 1.8)
    ax.set_ylim(float(ground.min()) - 0.2, float(ground.min()) + 3.0)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=8)


def render(out: str | Path, names: tuple[str, ...] = DEFAULT, panels: int = 5) -> None:
    from synth_core.build.animals import build_builtin
    from synth_core.quality.edge import Scenario
    from synth_core.quality.evaluate import edge_suite, world_positions
    from synth_core.runtime.bank import build_bank
    from synth_core.runtime.synthesis import Result

    bank = build_bank(build_builtin("horse"))
    keep: dict[str, tuple[Scenario, Result]] = {}
    edge_suite(bank, names=list(names), keep=keep)
    sk = bank.skeleton
    colors = [BODY] * sk.n_joints
    for foot in sk.feet:
        for j in foot.chain:
            colors[j] = LEFT if foot.name[0] == "L" else RIGHT
    rows = [(name, c) for name in names for c in (0, 1)]
    fig, axes = plt.subplots(len(rows), panels, figsize=(2.6 * panels, 2.3 * len(rows)), squeeze=False)
    for row, (name, c) in enumerate(rows):
        sc, result = keep[name]
        assert sc.ground is not None
        pos = np.asarray(world_positions(bank, result), np.float64)[c]
        T = pos.shape[0]
        gait = ("walk", "trot", "canter")[c]
        for k, f in enumerate(np.linspace(T * 0.35, T * 0.9, panels).astype(int)):
            front = "across" in name and k % 2 == 1
            side_panel(axes[row, k], pos[f], result.contacts[c, f], sk, colors,
                       sc.ground, f"{name} {gait} frame {f}" + (" (from behind)" if front else ""), front)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    render(sys.argv[1], tuple(sys.argv[2:]) or DEFAULT)
