"""A procedural low-poly skinned mesh for any quadruped skeleton, bound in a standing pose.

Body, neck, head, limbs and tail are tubes swept along the skeleton's bones; ears are cones on
the head. Radii come from the skeleton's own proportions (the fore limb's length sets the scale,
so a horse, a dog and a skeleton read from BVH all get a body that fits their legs). Each ring of
a tube is skinned to the joints that rotate the bones near it, blended smoothly across every
joint (at most two influences per vertex from a tube, normalized).

Which chain is what is read from the tree, not from joint names: the limbs are the feet's chains
(:meth:`Skeleton.limb_chain`), the body runs between the joints the hind and fore limbs branch
from, the head is the chain leaving the fore branch that reaches furthest forward, the tail the
one leaving the hind branch that reaches furthest back. Other chains that end in more than one
bone get a thin tube; single end-site bones (a withers tip) get none.

The mesh is made on, and bound to, a standing pose: the rest pose (every local rotation the
identity) where it stands, as the built-in animals' does; otherwise (a BVH rig whose zero pose
lies along +X) a standing frame of the library, its idle clip's first, given as local
rotations. Either way the pose is turned to face +Z and lifted so its lowest joint is at y = 0.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from synth_core.motion.skeleton import Skeleton

Floats = NDArray[np.float64]

MAX_INFLUENCES = 4  # glTF's JOINTS_0 / WEIGHTS_0 hold four per vertex


@dataclass(frozen=True, eq=False)
class SkinnedMesh:
    positions: NDArray[np.float32]  # (V, 3) bind pose, metres
    normals: NDArray[np.float32]  # (V, 3) unit
    triangles: NDArray[np.uint32]  # (T, 3) counter-clockwise seen from outside
    joints: NDArray[np.uint16]  # (V, 4) joint indices (the skeleton's order)
    weights: NDArray[np.float32]  # (V, 4) sums to 1; unused slots 0
    bind_pos: NDArray[np.float32]  # (J, 3) each joint's world position in the bind pose
    bind_rot: NDArray[np.float32]  # (J, 4) each joint's world rotation in the bind pose
    bind_local: NDArray[np.float32]  # (J, 4) the bind pose's local rotations (joint 0: world)


@dataclass(frozen=True)
class _Part:
    """One closed surface: positions, triangles, and per-vertex weights over all joints."""

    positions: Floats  # (V, 3)
    triangles: NDArray[np.int64]  # (T, 3)
    weights: Floats  # (V, J)


@dataclass(frozen=True)
class _Frame:
    forward: Floats  # (3,) level, from the hind limbs' roots to the fore limbs'
    up: Floats  # (3,) world +Y
    lateral: Floats  # (3,) towards the left limbs
    scale: float  # mean fore limb length, metres: every radius is a fraction of it


def rest_world_positions(skeleton: Skeleton) -> Floats:
    """(J, 3) joint positions in the rest pose, the root lifted so the lowest joint is at y = 0."""
    world = np.zeros((skeleton.n_joints, 3))
    for j in range(1, skeleton.n_joints):  # joints (tens), in parent order
        world[j] = world[skeleton.parents[j]] + skeleton.offsets[j]
    world[:, 1] -= world[:, 1].min()
    return world


def rest_stands(skeleton: Skeleton) -> bool:
    """Whether the rest pose is a standing pose: every foot at the bottom, well below its limb's
    root (a zero pose along +X, as the MANN dog's, is not)."""
    rest = rest_world_positions(skeleton)
    for foot in skeleton.feet:
        limb = skeleton.limb_chain(foot.end_effector)
        drop = rest[limb[0], 1] - rest[foot.end_effector, 1]
        length = _chain_length(rest, limb)
        if rest[foot.end_effector, 1] > 0.05 * length or drop < 0.5 * length:
            return False
    return True


def bind_pose(skeleton: Skeleton, local: NDArray[np.floating] | None = None
              ) -> tuple[Floats, Floats, Floats]:
    """World positions (J, 3), world rotations (J, 4) and local rotations (J, 4) of the pose the
    mesh is made on: ``local`` rotations (default the rest pose) turned about +Y to face +Z and
    lifted so the lowest joint is at y = 0."""
    from synth_core.motion import quat
    from synth_core.motion.skeleton import forward_kinematics

    local = quat.identity((skeleton.n_joints,), np.float64) if local is None else np.array(local, np.float64)
    pos, _ = forward_kinematics(skeleton, np.zeros(3), local)
    if skeleton.feet:
        tops = pos[[skeleton.limb_chain(f.end_effector)[0] for f in skeleton.feet]]
        heading = (tops[:2].mean(0) - tops[2:].mean(0)) * [1.0, 0.0, 1.0]
        if np.linalg.norm(heading) > 1e-9:
            yaw = np.arctan2(heading[0], heading[2])
            local[0] = quat.mul(quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), -yaw), local[0])
    world, rot = forward_kinematics(skeleton, np.zeros(3), local)
    lifted: Floats = np.asarray(world, np.float64)
    lifted[:, 1] -= lifted[:, 1].min()
    return lifted, np.asarray(rot, np.float64), np.asarray(local, np.float64)


