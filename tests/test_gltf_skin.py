"""glTF binaries that engines take as characters (synth_core.export.gltf): the library's skinned
mesh, a herd with a skin per character and one animation, gaits and contacts in extras and in
BVH sidecars. Read back with pygltflib here; with Khronos' glTF-Validator and three.js'
GLTFLoader under Node where node and npm are installed (scripts/ensure-node-tools)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pygltflib
import pytest

from synth_core.build.animals import build_builtin
from synth_core.build.artifact import Library
from synth_core.build.motion_graph import HUBS
from synth_core.export import write_bvh_files, write_glb
from synth_core.export.gltf import bind_rotations, mesh_glb
from synth_core.export.mesh import build_mesh, pose_mesh
from synth_core.motion import quat
from synth_core.motion.contacts import contacts_from_json, ranges_to_contacts
from synth_core.motion.skeleton import forward_kinematics
from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import build_bank
from synth_core.runtime.synthesis import Options, Result, synthesize

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def horse() -> Library:
    return build_builtin("horse")


@pytest.fixture(scope="module")
def result(horse: Library) -> Result:
    paths = crowd.simulate(3, 200, seed=4, top=6.0)
    return synthesize(build_bank(horse), paths, options=Options(seed=4, scale_range=(0.8, 1.2)))


def ibms(gltf: pygltflib.GLTF2, skin: int) -> np.ndarray:
    accessor = gltf.accessors[gltf.skins[skin].inverseBindMatrices]
    view = gltf.bufferViews[accessor.bufferView]
    flat = np.frombuffer(gltf.binary_blob(), "<f4", accessor.count * 16, view.byteOffset)
    return flat.reshape(-1, 4, 4).transpose(0, 2, 1)  # column-major in the file


def expand(runs: list[list[Any]], frames: int) -> list[str]:
    out: list[str] = []
    for start, stop, name in runs:
        assert start == len(out)
        out += [name] * (stop - start)
    assert len(out) == frames
    return out


def test_library_glb_binds_the_mesh_to_the_skeleton_in_its_rest_pose(horse: Library) -> None:
    skeleton = horse.skeleton
    gltf = pygltflib.GLTF2.load_from_bytes(mesh_glb(skeleton, "horse"))
    J = skeleton.n_joints
    assert [n.name for n in gltf.nodes[:J]] == list(skeleton.names)
    for j in range(J):
        assert sorted(gltf.nodes[j].children or []) == skeleton.children(j)
        assert gltf.nodes[j].rotation is None  # the rest pose: no rotation anywhere
    mesh = build_mesh(skeleton)
    world = np.tile(np.eye(4), (J, 1, 1))
    world[:, :3, 3] = mesh.bind_pos
    assert np.allclose(ibms(gltf, 0) @ world, np.eye(4), atol=1e-5)  # inverse bind = inverse rest
    assert gltf.scenes[0].nodes == [J + 1, J] and gltf.nodes[J + 1].children == [0]
    assert gltf.nodes[J].translation is None and gltf.nodes[J + 1].translation is None
    assert np.allclose(gltf.nodes[0].translation, mesh.bind_pos[0])  # standing on y = 0
    assert np.allclose(bind_rotations(mesh_glb(skeleton, "horse"), J), quat.identity((J,)))


def test_herd_glb_has_a_skin_per_character_scaled_with_gaits_and_contacts(horse: Library, result: Result,
                                                                          tmp_path: Path) -> None:
    ids = ["a", "b", "c"]
    path = write_glb(horse.skeleton, result, ids, tmp_path / "herd.glb", 60.0)
    gltf = pygltflib.GLTF2().load(str(path))
    J, (C, T) = horse.skeleton.n_joints, result.root_pos.shape[:2]
    assert len(gltf.nodes) == C * (J + 2) and len(gltf.skins) == C and len(gltf.meshes) == 1
    assert len(gltf.animations) == 1 and len(gltf.animations[0].channels) == C * (J + 1)
    unit = ibms(pygltflib.GLTF2.load_from_bytes(mesh_glb(horse.skeleton, "horse")), 0)
    for c in range(C):
        node = gltf.nodes[c * (J + 2) + J]
        assert node.name == ids[c] and node.skin == c and node.mesh == 0
        assert gltf.skins[c].joints == list(range(c * (J + 2), c * (J + 2) + J))
        scale = np.diag([result.scales[c]] * 3 + [1.0])
        assert np.allclose(ibms(gltf, c), scale @ unit, atol=1e-5)
        extras = node.extras
        assert extras["id"] == ids[c] and extras["scale"] == pytest.approx(result.scales[c])
        assert np.array_equal(ranges_to_contacts(extras["feet"], T), result.contacts[c])
        assert expand(extras["gait"], T) == [HUBS[g] for g in result.gait[c]]
    assert gltf.scenes[0].extras["frames"] == T and gltf.scenes[0].extras["gaits"] == list(HUBS)


def test_bvh_gets_a_gait_and_contact_sidecar(horse: Library, result: Result, tmp_path: Path) -> None:
    paths = write_bvh_files(horse.skeleton, result, ["a", "b/c", "d"], tmp_path, 60.0)
    T = result.root_pos.shape[1]
    for c, path in enumerate(paths):
        document = json.loads(path.with_name(f"{path.stem}.contacts.json").read_text())
        assert np.array_equal(contacts_from_json(document, T), result.contacts[c])
        assert expand(document["gait"], T) == [HUBS[g] for g in result.gait[c]]
    assert json.loads((tmp_path / "b_c.contacts.json").read_text())["id"] == "b/c"


# --- as engines read them (Node) -------------------------------------------------------------------

@pytest.fixture(scope="module")
def node_tools() -> Path:
    run = subprocess.run([str(REPO / "scripts" / "ensure-node-tools")], capture_output=True, text=True)
    if run.returncode != 0:
        pytest.skip(f"scripts/ensure-node-tools: {run.stderr.strip()}")
    return Path(run.stdout.strip().splitlines()[-1])


def check(node_tools: Path, *files: Path) -> list[dict[str, Any]]:
    run = subprocess.run(["node", str(node_tools / "check.mjs"), *map(str, files)], capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    return list(json.loads(run.stdout))


def three_pose(skeleton: Any, result: Result, c: int, time: float,
               fps: float) -> tuple[np.ndarray, np.ndarray]:
    """World joint positions and rotations of character c at ``time`` as glTF's LINEAR sampler
    plays it (lerp of the root, slerp of the rotations)."""
    f = time * fps
    f0 = min(int(np.floor(f)), result.root_pos.shape[1] - 2)
    a = f - f0
    root = (1 - a) * result.root_pos[c, f0] + a * result.root_pos[c, f0 + 1]
    rotations = quat.slerp(result.rotations[c, f0], result.rotations[c, f0 + 1], a)
    pos, rot = forward_kinematics(skeleton, root, rotations, skeleton.offsets * result.scales[c])
    return np.asarray(pos, np.float64), np.asarray(rot, np.float64)


def test_validator_and_three_take_the_glbs_as_skinned_characters(node_tools: Path, horse: Library,
                                                                 result: Result, tmp_path: Path) -> None:
    dog = build_builtin("dog")
    files = {"horse": tmp_path / "horse.glb", "dog": tmp_path / "dog.glb", "herd": tmp_path / "herd.glb"}
    files["horse"].write_bytes(mesh_glb(horse.skeleton, "horse"))
    files["dog"].write_bytes(mesh_glb(dog.skeleton, "dog"))
    write_glb(horse.skeleton, result, ["a", "b", "c"], files["herd"], 60.0)
    reports = dict(zip(files, check(node_tools, *files.values()), strict=True))
    for name, report in reports.items():
        validator = report["validator"]
        assert validator["errors"] == 0 and validator["warnings"] == 0, (name, validator["messages"])
    for name, library in (("horse", horse), ("dog", dog)):
        meshes = reports[name]["three"]["skinnedMeshes"]
        assert len(meshes) == 1 and meshes[0]["bones"] == list(library.skeleton.names), name
        assert meshes[0]["skinAttributes"]
        assert meshes[0]["triangles"] == len(build_mesh(library.skeleton).triangles)
    herd = reports["herd"]["three"]
    assert [m["bones"] for m in herd["skinnedMeshes"]] == [[f"{i}_{n}" for n in horse.skeleton.names]
                                                           for i in "abc"]
    [animation] = herd["animations"]
    assert animation["tracks"] == 3 * (horse.skeleton.n_joints + 1)
    assert herd["moved"] > 1.0  # metres: the animation carries the herd along
    # three.js skins the mesh where our own skinning puts it, each character at its scale.
    mesh = build_mesh(horse.skeleton)
    for c, sample in enumerate(herd["sample"]):
        pos, rot = three_pose(horse.skeleton, result, c, herd["time"], 60.0)
        ours = pose_mesh(mesh, pos, rot, float(result.scales[c]))[::herd["sampleEvery"]]
        assert np.abs(np.array(sample) - ours).max() < 1e-3, c


def test_a_bvh_rigs_mesh_is_bound_standing_and_valid(node_tools: Path, tmp_path: Path) -> None:
    from tests.helpers.mocap import mann_standing

    skeleton, standing = mann_standing()
    glb = mesh_glb(skeleton, "mann_dog", standing)
    (tmp_path / "mann.glb").write_bytes(glb)
    [report] = check(node_tools, tmp_path / "mann.glb")
    assert report["validator"]["errors"] == 0 and report["validator"]["warnings"] == 0, report["validator"]
    # The file opens standing (its nodes hold the bind pose), and three.js skins it where it was made.
    [sample] = report["three"]["sample"]
    mesh = build_mesh(skeleton, standing)
    assert np.abs(np.array(sample) - mesh.positions[::report["three"]["sampleEvery"]]).max() < 1e-3
    stored = bind_rotations(glb, skeleton.n_joints)
    assert np.allclose(np.abs(quat.dot(stored, mesh.bind_local)), 1, atol=1e-5)


def test_library_mesh_command_writes_the_served_glb_and_a_picture(tmp_path: Path) -> None:
    from quadsynth.cli import main

    dog = build_builtin("dog")
    assert main(["library", "mesh", "--animal", "dog", "--out", str(tmp_path / "dog.glb"),
                 "--png", str(tmp_path / "dog.png"), "--gait", "trot"]) == 0
    assert (tmp_path / "dog.glb").read_bytes() == mesh_glb(dog.skeleton, "dog")
    assert (tmp_path / "dog.png").read_bytes()[:4] == b"\x89PNG"


def test_blender_imports_an_armature_per_character(horse: Library, result: Result, tmp_path: Path) -> None:
    run = subprocess.run([str(REPO / "scripts" / "ensure-blender")], capture_output=True, text=True)
    if run.returncode != 0:
        pytest.skip(f"scripts/ensure-blender: {run.stderr.strip().splitlines()[-1:]}")
    blender = run.stdout.strip().splitlines()[-1]
    write_glb(horse.skeleton, result, ["a", "b", "c"], tmp_path / "herd.glb", 60.0)
    (tmp_path / "horse.glb").write_bytes(mesh_glb(horse.skeleton, "horse"))
    script = REPO / "tools" / "gltf-check" / "blender_import.py"
    done = subprocess.run([blender, "-b", "--factory-startup", "--python", str(script), "--",
                           str(tmp_path / "herd.glb"), str(tmp_path / "horse.glb")],
                          capture_output=True, text=True, timeout=600)
    reports = [json.loads(line.split(" ", 1)[1]) for line in done.stdout.splitlines()
               if line.startswith("QUADSYNTH_REPORT ")]
    assert len(reports) == 2, done.stdout[-2000:] + done.stderr[-2000:]
    herd, single = reports
    J = horse.skeleton.n_joints
    assert len(herd["armatures"]) == 3 and herd["skinned_meshes"] == 3 and herd["actions"] >= 1
    assert all(len(a["bones"]) == J for a in herd["armatures"])
    assert len(single["armatures"]) == 1 and single["skinned_meshes"] == 1
    assert single["armatures"][0]["bones"] == list(horse.skeleton.names)
