"""glTF 2.0 binaries (.glb) of skinned animals: a library's mesh in its rest pose, and a herd
with one skinned mesh per character and one animation moving them all.

glTF is Y up, metres, quaternions xyzw: our layout, written as it is. Every character is a joint
node hierarchy (a node per skeleton joint, the skeleton's order) plus a mesh node at the scene's
root holding the shared mesh (:mod:`synth_core.export.mesh`) and the character's own skin. A
character of scale h has bones h times as long; its skin's inverse bind matrices scale the
shared mesh by h too (``scale(h) @ inverse(bind[j])``), so one mesh serves the herd.

A herd is ONE animation (named ``herd``): every character shares the timeline, so an engine
plays the herd as a whole with one clip; per-character animations would have to be started
together by hand to keep the herd in step. Gaits and foot contacts ride in each mesh node's
``extras`` (:mod:`synth_core.export.annotations`); see docs/gltf.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pygltflib as G
from numpy.typing import NDArray

from synth_core import FOOT_NAMES
from synth_core.build.motion_graph import HUBS
from synth_core.export.annotations import character_annotations
from synth_core.export.mesh import SkinnedMesh, build_mesh
from synth_core.motion import quat
from synth_core.motion.skeleton import Skeleton
from synth_core.runtime.synthesis import Result

_FLOAT, _USHORT, _UINT = 5126, 5123, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_COMPONENT = {np.dtype("<f4"): _FLOAT, np.dtype("<u2"): _USHORT, np.dtype("<u4"): _UINT}
COAT = [0.55, 0.38, 0.24, 1.0]  # a bay horse's brown; the viewer may tint it per gait


class _Builder:
    """A glTF document and its binary chunk, filled a view and an accessor at a time."""

    def __init__(self) -> None:
        self.gltf = G.GLTF2(asset=G.Asset(generator="QuadSynth", version="2.0"))
        self.gltf.buffers.append(G.Buffer())
        self.blob = bytearray()

    def view(self, data: NDArray[np.generic], target: int | None = None) -> int:
        while len(self.blob) % 4:
            self.blob.append(0)
        self.gltf.bufferViews.append(G.BufferView(buffer=0, byteOffset=len(self.blob),
                                                  byteLength=data.nbytes, target=target))
        self.blob.extend(np.ascontiguousarray(data).tobytes())
        return len(self.gltf.bufferViews) - 1

    def accessor(self, view: int, count: int, kind: str, dtype: str = "<f4", offset: int = 0,
                 lo: list[float] | None = None, hi: list[float] | None = None) -> int:
        self.gltf.accessors.append(G.Accessor(bufferView=view, byteOffset=offset, count=count, type=kind,
                                              componentType=_COMPONENT[np.dtype(dtype)], min=lo, max=hi))
        return len(self.gltf.accessors) - 1

    def array(self, data: NDArray[np.generic], kind: str, target: int | None = None,
              bounds: bool = False) -> int:
        """``data`` (N, k) or (N,) in a view of its own, as one accessor."""
        flat = data.reshape(len(data), -1)
        lo = flat.min(0).tolist() if bounds else None
        hi = flat.max(0).tolist() if bounds else None
        return self.accessor(self.view(data, target), len(data), kind, data.dtype.str, 0, lo, hi)

    def glb(self) -> bytes:
        self.gltf.buffers[0].byteLength = len(self.blob)
        self.gltf.set_binary_blob(bytes(self.blob))
        return bytes(b"".join(self.gltf.save_to_bytes()))


def _add_mesh(b: _Builder, mesh: SkinnedMesh, name: str) -> int:
    index_type = "<u2" if len(mesh.positions) < 65536 else "<u4"
    attributes = G.Attributes(
        POSITION=b.array(mesh.positions.astype("<f4"), "VEC3", _ARRAY_BUFFER, bounds=True),
        NORMAL=b.array(mesh.normals.astype("<f4"), "VEC3", _ARRAY_BUFFER),
        JOINTS_0=b.array(mesh.joints.astype("<u2"), "VEC4", _ARRAY_BUFFER),
        WEIGHTS_0=b.array(mesh.weights.astype("<f4"), "VEC4", _ARRAY_BUFFER))
    indices = b.array(mesh.triangles.reshape(-1).astype(index_type), "SCALAR", _ELEMENT_ARRAY_BUFFER)
    b.gltf.materials.append(G.Material(name=f"{name} coat", pbrMetallicRoughness=G.PbrMetallicRoughness(
        baseColorFactor=COAT, metallicFactor=0.0, roughnessFactor=0.85)))
    b.gltf.meshes.append(G.Mesh(name=name, primitives=[G.Primitive(
        attributes=attributes, indices=indices, material=len(b.gltf.materials) - 1)]))
    return len(b.gltf.meshes) - 1


def inverse_bind_matrices(mesh: SkinnedMesh, scale: float) -> NDArray[np.float32]:
    """(J, 16) column-major ``scale(h) @ inverse(bind[j])``, bind[j] joint j's world transform in
    the mesh's bind pose (rotation R, position p): ``[h R^T | -h R^T p]``."""
    r = quat.to_matrix(mesh.bind_rot.astype(np.float64)).transpose(0, 2, 1)  # R^T
    m = np.zeros((len(r), 4, 4))
    m[:, :3, :3] = scale * r
    m[:, :3, 3] = -scale * np.einsum("jab,jb->ja", r, mesh.bind_pos.astype(np.float64))
    m[:, 3, 3] = 1.0
    return m.transpose(0, 2, 1).reshape(-1, 16).astype("<f4")


@dataclass(frozen=True)
class _Model:
    """The mesh, added to the file once (``mesh_index``), and the skeleton it is bound to."""

    skeleton: Skeleton
    mesh: SkinnedMesh
    mesh_index: int