def _unit(v: Floats, fallback: Floats) -> Floats:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-9 else fallback


def _chain_length(rest: Floats, chain: tuple[int, ...]) -> float:
    return float(np.linalg.norm(np.diff(rest[list(chain)], axis=0), axis=1).sum())


def _frame(skeleton: Skeleton, rest: Floats) -> _Frame:
    limbs = [skeleton.limb_chain(f.end_effector) for f in skeleton.feet]
    tops = np.array([rest[c[0]] for c in limbs])  # LF, RF, LH, RH limb roots
    # Level (the rest pose stands on the ground): soles flat, the body's belly straight down.
    forward = _unit((tops[:2].mean(0) - tops[2:].mean(0)) * [1.0, 0.0, 1.0], np.array([0.0, 0.0, 1.0]))
    up = np.array([0.0, 1.0, 0.0])
    side = tops[[0, 2]].mean(0) - tops[[1, 3]].mean(0)
    side -= (side @ forward) * forward + (side @ up) * up
    lateral = _unit(side, np.cross(up, forward))
    scale = (_chain_length(rest, limbs[0]) + _chain_length(rest, limbs[1])) / 2
    return _Frame(forward, up, lateral, max(scale, 1e-3))


def _path(skeleton: Skeleton, a: int, b: int) -> list[int]:
    """Joints on the tree path from ``a`` to ``b``."""
    def up_from(j: int) -> list[int]:
        out = [j]
        while skeleton.parents[out[-1]] >= 0:
            out.append(int(skeleton.parents[out[-1]]))
        return out
    ua, ub = up_from(a), up_from(b)
    common = next(j for j in ua if j in ub)
    return ua[:ua.index(common) + 1] + list(reversed(ub[:ub.index(common)]))


def _leaves_below(skeleton: Skeleton, j: int) -> list[int]:
    below = [j]
    for k in range(j + 1, skeleton.n_joints):  # parents come first
        if skeleton.parents[k] in below:
            below.append(k)
    return [k for k in below if not skeleton.children(k)]


def _smoothstep(x: Floats) -> Floats:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _ring_stations(points: Floats, spacing: float) -> tuple[Floats, Floats, Floats, Floats]:
    """Stations along a polyline: arclength s (K,), positions (K, 3), tangents (K, 3), segment
    lengths (S,). Zero-length segments must be removed before."""
    seg = np.diff(points, axis=0)
    lengths = np.linalg.norm(seg, axis=1)
    dirs = seg / lengths[:, None]
    starts = np.concatenate([[0.0], np.cumsum(lengths)])
    counts = np.maximum(1, np.ceil(lengths / spacing).astype(int))
    s = np.concatenate([np.linspace(starts[k], starts[k + 1], counts[k], endpoint=False)
                        for k in range(len(lengths))] + [starts[-1:]])
    k = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(lengths) - 1)
    pos = points[k] + dirs[k] * (s - starts[k])[:, None]
    # At a joint the ring faces the mean of the two bones' directions (less pinching at bends).
    tangent = dirs[k].copy()
    at_joint = np.isin(s, starts[1:-1])
    tangent[at_joint] = dirs[k[at_joint]] + dirs[k[at_joint] - 1]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return s, pos, tangent, lengths


