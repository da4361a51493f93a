"""Building a library from a user's BVH mocap: the real dog manifest, generated transitions, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from synth_core.build.animals import map_positions, report
from synth_core.build.artifact import Library
from synth_core.build.manifest import ManifestError, build_from_manifest
from synth_core.build.speed_map import cycle_displacement
from synth_core.motion import contacts as C
from synth_core.quality import metrics as M
from tests.helpers.mocap import MANN_DIR

FIXTURE = Path(__file__).parent / "fixtures" / "mann_dog.toml"
needs_mann = pytest.mark.skipif(not MANN_DIR.is_dir(), reason="real dog mocap not found beside the repo")


@pytest.fixture(scope="module")
def mann() -> Library:
    return build_from_manifest(FIXTURE)


@pytest.fixture(scope="module")
def mann_figures(mann: Library) -> dict:
    return report(mann)


@needs_mann
def test_the_real_dog_builds_with_generated_transitions_where_data_lacks_them(mann_figures: dict) -> None:
    graph = mann_figures["graph"]
    assert graph["nodes"] == ["static", "walk", "trot", "canter", "gallop"]
    assert graph["generated_transitions"] == ["canter2gallop", "canter2trot", "trot2canter"]
    assert len(graph["transitions"]) == 8 and graph["static_to_gallop"]
    for gait, f in mann_figures["gaits"].items():
        assert f["clips"] >= 55, gait
        assert f["skate_mm_mean"] <= 0.5, gait
        assert f["speed_error_pct_max"] <= 1.0, gait
        # The issue asks the 3% stretch bound of the built-ins only; the real dog meets it too.
        assert f["footfall_preserved"] == 1.0, gait
        assert f["max_limb_stretch_pct"] <= 3.0, gait


@needs_mann
def test_every_transition_keeps_feet_planted_and_steps_on(mann: Library) -> None:
    """Mocap transitions are foot-locked; generated ones also step on without skipping a step and
    with at most one quick step per foot (changing lead between a trot and a canter needs one)."""
    for name, motion in mann.transitions.items():
        assert M.foot_skate(motion.foot_positions(), motion.contacts).mean_mm <= 0.5, name
        if name not in mann.generated:
            continue
        strides = [mann.maps[g].n_frames for g in name.split("2") if g in mann.maps]
        for k, downs in enumerate(C.touchdowns(motion.contacts)):
            gaps = np.diff(downs)
            assert np.all(gaps <= 1.5 * max(strides)), (name, k, gaps)
            assert np.sum(gaps < 0.6 * min(strides)) <= 1, (name, k, gaps)


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "m.toml"
    path.write_text(f'mocap_dir = "{MANN_DIR}"\n' + text)
    return path


GOOD = FIXTURE.read_text().replace('mocap_dir = "../../../shared/mocap/mann_dog"\n', "") + \
    "\n[speeds.walk]\nlow = 0.5\n"  # so a test can misname a [speeds] table
GALLOP = 'file = "D1_010_KAN01_004.bvh"\nframes = "auto"\nsearch = [7, 54]'


@needs_mann
@pytest.mark.parametrize(("edit", "message"), [
    (("D1_009_KAN01_002.bvh", "no_such_file.bvh"), r"gaits\.trot\.file: .*no_such_file\.bvh not found"),
    (("frames = [296, 326]", "frames = [296, 99999]"),
     r"gaits\.trot\.frames: \[296, 99999\] is out of bounds"),
    (('LF = "LeftHand_end"', 'LF = "LeftPaw"'), r"feet\.LF: no joint 'LeftPaw'"),
    (("[gaits.canter]", "[gaits.lope]"),
     r"gaits\.lope: unknown gait 'lope'; known: walk, trot, canter, gallop"),
    (("[gaits.gallop]", "[not_a_gait]"), r"gaits: missing \['gallop'\]"),
    (("frames = [296, 326]", "frames = [326, 296]"),
     r"gaits\.trot\.frames: \[326, 296\] is reversed: the first frame must come before the stop frame"),
    (("search = [7, 54]", "search = [54, 7]"), r"gaits\.gallop\.search: \[54, 7\] is reversed"),
    (("[speeds.walk]", "[speeds.pace]"), r"speeds\.pace: unknown gait 'pace'"),
    (('frames = "auto"', 'frames = "sometimes"'),
     r'gaits\.gallop\.frames: expected \[first, stop\] or "auto"'),
    (('unit = "cm"', 'unit = "furlong"'), r"unit: expected one of"),
    (("[transitions.trot2walk]", "[transitions.trot2gallop]"), r"transitions: unknown \['trot2gallop'\]"),
])
def test_bad_manifests_name_the_field(tmp_path: Path, edit: tuple[str, str], message: str) -> None:
    old, new = edit
    assert old in GOOD
    with pytest.raises(ManifestError, match=message):
        build_from_manifest(write(tmp_path, GOOD.replace(old, new, 1)))


def test_unreadable_and_missing_manifests(tmp_path: Path) -> None:
    with pytest.raises(ManifestError, match="no such manifest"):
        build_from_manifest(tmp_path / "absent.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("animal = [unclosed")
    with pytest.raises(ManifestError, match="not valid TOML"):
        build_from_manifest(bad)
    empty = tmp_path / "empty.toml"
    empty.write_text('animal = "x"\n')
    with pytest.raises(ManifestError, match="feet: missing"):
        build_from_manifest(empty)


def with_gallop(tmp_path: Path, file: str, frames: str) -> Path:
    assert GALLOP in GOOD
    return write(tmp_path, GOOD.replace(GALLOP, f'file = "{file}"\nframes = {frames}'))


@needs_mann
def test_a_standing_segment_declared_as_a_gait_is_refused_naming_it(tmp_path: Path) -> None:
    """SOURCE.md: D1_ex01 stands over frames 0-147. As the gallop it would build a map of standing
    clips (footfall_preserved 0.0 before this check)."""
    with pytest.raises(ManifestError, match=r"gaits\.gallop: D1_ex01_KAN01_001\.bvh frames \[0, 60\] "
                                           r"moves at 0\.0\d m/s: a gait cycle must move"):
        build_from_manifest(with_gallop(tmp_path, "D1_ex01_KAN01_001.bvh", "[0, 60]"))


@needs_mann
def test_gaits_out_of_speed_order_are_refused_naming_both(tmp_path: Path) -> None:
    """The pace cycle of D1_007 (1.12 m/s) declared as the gallop would be slower than the canter."""
    with pytest.raises(ManifestError, match=r"gaits\.gallop: D1_007_KAN01_001\.bvh frames \[208, 245\] "
                                           r"moves at 1\.12 m/s, no faster than the canter "
                                           r"\(D1_010_KAN01_001\.bvh frames \[487, 515\], 3\.69 m/s\)"):
        build_from_manifest(with_gallop(tmp_path, "D1_007_KAN01_001.bvh", "[208, 245]"))


@needs_mann
def test_a_cycle_with_another_gaits_footfall_builds_with_a_warning(tmp_path: Path) -> None:
    """A trot (D1_031, 2.09 m/s: in speed order) declared as the canter: the library builds, and
    says what it found."""
    text = GOOD.replace('file = "D1_010_KAN01_001.bvh"\nframes = [487, 515]',
                        'file = "D1_031_KAN01_001.bvh"\nframes = [596, 624]')
    library = build_from_manifest(write(tmp_path, text))
    assert library.extra["warnings"][0] == (
        "gaits.canter: D1_031_KAN01_001.bvh frames [596, 624] has the footfall of a trot, not of a "
        "canter (expected one of canter, gallop)")


@needs_mann
def test_cycles_are_closed_into_loops_or_said_not_to_loop(mann: Library) -> None:
    """The fixture's walk, trot and canter strides repeat (leg joints within 5-21 deg of the next
    stride's first frame): they are closed, and no speed-map clip's paw jumps at the loop's seam
    more than inside it. Its gallop, the last stride before the dog brakes, does not repeat (the
    left elbow 78 deg off): left as it is, and said."""
    assert mann.extra["warnings"] == [
        "gaits.gallop: D1_010_KAN01_004.bvh frames [29, 54] does not loop: LeftForeArm turns 78 deg "
        "from its first frame to the next stride's (more than 30); its speed maps jump where they "
        "loop. A stride that repeats closes better"]
    for gait in ("walk", "trot", "canter"):
        speed_map = mann.maps[gait]
        feet = map_positions(speed_map)[:, :, mann.skeleton.foot_joints]
        advance = np.stack([cycle_displacement(r) for r in speed_map.root_pos])[:, None, None]
        looped = np.concatenate([feet[:, -2:] - advance, feet[:, :2]], axis=1)  # across the seam
        seam = np.linalg.norm(np.diff(looped, n=2, axis=1), axis=-1).max()
        inside = np.linalg.norm(np.diff(feet, n=2, axis=1), axis=-1).max()
        assert seam <= inside, gait


def test_close_loop_removes_a_strides_drift_and_keeps_its_shape() -> None:
    """A joint swinging sin-wise while drifting 12 deg over the stride (the next stride starts
    12 deg on): closed, the stride swings exactly periodically; the loop error names the joint."""
    from synth_core.build.mocap_clips import close_loop, loop_error
    from synth_core.motion import quat
    from synth_core.motion.clip import Motion
    from tests.helpers.motion import toy_skeleton

    skeleton = toy_skeleton()
    F, joint = 40, skeleton.index("LeftUpLeg")
    t = np.arange(F + 1)
    swing = np.radians(25.0) * np.sin(2 * np.pi * t / F)
    angles = swing + np.radians(12.0) * t / F
    rotations = np.tile(quat.identity(), (F + 1, skeleton.n_joints, 1))
    rotations[:, joint] = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), angles)
    take = Motion(skeleton, np.tile([0.0, 0.5, 0.0], (F + 1, 1)), rotations, 60.0)
    cycle, following = take.slice(0, F), take.slice(F, F + 1)
    assert loop_error(cycle, following) == ("LeftUpLeg", pytest.approx(12.0, abs=1e-3))
    closed = close_loop(cycle, following).rotations[:, joint]
    got = 2 * np.arctan2(closed[:, 2], closed[:, 3])
    assert np.allclose(got, swing[:F], atol=1e-5)
