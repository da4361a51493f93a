"""A herd as one glTF 2.0 binary (.glb): one node hierarchy per character and one animation
moving them all (root translation, every joint's rotation), readable by three.js GLTFLoader and
Blender. glTF is Y up, metres, quaternions xyzw: our layout, written as it is.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pygltflib as G

from synth_core.skeleton import Skeleton
from synth_core.synthesis import Result

_FLOAT = 5126


def _accessor(gltf: G.GLTF2, view: int, offset: int, count: int, kind: str,
              lo: list[float] | None = None, hi: list[float] | None = None) -> int:
    gltf.accessors.append(G.Accessor(bufferView=view, byteOffset=offset, componentType=_FLOAT,
                                     count=count, type=kind, min=lo, max=hi))
    return len(gltf.accessors) - 1


def write_glb(skeleton: Skeleton, result: Result, ids: list[str], path: str | Path, fps: float) -> Path:
    path = Path(path)
    C, T, J = result.rotations.shape[:3]
    blob = bytearray()
    gltf = G.GLTF2(asset=G.Asset(generator="QuadSynth", version="2.0"))
    gltf.buffers.append(G.Buffer())
    animation = G.Animation(name="herd", channels=[], samplers=[])

    def view(data: np.ndarray) -> int:
        while len(blob) % 4:
            blob.append(0)
        gltf.bufferViews.append(G.BufferView(buffer=0, byteOffset=len(blob), byteLength=data.nbytes))
        blob.extend(np.ascontiguousarray(data, dtype="<f4").tobytes())
        return len(gltf.bufferViews) - 1

    times = np.arange(T, dtype=np.float32) / np.float32(fps)
    time_acc = _accessor(gltf, view(times), 0, T, "SCALAR", [float(times[0])], [float(times[-1])])
    roots = []
    for c in range(C):
        h = float(result.scales[c])
        first = len(gltf.nodes)
        for j in range(J):
            children = [first + k for k in range(J) if skeleton.parents[k] == j]
            offset = [0.0, 0.0, 0.0] if j == 0 else [float(v) * h for v in skeleton.offsets[j]]
            name = f"{ids[c]}:{skeleton.names[j]}" if j else str(ids[c])
            gltf.nodes.append(G.Node(name=name, translation=offset, children=children or None))
        roots.append(first)
        rot_view = view(result.rotations[c].transpose(1, 0, 2))  # (J, T, 4): one run per joint
        root_view = view(result.root_pos[c])
        targets = [(first, "translation", _accessor(gltf, root_view, 0, T, "VEC3"))]
        targets += [(first + j, "rotation", _accessor(gltf, rot_view, j * T * 16, T, "VEC4"))
                    for j in range(J)]
        for node, prop, acc in targets:
            animation.samplers.append(G.AnimationSampler(input=time_acc, output=acc, interpolation="LINEAR"))
            target = G.AnimationChannelTarget(node=node, path=prop)
            animation.channels.append(G.AnimationChannel(sampler=len(animation.samplers) - 1, target=target))
    gltf.scenes.append(G.Scene(name="herd", nodes=roots))
    gltf.scene = 0
    gltf.animations.append(animation)
    gltf.buffers[0].byteLength = len(blob)
    gltf.set_binary_blob(bytes(blob))
    path.parent.mkdir(parents=True, exist_ok=True)
    gltf.save_binary(str(path))
    return path