def _add_character(b: _Builder, model: _Model, scale: float, name: str, prefix: str, root: list[float],
                   posed: bool) -> tuple[int, int]:
    """A character's joint nodes, its mesh node and the node its joints hang from (no
    transform), in that order; returns (that rig node, mesh node).
    ``posed``: the nodes hold the bind pose's rotations (else none: the animation sets them)."""
    skeleton, mesh, mesh_index = model.skeleton, model.mesh, model.mesh_index
    first = len(b.gltf.nodes)
    for j in range(skeleton.n_joints):
        children = [first + k for k in np.flatnonzero(skeleton.parents == j)]
        offset = root if j == 0 else [float(v) * scale for v in skeleton.offsets[j]]
        turned = posed and not np.allclose(mesh.bind_local[j], [0, 0, 0, 1], atol=1e-7)
        unit = mesh.bind_local[j] / np.linalg.norm(mesh.bind_local[j])
        rotation = [float(v) for v in unit] if turned else None
        b.gltf.nodes.append(G.Node(name=prefix + skeleton.names[j], translation=offset, rotation=rotation,
                                   children=[int(k) for k in children] or None))
    ibm = b.array(inverse_bind_matrices(mesh, scale), "MAT4")
    b.gltf.skins.append(G.Skin(name=name, joints=list(range(first, first + skeleton.n_joints)),
                               skeleton=first, inverseBindMatrices=ibm))
    b.gltf.nodes.append(G.Node(name=name, mesh=mesh_index, skin=len(b.gltf.skins) - 1))
    # The joints hang from a node of their own: Blender's importer makes an armature of the
    # parent of a skin's root joint, and of a scene root all skins' joints would share one.
    b.gltf.nodes.append(G.Node(name=f"{name}_rig", children=[first]))
    return len(b.gltf.nodes) - 1, len(b.gltf.nodes) - 2


def mesh_glb(skeleton: Skeleton, animal: str, bind_local: NDArray[np.floating] | None = None) -> bytes:
    """The library's mesh (:func:`build_mesh`) bound to its skeleton, standing on y = 0: joint
    nodes named as the skeleton's joints, in its order, with the skeleton's rest offsets and the
    bind pose's rotations (none where the rest pose is the bind pose)."""
    b = _Builder()
    mesh = build_mesh(skeleton, bind_local)
    mesh_index = _add_mesh(b, mesh, f"{animal} mesh")
    rig, node = _add_character(b, _Model(skeleton, mesh, mesh_index), 1.0, animal, "",
                               [float(v) for v in mesh.bind_pos[0]], posed=True)
    b.gltf.scenes.append(G.Scene(name=f"{animal} rest pose", nodes=[rig, node]))
    b.gltf.scene = 0
    return b.glb()


def bind_rotations(glb: bytes, n_joints: int) -> NDArray[np.float32]:
    """The bind pose (local rotations (J, 4)) of a :func:`mesh_glb` file: its first J nodes'."""
    gltf = G.GLTF2.load_from_bytes(glb)
    return np.array([n.rotation if n.rotation else [0.0, 0.0, 0.0, 1.0] for n in gltf.nodes[:n_joints]],
                    np.float32)


def write_glb(skeleton: Skeleton, result: Result, ids: list[str], path: str | Path, fps: float,
              bind_local: NDArray[np.floating] | None = None) -> Path:
    """The herd: per character ``<id>_<joint>`` nodes (three.js strips ``:`` and ``.`` from
    node names, so neither separates), a skinned mesh node ``<id>`` whose
    ``extras`` hold its gaits and contacts, and one animation ``herd`` for them all.
    ``bind_local``: the library's bind pose (:func:`synth_core.export.mesh.standing_rotations`)."""
    path = Path(path)
    C, T, J = result.rotations.shape[:3]
    b = _Builder()
    mesh = build_mesh(skeleton, bind_local)
    model = _Model(skeleton, mesh, _add_mesh(b, mesh, f"{skeleton.name or 'animal'} mesh"))
    animation = G.Animation(name="herd", channels=[], samplers=[])
    times = np.arange(T, dtype="<f4") / np.float32(fps)
    time_acc = b.array(times, "SCALAR", bounds=True)
    scene_nodes = []
    for c in range(C):
        rig, node = _add_character(b, model, float(result.scales[c]), str(ids[c]), f"{ids[c]}_",
                                   [float(v) for v in result.root_pos[c, 0]], posed=False)
        b.gltf.nodes[node].extras = character_annotations(result, c, fps, str(ids[c]))
        first = rig - 1 - J
        scene_nodes += [rig, node]
        rot_view = b.view(result.rotations[c].transpose(1, 0, 2).astype("<f4"))  # (J, T, 4): a run per joint
        targets = [(first, "translation", b.array(result.root_pos[c].astype("<f4"), "VEC3"))]
        targets += [(first + j, "rotation", b.accessor(rot_view, T, "VEC4", offset=j * T * 16))
                    for j in range(J)]
        for target_node, prop, acc in targets:
            animation.samplers.append(G.AnimationSampler(input=time_acc, output=acc, interpolation="LINEAR"))
            target = G.AnimationChannelTarget(node=target_node, path=prop)
            animation.channels.append(G.AnimationChannel(sampler=len(animation.samplers) - 1, target=target))
    b.gltf.scenes.append(G.Scene(name="herd", nodes=scene_nodes, extras={
        "fps": fps, "frames": T, "characters": C, "feet": list(FOOT_NAMES), "gaits": list(HUBS),
        "annotations": "each character's mesh node extras: gait and contact ranges [start, stop) "
                       "in frames (docs/gltf.md)"}))
    b.gltf.scene = 0
    b.gltf.animations.append(animation)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b.glb())
    return path
