"""The procedural skinned mesh (synth_core.export.mesh): a closed, outward-facing surface of a few
thousand triangles on any quadruped skeleton, smooth normalized weights, standing on the ground,
and feet that stay on the ground when the skinned mesh plays a gait."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from synth_core.build.animals import build_builtin
from synth_core.builtin import build_skeleton
from synth_core.export.mesh import (
    SkinnedMesh,
    build_mesh,
    pose_mesh,
    rest_stands,
    rest_world_positions,
    standing_rotations,
)
from synth_core.motion.skeleton import Skeleton, forward_kinematics
from tests.helpers.mocap import mann_standing
from tests.helpers.motion import toy_skeleton

Posed = tuple[Skeleton, np.ndarray | None]  # a skeleton and its bind pose (None: the rest pose)


def skeletons() -> dict[str, Skeleton]:
    return {"horse": build_skeleton("horse"), "dog": build_skeleton("dog"), "toy": toy_skeleton()}


@pytest.fixture(params=["horse", "dog", "toy", "mann_dog"])
def posed(request: pytest.FixtureRequest) -> Posed:
    if request.param == "mann_dog":
        skeleton, standing = mann_standing()
        return skeleton, standing_rotations(skeleton, standing)
    return skeletons()[request.param], None


def test_mesh_is_closed_outward_and_a_few_thousand_triangles(posed: Posed) -> None:
    assert_closed_and_outward(build_mesh(*posed))


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(0.5, 2.0), min_size=20, max_size=20), st.floats(-np.pi, np.pi))
def test_any_proportions_and_heading_make_a_closed_standing_mesh(lengths: list[float], yaw: float) -> None:
    """The toy quadruped with every bone 0.5-2x as long, its rest pose turned to any heading."""
    toy = toy_skeleton()
    turn = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
    offsets = (toy.offsets * np.array(lengths)[:, None]) @ turn.T
    skeleton = Skeleton(toy.names, toy.parents, offsets.astype(np.float32), toy.end_site, toy.feet, "toy")
    mesh = build_mesh(skeleton)
    assert_closed_and_outward(mesh)
    assert np.allclose(mesh.weights.sum(axis=1), 1.0, atol=1e-6)
    assert abs(float(mesh.positions[:, 1].min())) < 1e-3  # soles on the ground
    # Turned to face +Z: from the hind limbs' roots to the fore limbs', level.
    roots = mesh.bind_pos[[skeleton.limb_chain(f.end_effector)[0] for f in skeleton.feet]][:, [0, 2]]
    heading = roots[:2].mean(0) - roots[2:].mean(0)
    assert abs(heading[0]) < 1e-4 and heading[1] > 0


def assert_closed_and_outward(mesh: SkinnedMesh) -> None:
    tri = mesh.triangles.astype(np.int64)
    assert 1000 <= len(tri) <= 8000
    # Closed and consistently wound: every directed edge meets its reverse exactly once.
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    forward = {tuple(e) for e in edges.tolist()}
    assert len(forward) == len(edges) and all((b, a) in forward for a, b in forward)
    p = mesh.positions.astype(np.float64)[tri]
    volume = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6
    assert volume > 0  # counter-clockwise seen from outside (glTF's front faces)
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    vertex = mesh.normals[tri].sum(axis=1)
    assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-5)
    assert np.mean(np.einsum("ij,ij->i", face, vertex) > 0) > 0.99


def test_weights_are_smooth_normalized_and_on_moving_joints(posed: Posed) -> None:
    skeleton, mesh = posed[0], build_mesh(*posed)
    assert np.allclose(mesh.weights.sum(axis=1), 1.0, atol=1e-6)
    assert mesh.weights.shape[1] == 4 and mesh.weights.min() >= 0
    assert mesh.joints.max() < skeleton.n_joints
    assert np.all(mesh.joints[mesh.weights == 0] == 0)
    influences = (mesh.weights > 0).sum(axis=1)
    assert np.mean(influences >= 2) > 0.15  # blended across joints, not rigid pieces
    weighted = np.unique(mesh.joints[mesh.weights > 0])
    assert not np.any(skeleton.end_site[weighted])  # an end site's rotation moves nothing
    # Every limb joint above the end site drives some of the mesh.
    for foot in skeleton.feet:
        assert set(skeleton.limb_chain(foot.end_effector)[:-1]) <= set(weighted.tolist())


def test_rest_mesh_stands_on_the_ground_around_its_skeleton() -> None:
    for name, skeleton in skeletons().items():
        mesh = build_mesh(skeleton)
        rest = rest_world_positions(skeleton)
        assert abs(float(mesh.positions[:, 1].min())) < 1e-3, name  # soles flat on y = 0
        assert rest_stands(skeleton)
        feet = mesh.bind_pos[skeleton.foot_joints]
        assert feet[:2, 2].mean() > feet[2:, 2].mean()  # facing +Z (the toy's rest faces +X)
        if name != "toy":  # the built-in animals face +Z: bound in their rest pose as it is
            assert np.allclose(mesh.bind_pos, rest, atol=1e-6)
        rest = mesh.bind_pos.astype(np.float64)
        for foot in skeleton.feet:  # a hoof or paw around each end effector
            gap = np.linalg.norm(mesh.positions - rest[foot.end_effector], axis=1).min()
            assert gap < 0.06 * float(rest[:, 1].max()), (name, foot.name)
        lo, hi = mesh.positions.min(0), mesh.positions.max(0)
        assert np.all(lo <= rest.min(0) + 0.01) and np.all(hi >= rest.max(0) - 0.01), name


def planted_sole_heights(mesh: SkinnedMesh, skeleton: Skeleton, root: np.ndarray, rotations: np.ndarray,
                         contacts: np.ndarray) -> np.ndarray:
    """Lowest vertex of each planted foot's last bone, per frame where it is planted (metres)."""
    heights = []
    for f in range(len(root)):  # a few dozen frames of one clip
        pos, rot = forward_kinematics(skeleton, root[f], rotations[f])
        vertices = pose_mesh(mesh, pos, rot)
        for k, foot in enumerate(skeleton.feet):
            sole = mesh.joints[:, 0] == foot.chain[-2]
            if contacts[f, k]:
                heights.append(vertices[sole, 1].min())
    return np.array(heights)


