"""Pictures of a library's skinned mesh: rest pose and poses from its gait clips, shaded
(matplotlib, headless). The mesh is skinned here as a glTF viewer skins it
(:func:`synth_core.export.mesh.pose_mesh`), so what the picture shows is what an engine shows.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless: no display on servers or CI

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from synth_core.build.artifact import Library  # noqa: E402
from synth_core.export.mesh import SkinnedMesh, build_mesh, pose_mesh, standing_rotations  # noqa: E402
from synth_core.motion.skeleton import forward_kinematics  # noqa: E402

LIGHT = np.array([0.4, 0.8, 0.45]) / np.linalg.norm([0.4, 0.8, 0.45])
COLOR = np.array([0.55, 0.38, 0.24])


def _draw(ax: object, mesh: SkinnedMesh, vertices: NDArray[np.float64], title: str, elev: float,
          azim: float) -> None:
    tri = vertices[mesh.triangles.astype(np.int64)]
    face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    face /= np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-12)
    shade = 0.35 + 0.65 * np.clip(face @ LIGHT, 0.0, 1.0)
    # matplotlib is Z up: show glTF's (x, y, z) as (x, z, y), the ground in the picture's floor.
    polys = tri[:, :, [0, 2, 1]]
    lo, hi = polys.reshape(-1, 3).min(0), polys.reshape(-1, 3).max(0)
    lo[2], pad = 0.0, 0.05 * float((hi - lo).max())
    lo, hi = lo - pad, hi + pad
    ground = np.array([[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0], [lo[0], hi[1], 0]])
    # The ground first and the mesh over it: mplot3d's own depth sort puts the big ground quad
    # in front of the hooves.
    ax.computed_zorder = False  # type: ignore[attr-defined]
    ax.add_collection3d(Poly3DCollection([ground], facecolors=(0.85, 0.88, 0.8, 1.0), zorder=0))  # type: ignore[attr-defined]
    ax.add_collection3d(Poly3DCollection(polys, facecolors=np.clip(shade[:, None] * COLOR, 0, 1),  # type: ignore[attr-defined]
                                         edgecolors=(0, 0, 0, 0.08), linewidths=0.2, zorder=1))
    for axis, a, b in zip("xyz", lo, hi, strict=True):
        getattr(ax, f"set_{axis}lim")(a, b)
    ax.set_box_aspect(tuple(hi - lo), zoom=1.3)  # type: ignore[attr-defined]
    ax.view_init(elev=elev, azim=azim)  # type: ignore[attr-defined]
    ax.set_axis_off()  # type: ignore[attr-defined]
    ax.set_title(title, fontsize=10)  # type: ignore[attr-defined]


def render_mesh(library: Library, out: str | Path, gait: str = "gallop") -> Path:
    """A PNG: the mesh in its bind pose (the rest pose where it stands) and at the middle frame
    of ``gait``'s middle clip, each from the side and three-quarters front."""
    skeleton = library.skeleton
    mesh = build_mesh(skeleton, standing_rotations(skeleton, library.idle.rotations[0]))
    rest = mesh.positions.astype(np.float64)
    speed_map = library.maps[gait]
    clip = speed_map.clip(len(speed_map.speeds) // 2)
    f = clip.n_frames // 2
    pos, rot = forward_kinematics(skeleton, clip.root_pos[f], clip.rotations[f])
    posed = pose_mesh(mesh, pos, rot)
    posed[:, [0, 2]] -= pos[0, [0, 2]]  # centred under the root, as the rest pose is
    speed = speed_map.speeds[len(speed_map.speeds) // 2]
    views = [(f"bind pose, side ({len(mesh.triangles)} triangles)", rest, 5.0, 0.0),
             ("bind pose, three-quarters", rest, 20.0, 35.0),
             (f"{gait} {speed:.1f} m/s, frame {f}, side", posed, 5.0, 0.0),
             (f"{gait}, three-quarters", posed, 20.0, 35.0)]
    fig = plt.figure(figsize=(12, 10), dpi=100)
    for i, (title, vertices, elev, azim) in enumerate(views):
        _draw(fig.add_subplot(2, 2, i + 1, projection="3d"), mesh, vertices, title, elev, azim)
    fig.suptitle(f"{library.animal}: procedural skinned mesh (synth_core.export.mesh)")
    fig.tight_layout()
    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
