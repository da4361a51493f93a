"""BVH import/export: the real dog files, round trips, channel layouts, malformed input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from synth_core.motion import bvh
from synth_core.motion.bvh import BVHError
from tests.helpers.mocap import MANN_DIR, MANN_FILES, mann_path
from tests.helpers.motion import random_motion

ROUND_TRIP_MM = 0.1


def max_position_error_mm(a, b) -> float:  # type: ignore[no-untyped-def]
    """Largest joint position difference, joints matched by name (BVH lists them in preorder)."""
    order = [b.skeleton.index(name) for name in a.skeleton.names]
    return float(np.abs(a.positions() - b.positions()[:, order]).max() * 1000.0)


@pytest.mark.skipif(not MANN_FILES, reason=f"real dog mocap not found at {MANN_DIR}")
@pytest.mark.parametrize("path", MANN_FILES, ids=lambda p: p.stem)
def test_every_mann_file_reads_and_round_trips(path: Path, tmp_path: Path) -> None:
    motion = bvh.read(path)
    assert motion.fps == 60.0
    assert motion.skeleton.n_joints == 27  # 21 joints + 6 End Sites (SOURCE.md)
    assert [motion.skeleton.names[f.end_effector] for f in motion.skeleton.feet] == [
        "LeftHand_end", "RightHand_end", "LeftFoot_end", "RightFoot_end"]
    pos = motion.positions()
    # Root OFFSET ignored and centimetres converted: the paws sit on the ground (Y ~ 0, metres).
    paws = pos[:, motion.skeleton.foot_joints, 1]
    assert abs(np.percentile(paws, 2)) < 0.03
    out = tmp_path / path.name
    bvh.write(motion, out)
    again = bvh.read(out)
    assert again.n_frames == motion.n_frames and again.fps == motion.fps
    assert max_position_error_mm(motion, again) < ROUND_TRIP_MM


def test_standing_dog_has_hips_about_46cm_high() -> None:
    motion = bvh.read(mann_path("D1_ex01_KAN01_001"))  # stands during frames 0-147
    hips = motion.positions()[:140, 0, 1]
    assert 0.40 < float(np.median(hips)) < 0.52


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**31), st.sampled_from(["ZXY", "XYZ", "YZX", "ZYX"]),
       st.sampled_from(["cm", "m", "mm", "in"]))
def test_made_motions_round_trip_in_any_order_and_unit(seed: int, order: str, unit: str) -> None:
    motion = random_motion(np.random.default_rng(seed), frames=12, spread=1.5)
    again = bvh.parse(bvh.dumps(motion, unit=unit, order=order), unit=unit)
    assert sorted(again.skeleton.names) == sorted(motion.skeleton.names)
    ends = {n for n, e in zip(motion.skeleton.names, motion.skeleton.end_site, strict=True) if e}
    assert {n for n, e in zip(again.skeleton.names, again.skeleton.end_site, strict=True) if e} == ends
    assert [again.skeleton.names[f.end_effector] for f in again.skeleton.feet] == [
        motion.skeleton.names[f.end_effector] for f in motion.skeleton.feet]
    assert max_position_error_mm(motion, again) < ROUND_TRIP_MM


SIMPLE = """HIERARCHY
ROOT Hips
{
  OFFSET 1 2 3
  CHANNELS 6 Zrotation Xposition Yposition Xrotation Zposition Yrotation
  JOINT Leg
  {
    OFFSET 0 -10 0
    CHANNELS 3 Xrotation Yrotation Zrotation
    End Site
    {
      OFFSET 0 -10 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
90 10 20 0 30 0 0 0 0
0 10 20 0 30 0 90 0 0
"""


def test_any_root_channel_layout_crlf_and_root_offset_modes() -> None:
    motion = bvh.parse(SIMPLE.replace("\n", "\r\n"), unit="cm")
    assert motion.fps == 30.0
    np.testing.assert_allclose(motion.root_pos, [[0.1, 0.2, 0.3]] * 2, atol=1e-7)
    added = bvh.parse(SIMPLE, unit="cm", root_offset="add")
    np.testing.assert_allclose(added.root_pos, [[0.11, 0.22, 0.33]] * 2, atol=1e-7)
    pos = motion.positions()
    # Frame 0: root turned 90 deg about Z, so the leg (down) points along +X.
    np.testing.assert_allclose(pos[0, 2], [0.3, 0.2, 0.3], atol=1e-6)
    # Frame 1: the leg joint hangs 10 cm below the root and turns 90 deg about X: its end
    # site points along -Z.
    np.testing.assert_allclose(pos[1, 1], [0.1, 0.1, 0.3], atol=1e-6)
    np.testing.assert_allclose(pos[1, 2], [0.1, 0.1, 0.2], atol=1e-6)
    assert motion.skeleton.names == ("Hips", "Leg", "Leg_end")


def test_constant_position_channels_on_joints_become_offsets() -> None:
    text = SIMPLE.replace("CHANNELS 3 Xrotation", "CHANNELS 4 Yposition Xrotation").replace(
        "90 10 20 0 30 0 0 0 0", "90 10 20 0 30 0 -20 0 0 0").replace(
        "0 10 20 0 30 0 90 0 0", "0 10 20 0 30 0 -20 90 0 0")
    motion = bvh.parse(text)
    np.testing.assert_allclose(motion.skeleton.offsets[1], [0, -0.2, 0], atol=1e-7)
    animated = text.replace("30 0 -20 90", "30 0 -25 90")
    with pytest.raises(BVHError, match="Leg has animated position channels"):
        bvh.parse(animated)


MALFORMED = {
    "no MOTION section": (SIMPLE.split("MOTION")[0], "no MOTION section"),
    "bad offset": (SIMPLE.replace("OFFSET 0 -10 0", "OFFSET 0 x 0", 1), r":8: expected a number"),
    "unknown channel": (SIMPLE.replace("Xrotation Yrotation", "Wrotation Yrotation"),
                        r":9: .*unknown channel"),
    "short frame": (SIMPLE.replace("0 10 20 0 30 0 90 0 0", "0 10 20 0 30 0 90 0"),
                    r":20: .*expected 9 values"),
    "text in frame": (SIMPLE.replace("90 10 20", "90 ten 20"), r":19: .*'ten' is not a finite number"),
    "nan in frame": (SIMPLE.replace("90 10 20", "90 nan 20"), r":19: .*'nan' is not a finite number"),
    "frame count": (SIMPLE.replace("Frames: 2", "Frames: 3"), "says 3 but the file has 2"),
    "frame time": (SIMPLE.replace("0.0333333", "0"), r":18: Frame Time: expected a positive"),
    "unclosed brace": (SIMPLE.replace("}\nMOTION", "MOTION"), "unexpected end of file"),
    "zero frames": (SIMPLE.replace("Frames: 2", "Frames: 0"), "no frames"),
    "no hierarchy": ("MOTION\nFrames: 1\n", "expected 'HIERARCHY'"),
    "two roots": (SIMPLE.split("MOTION")[0] + "ROOT B\n{\nOFFSET 0 0 0\nCHANNELS 0\n}\nMOTION"
                  + SIMPLE.split("MOTION")[1], "one ROOT only"),
    "negative count": (SIMPLE.replace("CHANNELS 3", "CHANNELS -3"), "non-negative integer"),
    "end site child": (SIMPLE.replace("OFFSET 0 -10 0\n    }", "OFFSET 0 -10 0\n JOINT X\n    }"),
                       "End Site cannot have children"),
}


@pytest.mark.parametrize("case", MALFORMED, ids=list(MALFORMED))
def test_malformed_files_get_a_clear_error_naming_the_line(case: str) -> None:
    text, message = MALFORMED[case]
    with pytest.raises(BVHError, match=message) as err:
        bvh.parse(text, source="bad.bvh")
    assert str(err.value).startswith("bad.bvh")


def test_binary_garbage_and_bad_units_are_clear_errors(tmp_path: Path) -> None:
    junk = tmp_path / "junk.bvh"
    junk.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(BVHError, match="junk.bvh: not a text file"):
        bvh.read(junk)
    with pytest.raises(ValueError, match="unit: expected one of"):
        bvh.parse(SIMPLE, unit="furlong")
    with pytest.raises(ValueError, match="unit: a numeric scale must be positive"):
        bvh.parse(SIMPLE, unit=-1.0)


def test_a_huge_declared_frame_count_fails_fast_instead_of_hanging() -> None:
    with pytest.raises(BVHError, match="says 999999999999"):
        bvh.parse(SIMPLE.replace("Frames: 2", "Frames: 999999999999"))


def test_deep_hierarchies_do_not_hit_the_recursion_limit() -> None:
    depth = 3000
    head = "HIERARCHY\nROOT j0\n{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition Zposition\n"
    body = "".join(f"JOINT j{i}\n{{\nOFFSET 0 1 0\nCHANNELS 0\n" for i in range(1, depth))
    text = head + body + "}\n" * depth + "MOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0\n"
    motion = bvh.parse(text, unit="m")
    assert motion.skeleton.n_joints == depth
    assert motion.positions()[0, -1, 1] == pytest.approx(depth - 1)
    assert bvh.parse(bvh.dumps(motion, unit="m"), unit="m").skeleton.n_joints == depth


def test_export_writes_centimetres_by_default(tmp_path: Path) -> None:
    motion = bvh.parse(SIMPLE)
    text = bvh.dumps(motion)
    assert "OFFSET 0.000000 -10.000000 0.000000" in text  # 10 cm leg written back as 10
    assert "End Site" in text