def _chain_weights(s: Floats, lengths: Floats, owners: list[int], n_joints: int) -> Floats:
    """(K, J) weights along a polyline whose segment k is moved by joint ``owners[k]``: each
    segment's joint fully in its middle, blended with the next one's over +-30% of the shorter
    bone around the joint between them (smoothstep, so the ramps sum to 1)."""
    starts = np.concatenate([[0.0], np.cumsum(lengths)])
    half = 0.3 * np.minimum(lengths[:-1], lengths[1:])
    ramps = [_smoothstep((s - (starts[i + 1] - half[i])) / (2 * half[i])) for i in range(len(half))]
    weights = np.zeros((len(s), n_joints))
    for k, owner in enumerate(owners):  # segments of one chain (a handful)
        w = np.ones_like(s)
        if k > 0:
            w *= ramps[k - 1]
        if k < len(owners) - 1:
            w *= 1.0 - ramps[k]
        weights[:, owner] += w
    return weights


def _tube(centres: Floats, tangents: Floats, radii: Floats, ref: Floats, alt_ref: Floats,
          weights: Floats, sides: int, caps: tuple[float, float]) -> _Part:
    """A closed tube: rings of ``sides`` vertices around ``centres`` (K, 3) facing ``tangents``,
    elliptical with ``radii`` (K, 2) = (across ``ref``, across the other axis), a pole vertex
    beyond each end ``caps`` metres out. ``ref`` orients the rings (``alt_ref`` where the tube
    runs along ``ref``)."""
    side = ref - (tangents @ ref)[:, None] * tangents
    weak = np.linalg.norm(side, axis=1) < 0.3
    side[weak] = alt_ref - (tangents[weak] @ alt_ref)[:, None] * tangents[weak]
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    normal = np.cross(side, tangents)  # (tangent, normal, side) right-handed
    theta = 2 * np.pi * np.arange(sides) / sides
    rings = (centres[:, None] + radii[:, None, :1] * np.cos(theta)[None, :, None] * side[:, None]
             + radii[:, None, 1:] * np.sin(theta)[None, :, None] * normal[:, None])
    K = len(centres)
    poles = np.stack([centres[0] - caps[0] * tangents[0], centres[-1] + caps[1] * tangents[-1]])
    positions = np.concatenate([rings.reshape(-1, 3), poles])
    ring = np.arange(K - 1)[:, None] * sides
    i, n = np.arange(sides)[None], (np.arange(sides)[None] + 1) % sides
    a, b, c, d = ring + i, ring + sides + i, ring + n, ring + sides + n
    quads = np.concatenate([np.stack([a, b, c], -1), np.stack([b, d, c], -1)], axis=1).reshape(-1, 3)
    first, last = K * sides, K * sides + 1
    ends = np.arange(sides)
    cap0 = np.stack([np.full(sides, first), ends, (ends + 1) % sides], -1)
    cap1 = np.stack([np.full(sides, last), (K - 1) * sides + (ends + 1) % sides, (K - 1) * sides + ends], -1)
    vertex_weights = np.concatenate([np.repeat(weights, sides, axis=0), weights[[0, -1]]])
    return _Part(positions, np.concatenate([quads, cap0, cap1]), vertex_weights)


@dataclass(frozen=True)
class _Chain:
    points: Floats  # (P, 3) polyline, no zero-length segments
    owners: list[int]  # (P - 1) joint moving each segment


def _chain(rest: Floats, joints: list[int], skeleton: Skeleton) -> _Chain:
    """The polyline through ``joints`` (each the parent or child of the next), segments owned by
    the joint that rotates them (the upper end's, in the direction of the tree)."""
    points, owners = [rest[joints[0]]], []
    for a, b in zip(joints[:-1], joints[1:], strict=True):
        if np.linalg.norm(rest[b] - points[-1]) < 1e-6:
            continue
        points.append(rest[b])
        owners.append(a if skeleton.parents[b] == a else b)
    return _Chain(np.array(points), owners)


@dataclass(frozen=True)
class _Rig:
    """What every part is made against: the skeleton, its bind-pose joint positions ``rest``
    (J, 3), the body's frame and the spacing of a tube's rings."""

    skeleton: Skeleton
    rest: Floats
    frame: _Frame
    spacing: float


