"""Crowd outputs (BVH per character, glTF binary, herd preview), the on-the-fly baseline, and the
crowd-sim / synth / eval commands end to end."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pygltflib
import pytest

from quadsynth.cli import main
from synth_core.build.animals import build_builtin
from synth_core.export import write_bvh_files, write_glb
from synth_core.motion import bvh
from synth_core.quality import herd_sim as crowd
from synth_core.quality.onthefly import synthesize_onthefly
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.synthesis import Options, Result, synthesize


@pytest.fixture(scope="module")
def library():  # type: ignore[no-untyped-def]
    return build_builtin("horse")


@pytest.fixture(scope="module")
def bank(library) -> Bank:  # type: ignore[no-untyped-def]
    return build_bank(library)


@pytest.fixture(scope="module")
def result(bank: Bank) -> Result:
    return synthesize(bank, crowd.simulate(3, 240, seed=2), options=Options(scale_range=(0.8, 1.2)))


def test_bvh_per_character_is_centimetres_at_its_scale(bank: Bank, result: Result, tmp_path: Path) -> None:
    paths = write_bvh_files(bank.skeleton, result, ["a", "b/c", "d"], tmp_path, bank.fps)
    assert [p.name for p in paths] == ["a.bvh", "b_c.bvh", "d.bvh"]
    back = bvh.read(paths[1], unit="cm", feet=None)
    assert np.allclose(back.root_pos, result.root_pos[1], atol=1e-5)
    assert np.allclose(back.skeleton.offsets[1:], bank.skeleton.offsets[1:] * result.scales[1], atol=1e-5)
    angle = np.abs(np.sum(back.rotations * result.rotations[1], axis=-1))
    assert angle.min() > np.cos(np.radians(0.1) / 2)  # 6 decimals of degrees, float32 dot


def test_glb_holds_one_hierarchy_and_animation_per_character(bank: Bank, result: Result,
                                                            tmp_path: Path) -> None:
    path = write_glb(bank.skeleton, result, ["a", "b", "c"], tmp_path / "herd.glb", bank.fps)
    gltf = pygltflib.GLTF2().load(str(path))
    J, (C, T) = bank.skeleton.n_joints, result.root_pos.shape[:2]
    # Per character: its joints, its skinned mesh node, the node its joints hang from.
    assert len(gltf.nodes) == C * (J + 2) and len(gltf.scenes[0].nodes) == 2 * C
    assert len(gltf.animations[0].channels) == C * (J + 1)
    times = gltf.accessors[gltf.animations[0].samplers[0].input]
    assert times.max == [pytest.approx((T - 1) / bank.fps)]
    blob = gltf.binary_blob()
    # The second character's LF upper leg rotation track decodes to the synthesized rotations.
    j = bank.skeleton.index("L_Humerus")
    channel = next(ch for ch in gltf.animations[0].channels
                   if ch.target.node == J + 2 + j and ch.target.path == "rotation")
    acc = gltf.accessors[gltf.animations[0].samplers[channel.sampler].output]
    view = gltf.bufferViews[acc.bufferView]
    data = np.frombuffer(blob, "<f4", acc.count * 4, view.byteOffset + acc.byteOffset).reshape(-1, 4)
    assert np.allclose(data, result.rotations[1, :, j])
    node = gltf.nodes[J + 2 + j]
    assert np.allclose(node.translation, bank.skeleton.offsets[j] * result.scales[1], atol=1e-6)


def test_onthefly_baseline_follows_the_same_schedule_with_exact_speed_clips(library, bank: Bank) -> None:  # type: ignore[no-untyped-def]
    paths = crowd.simulate(3, 300, seed=1, top=5.0)
    fast = synthesize(bank, paths, options=Options(seed=1))
    slow = synthesize_onthefly(bank, library, paths, options=Options(seed=1))
    assert np.array_equal(fast.gait, slow.gait) and np.array_equal(fast.contacts, slow.contacts)
    assert np.allclose(fast.root_pos[..., [0, 2]], slow.root_pos[..., [0, 2]], atol=0.01)
    turn = 2 * np.degrees(np.arccos(np.clip(np.abs(np.sum(fast.rotations * slow.rotations, -1)), 0, 1)))
    # Interpolating neighbouring speed-map clips is close to making the clip for the exact speed.
    assert np.percentile(turn, 99) < 5.0 and turn.max() > 0.01


def test_crowd_sim_then_synth_writes_every_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    traj = tmp_path / "traj.npz"
    assert main(["crowd-sim", "--characters", "4", "--frames", "150", "--seed", "3", "--out", str(traj)]) == 0
    assert np.load(traj)["positions"].shape == (4, 150, 3)
    out = tmp_path / "out"
    code = main(["synth", "--trajectories", str(traj), "--animal", "horse", "--seed", "3", "--out", str(out),
                 "--bvh", "--glb", str(tmp_path / "h.glb"), "--preview", str(tmp_path / "h.gif")])
    assert code == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["characters"] == 4 and summary["frames"] == 150
    assert sorted(p.name for p in out.glob("*.bvh")) == ["0.bvh", "1.bvh", "2.bvh", "3.bvh"]
    assert sorted(p.name for p in out.glob("*.contacts.json")) == [f"{c}.contacts.json" for c in range(4)]
    assert (tmp_path / "h.glb").stat().st_size > 0 and (tmp_path / "h.gif").read_bytes()[:3] == b"GIF"
    motion = np.load(out / "motion.npz")
    assert motion["rotations"].shape == (4, 150, bvh.read(out / "0.bvh", feet=None).skeleton.n_joints, 4)


def test_synth_reports_bad_input_without_a_traceback(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    csv = tmp_path / "t.csv"
    csv.write_text("id,frame,x,y,z\na,0,0,0,0\na,2,0,0,0\n")
    assert main(["synth", "--trajectories", str(csv), "--out", str(tmp_path / "o")]) == 2
    assert "frames missing [1]" in capsys.readouterr().err
    assert main(["synth", "--trajectories", str(csv), "--animal", "cat", "--out", str(tmp_path / "o")]) == 2


def test_eval_prints_the_issue_figures(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["eval", "--animal", "dog", "--characters", "8", "--frames", "300", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out)
    for key in ("path_error_cm_max", "path_error_cm_mean", "timing_error_cm_max", "skate_mm_mean",
                "skate_mm_p95", "skating_ratio", "footfall_preserved", "footfall_across_transitions",
                "pop_ratio", "penetration_mm",
                "gait_frames", "nan_count", "resample_rate"):
        assert key in figures
    assert figures["nan_count"] == 0 and figures["path_error_cm_max"] <= 1.0
    assert set(figures["gait_frames"]) == {"static", "walk", "trot", "canter", "gallop"}