@pytest.mark.parametrize("animal", ["horse", "dog"])
def test_planted_feet_of_the_skinned_mesh_stay_on_the_ground(animal: str) -> None:
    library = build_builtin(animal)
    for gait in ("walk", "trot", "canter", "gallop"):
        clip = library.maps[gait].clip(len(library.maps[gait].speeds) // 2)
        heights = planted_sole_heights(build_mesh(library.skeleton), library.skeleton, clip.root_pos,
                                       clip.rotations, clip.contacts)
        # A planted hoof or paw touches the ground (not floating) and does not sink into it by
        # as much as a centimetre (what a viewer's ground plane would show), also while it
        # rolls over its toe.
        assert len(heights) > 0, gait
        assert heights.min() > -0.01 and heights.max() < 0.01, (gait, heights.min(), heights.max())


def test_a_scaled_character_gets_a_scaled_mesh() -> None:
    skeleton = build_skeleton("dog")
    mesh = build_mesh(skeleton)
    rest = rest_world_positions(skeleton)
    identity = np.tile([0.0, 0.0, 0.0, 1.0], (skeleton.n_joints, 1))
    big = pose_mesh(mesh, 1.3 * rest, identity, scale=1.3)
    assert np.allclose(big, 1.3 * mesh.positions, atol=1e-5)


def test_a_rig_whose_zero_pose_lies_flat_is_bound_standing_facing_z() -> None:
    skeleton, standing = mann_standing()
    assert not rest_stands(skeleton)
    mesh = build_mesh(skeleton, standing_rotations(skeleton, standing))
    feet = mesh.bind_pos[skeleton.foot_joints]
    assert np.abs(feet[:, 1]).max() < 0.03  # the four paws on the ground
    assert feet[:2, 2].mean() > feet[2:, 2].mean() + 0.2  # fore paws ahead, along +Z
    height = mesh.positions[:, 1].max()
    assert 0.4 < height < 0.8  # a 0.46 m (hips) dog, head up
    # Skinned to its own bind pose, the mesh is where it was made.
    assert np.allclose(pose_mesh(mesh, mesh.bind_pos, mesh.bind_rot), mesh.positions, atol=1e-5)


def test_a_skeleton_without_feet_is_refused_by_name() -> None:
    skeleton = toy_skeleton()
    bare = Skeleton(skeleton.names, skeleton.parents, skeleton.offsets, skeleton.end_site, name="bare")
    with pytest.raises(ValueError, match="bare.*feet"):
        build_mesh(bare)