def _sweep(rig: _Rig, chain: _Chain, radius: Floats | float, profile: object, sides: int,
           lead_in: int | None = None, caps: tuple[float, float] | None = None,
           sole: bool = False) -> _Part | None:
    """A tube along ``chain`` with radius ``profile(a) * radius`` at fraction ``a`` of its length
    (``profile`` a callable on arrays). ``lead_in``: a joint whose bone ends where the chain
    starts, blended into the first ring (a limb's top moves half with the body). ``sole``: the
    last ring is a hoof's or paw's sole, level, and behind the chain's end (the toe): a foot
    planted on its toe rolls over it without its sole sinking into the ground."""
    if len(chain.owners) == 0:
        return None
    skeleton, frame = rig.skeleton, rig.frame
    s, centres, tangents, lengths = _ring_stations(chain.points, rig.spacing)
    if sole:
        tangents[-1] = -frame.up
    owners = chain.owners
    if lead_in is not None:  # a virtual bone before the chain, as long as its first bone
        s, lengths, owners = s + lengths[0], np.concatenate([lengths[:1], lengths]), [lead_in, *owners]
    weights = _chain_weights(s, lengths, owners, skeleton.n_joints)
    a = (s - s[0]) / max(s[-1] - s[0], 1e-9)
    r = np.asarray(profile(a)) * radius  # type: ignore[operator]
    r2 = np.stack([r, r], -1) if r.ndim == 1 else r
    if sole:
        centres[-1] -= 0.8 * r2[-1, 0] * frame.forward
    end_caps = caps if caps is not None else (0.5 * float(r2[0].min()), 0.5 * float(r2[-1].min()))
    return _tube(centres, tangents, r2, frame.lateral, frame.up, weights, sides, end_caps)


def _ear(skeleton: Skeleton, frame: _Frame, base: Floats, direction: Floats, length: float,
         owner: int) -> _Part:
    stations = base + np.outer([0.0, 0.35, 1.0], direction) * length
    radii = length * np.array([0.22, 0.2, 0.03])
    weights = np.zeros((3, skeleton.n_joints))
    weights[:, owner] = 1.0
    return _tube(stations, np.repeat(direction[None], 3, 0), np.stack([radii, 0.55 * radii], -1),
                 frame.forward, frame.up, weights, 6, (0.0, 0.01 * length))


def _parts(skeleton: Skeleton, rest: Floats) -> list[_Part]:
    """The surfaces around the joints at ``rest`` (J, 3), the bind pose's world positions."""
    frame = _frame(skeleton, rest)
    rig = _Rig(skeleton, rest, frame, 0.045 * frame.scale)
    limbs = [skeleton.limb_chain(f.end_effector) for f in skeleton.feet]
    fore, hind = int(skeleton.parents[limbs[0][0]]), int(skeleton.parents[limbs[2][0]])
    spine = _path(skeleton, hind, fore)
    used = set(spine) | {j for c in limbs for j in c}
    rv = 0.2 * frame.scale  # the body's radius
    parts: list[_Part | None] = [_body(rig, spine, limbs, fore, hind, rv), *_limbs(rig, limbs)]

    head_path = _reach(rig, used, fore, 1.0)
    if head_path is not None and len(head_path) >= 3:
        used |= set(head_path)
        parts += _head(rig, head_path, fore, rv)

    tail_path = _reach(rig, used, hind, -1.0)
    if tail_path is not None and len(tail_path) >= 2:
        used |= set(tail_path)
        parts.append(_sweep(rig, _chain(rest, tail_path[1:], skeleton), rv,
                            lambda x: 0.16 - 0.09 * x, 8, lead_in=hind))

    # Any other chain of two bones or more (ears or a jaw in a skeleton that has them).
    for j in range(1, skeleton.n_joints):
        if j in used or skeleton.parents[j] not in used:
            continue
        for leaf in _leaves_below(skeleton, j):
            path = _path(skeleton, int(skeleton.parents[j]), leaf)
            used |= set(path)
            if len(path) >= 3:
                length = _chain_length(rest, tuple(path))
                parts.append(_sweep(rig, _chain(rest, path, skeleton), min(0.12 * length, 0.1 * rv),
                                    lambda x: 1.0 - 0.5 * x, 8))
    return [p for p in parts if p is not None]


def _body(rig: _Rig, spine: list[int], limbs: list[tuple[int, ...]], fore: int, hind: int,
          rv: float) -> _Part:
    """Along the spine, reaching past both branch joints; below the spine more than above."""
    skeleton, rest, frame = rig.skeleton, rig.rest, rig.frame
    body = _chain(rest, spine, skeleton)
    # To the limbs' roots where they sit beyond the branch joints (a rig whose shoulders hang
    # from the middle of the back, as the MANN dog's, still gets a chest), then a little beyond.
    roots = np.array([rest[c[0]] for c in limbs])
    ahead = max(0.0, float((roots[:2].mean(0) - rest[fore]) @ frame.forward))
    behind = max(0.0, float((rest[hind] - roots[2:].mean(0)) @ frame.forward))
    ends = [rest[hind] - (behind + 0.9 * rv) * frame.forward,
            rest[fore] + (ahead + 0.85 * rv) * frame.forward]
    owners = body.owners or [fore]
    body = _Chain(np.vstack([ends[0], body.points, ends[1]]), [owners[0], *owners, fore])
    s, centres, tangents, lengths = _ring_stations(body.points, rig.spacing)
    a = s / s[-1]
    fill = np.maximum(1.0 - np.abs(2 * a - 1) ** 2.5, 0.0) ** 0.45 * 0.8 + 0.2
    centres = centres - np.outer(0.67 * rv * fill, frame.up)
    weights = _chain_weights(s, lengths, body.owners, skeleton.n_joints)
    return _tube(centres, tangents, np.stack([0.85 * rv * fill, rv * fill], -1), frame.lateral,
                 frame.up, weights, 20, (0.25 * rv, 0.25 * rv))


def _limbs(rig: _Rig, limbs: list[tuple[int, ...]]) -> list[_Part | None]:
    """Thick at the top (shoulder, thigh), slender below, the hoof or paw a little wider."""
    skeleton, rest, S = rig.skeleton, rig.rest, rig.frame.scale
    parts = []
    for i, limb in enumerate(limbs):
        top = 0.06 if i < 2 else 0.09
        power = 1.5 if i < 2 else 2.0
        n_last = _chain_length(rest, limb[-2:]) / max(_chain_length(rest, limb), 1e-9)

        def limb_profile(x: Floats, top: float = top, power: float = power, n_last: float = n_last) -> Floats:
            hoof = 1.0 + 0.45 * _smoothstep((x - (1 - n_last)) / max(n_last, 1e-3))
            return (0.02 + top * (1 - x) ** power) * hoof
        top_cap = 0.15 * S * (0.02 + top)  # flat: a round cap pokes out of the back at the withers
        parts.append(_sweep(rig, _chain(rest, list(limb), skeleton), S, limb_profile, 12,
                            lead_in=int(skeleton.parents[limb[0]]), caps=(top_cap, 0.0), sole=True))
    return parts


def _reach(rig: _Rig, used: set[int], branch: int, sign: float) -> list[int] | None:
    """The path from ``branch`` to the leaf furthest along ``sign * forward`` below its
    children off the body and limbs (``used``)."""
    skeleton, rest = rig.skeleton, rig.rest
    leaves = [leaf for c in skeleton.children(branch) if c not in used
              for leaf in _leaves_below(skeleton, c)]
    if not leaves:
        return None
    best = max(leaves, key=lambda j: sign * float((rest[j] - rest[branch]) @ rig.frame.forward))
    return _path(skeleton, branch, best)


def _head(rig: _Rig, head_path: list[int], fore: int, rv: float) -> list[_Part | None]:
    """Neck, skull and ears along ``head_path`` (from the fore branch joint to the head's tip)."""
    skeleton, rest, frame = rig.skeleton, rig.rest, rig.frame
    head_len = float(np.linalg.norm(rest[head_path[-1]] - rest[head_path[-2]]))
    rh = 0.22 * head_len
    # From the first neck joint (the body's front covers the bone up to it; a tube from the
    # branch joint pokes its end out of the back), its base moving half with the body.
    short = len(head_path) >= 4
    neck = _chain(rest, head_path[1:-1] if short else head_path[:-1], skeleton)
    parts = [_sweep(rig, neck, 1.0, lambda x: 0.55 * rv + (rh - 0.55 * rv) * x, 14,
                    lead_in=fore if short else None)]
    skull = _chain(rest, head_path[-2:], skeleton)
    parts.append(_sweep(rig, skull, rh,
                        lambda x: 1.0 + 0.15 * np.sin(np.pi * np.minimum(x / 0.5, 1.0)) - 0.45 * x,
                        12, caps=(0.6 * rh, 0.4 * rh)))
    owner, head = head_path[-2], rest[head_path[-2]]
    for sign in (1.0, -1.0):
        base = head + frame.up * 0.75 * rh + frame.lateral * sign * 0.45 * rh
        direction = _unit(frame.up - 0.3 * frame.forward + 0.3 * sign * frame.lateral, frame.up)
        parts.append(_ear(skeleton, frame, base, direction, 0.3 * head_len, owner))
    return parts


def _vertex_normals(positions: Floats, triangles: NDArray[np.int64]) -> Floats:
    """Area-weighted mean of the faces around each vertex."""
    p = positions[triangles]
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    normals = np.zeros_like(positions)
    for corner in range(3):
        np.add.at(normals, triangles[:, corner], face)
    return np.asarray(normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12), np.float64)


def _top_influences(weights: Floats) -> tuple[NDArray[np.uint16], NDArray[np.float32]]:
    """The four largest weights per vertex, renormalized; unused slots weight 0 on joint 0."""
    order = np.argsort(-weights, axis=1, kind="stable")[:, :MAX_INFLUENCES]
    top = np.take_along_axis(weights, order, axis=1)
    top = np.where(top > 1e-4, top, 0.0)
    top /= top.sum(axis=1, keepdims=True)
    joints = np.where(top > 0, order, 0)
    return joints.astype(np.uint16), top.astype(np.float32)


def build_mesh(skeleton: Skeleton, bind_local: NDArray[np.floating] | None = None) -> SkinnedMesh:
    """The procedural skinned mesh of ``skeleton`` made on :func:`bind_pose` of ``bind_local``
    (local rotations (J, 4); default: the rest pose, which must then stand)."""
    if not skeleton.feet:
        raise ValueError(f"skeleton {skeleton.name!r}: a mesh needs the four feet declared")
    key = None if bind_local is None else np.asarray(bind_local, np.float32).tobytes()
    return _build_mesh(skeleton, key)


@functools.lru_cache(maxsize=16)  # per skeleton (identity) and bind pose: made once per library
def _build_mesh(skeleton: Skeleton, bind_key: bytes | None) -> SkinnedMesh:
    local = None if bind_key is None else np.frombuffer(bind_key, np.float32).reshape(-1, 4)
    pos, rot, local_rot = bind_pose(skeleton, local)
    parts = _parts(skeleton, pos)
    starts = np.cumsum([0] + [len(p.positions) for p in parts])
    positions = np.concatenate([p.positions for p in parts])
    triangles = np.concatenate([p.triangles + s for p, s in zip(parts, starts, strict=False)])
    normals = np.concatenate([_vertex_normals(p.positions, p.triangles) for p in parts])
    joints, weights = _top_influences(np.concatenate([p.weights for p in parts]))
    return SkinnedMesh(positions.astype(np.float32), normals.astype(np.float32),
                       triangles.astype(np.uint32), joints, weights, pos.astype(np.float32),
                       rot.astype(np.float32), local_rot.astype(np.float32))


def standing_rotations(skeleton: Skeleton, standing: NDArray[np.floating]) -> NDArray[np.float32] | None:
    """The bind pose for a library: None (its rest pose) where the rest pose stands, else
    ``standing`` (local rotations (J, 4) of a standing frame, e.g. its idle clip's first)."""
    return None if rest_stands(skeleton) else np.asarray(standing, np.float32)


def pose_mesh(mesh: SkinnedMesh, world_pos: NDArray[np.floating], world_rot: NDArray[np.floating],
              scale: float = 1.0) -> NDArray[np.float64]:
    """(V, 3) vertices of ``mesh`` skinned to one pose (linear blend skinning, as a glTF viewer
    does): ``world_pos (J, 3)`` and ``world_rot (J, 4)`` from :func:`forward_kinematics` of a
    character of ``scale`` (its bones ``scale`` times as long, so its mesh is too)."""
    from synth_core.motion import quat

    bound = quat.rotate(quat.inv(mesh.bind_rot[mesh.joints]),
                        mesh.positions[:, None, :] - mesh.bind_pos[mesh.joints])  # (V, 4, 3) joint space
    moved = (quat.rotate(np.asarray(world_rot)[mesh.joints], scale * bound)
             + np.asarray(world_pos)[mesh.joints])
    return np.asarray(np.einsum("vk,vkc->vc", mesh.weights.astype(np.float64), moved), np.float64)
