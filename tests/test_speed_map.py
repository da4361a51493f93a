"""Speed maps and the motion graph of the built-in animals: the issue-4 figures, and the queries."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from synth_core.build import ik
from synth_core.build.animals import (
    build_builtin,
    clip_glide,
    clip_strict_skate,
    footfall_gaps,
    map_positions,
    report,
    sync_frames,
)
from synth_core.build.artifact import Library
from synth_core.build.motion_graph import HUBS, MotionGraph, Transition
from synth_core.build.speed_map import (
    FASTEST,
    STRAIGHT,
    SpeedRange,
    build_speed_map,
    default_ranges,
    relocate_root,
)
from synth_core.build.straight_crossings import ease_paws
from synth_core.motion import quat
from synth_core.runtime.bank import library_ground
from tests.helpers.motion import PEAK_JOINT_SPEED

ANIMALS = ("horse", "dog")


@pytest.fixture(scope="module")
def libraries() -> dict[str, Library]:
    return {animal: build_builtin(animal) for animal in ANIMALS}


@pytest.fixture(scope="module")
def figures(libraries: dict[str, Library]) -> dict[str, dict]:
    return {animal: report(lib) for animal, lib in libraries.items()}


@pytest.mark.parametrize("animal", ANIMALS)
def test_every_gait_meets_the_speed_map_figures(figures: dict, animal: str) -> None:
    for gait, f in figures[animal]["gaits"].items():
        assert f["clips"] >= 55, gait
        assert f["footfall_preserved"] == 1.0, gait
        assert f["skate_mm_mean"] <= 0.5, gait
        assert f["speed_error_pct_max"] <= 1.0, gait
        assert f["max_limb_stretch_pct"] <= 3.0, gait


@pytest.mark.parametrize("animal", ANIMALS)
def test_clips_keep_the_source_frames_and_contacts_and_adjacent_ranges_overlap(
        libraries: dict[str, Library], animal: str) -> None:
    lib = libraries[animal]
    gaits = list(lib.maps)
    assert gaits == ["walk", "trot", "canter", "gallop"]
    for gait, m in lib.maps.items():
        shape = (m.n_clips, m.n_frames)
        assert m.rotations.shape[:2] == shape and m.root_pos.shape[:2] == shape
        assert m.speeds[0] < m.source_speed < m.speeds[-1], gait
        assert np.all(np.diff(m.speeds) > 0)
    for slow, fast in zip(gaits[:-1], gaits[1:], strict=True):
        assert lib.maps[slow].speeds[-1] > lib.maps[fast].speeds[0], (slow, fast)


@pytest.mark.parametrize("animal", ANIMALS)
def test_no_speed_map_clip_pops(libraries: dict[str, Library], animal: str) -> None:
    """Seam included. A slow horse gallop once flipped its elbow 80 degrees in one frame where the
    source's forearm-and-carpus swung past the upper arm's line."""
    for gait, m in libraries[animal].maps.items():
        q = quat.make_continuous(m.rotations.astype(np.float64), axis=1)
        q = quat.make_continuous(np.concatenate([q, q[:, :1]], axis=1), axis=1)
        speed = np.degrees(quat.angle(quat.mul(quat.inv(q[:, :-1]), q[:, 1:]))) * m.fps
        assert speed.max() <= PEAK_JOINT_SPEED[animal], (gait, float(speed.max()))


def test_footfall_measure_catches_a_clip_that_lands_out_of_order(libraries: dict[str, Library]) -> None:
    """The motion's plants stay where they are; the annotation it is judged against says LF lands
    a quarter stride later than it does."""
    m = libraries["horse"].maps["trot"]
    pos = map_positions(m)
    assert footfall_gaps(m, pos).max() <= sync_frames(m.n_frames)
    moved = m.contacts.copy()
    moved[:, 0] = np.roll(moved[:, 0], m.n_frames // 4)
    assert footfall_gaps(replace(m, contacts=moved), pos).min() > sync_frames(m.n_frames)


@pytest.mark.parametrize("gait", ["walk", "gallop"])
def test_fast_strides_lower_the_body_instead_of_stretching_legs(gait: str) -> None:
    from synth_core.builtin.clips import build_clips

    source = build_clips("horse")[gait]
    sm = build_speed_map(source, source.speed_mps() * np.array([1.0, FASTEST]))
    assert np.all(sm.stretch == 1.0)
    limit = np.clip(ik.extension(source.skeleton, source.root_pos, source.rotations).max(axis=0), *STRAIGHT)
    assert np.all(ik.extension(sm.skeleton, sm.root_pos[1], sm.rotations[1]) <= limit + 1e-4)
    assert np.abs(sm.root_pos[0, :, 1] - source.root_pos[:, 1]).max() < 0.002  # own speed: ~no sink
    sink = source.root_pos[:, 1] - sm.root_pos[1, :, 1]
    assert 0.005 < sink.max() < 0.03 * source.skeleton.leg_length() and sink.min() >= 0.0
    # Eased around the loop: it moves the body no faster than the gait's own bob (+2 mm/frame).
    bob = np.abs(np.diff(source.root_pos[:, 1])).max()
    assert np.abs(np.diff(np.append(sink, sink[0]))).max() < bob + 0.002
    assert sm.clip(1).speed_mps() == pytest.approx(FASTEST * source.speed_mps(), rel=1e-3)


def test_root_relocation_scales_ground_steps_keeps_heights_and_the_first_frame() -> None:
    rng = np.random.default_rng(0)
    root = np.cumsum(rng.uniform(0.0, 0.02, (40, 3)), axis=0)
    new = relocate_root(root, np.array([0.5, 1.0, 1.3]))
    assert np.allclose(new[:, 0], root[0])
    assert np.allclose(new[:, :, 1], root[:, 1])
    step = np.linalg.norm(np.diff(root[:, [0, 2]], axis=0), axis=-1)
    for r, clip in zip([0.5, 1.0, 1.3], new, strict=True):
        assert np.allclose(np.linalg.norm(np.diff(clip[:, [0, 2]], axis=0), axis=-1), r * step)


def test_plants_move_along_the_stride_by_the_root_shift(libraries: dict[str, Library]) -> None:
    """Paper step 2: a plant's new place is its old one plus d_c along the stride of that foot."""
    from synth_core.builtin.clips import build_clips

    trot = build_clips("horse")["trot"]
    own = trot.speed_mps()
    sm = build_speed_map(trot, [own * 2 / 3, own, own * 4 / 3])
    # Own speed: (almost) unchanged, but where a paw's joint passes through straight faster than
    # a stride rate can play (straight_crossings: the hind fetlocks' lift-offs, eased a degree).
    eased = ease_paws(trot.skeleton, trot.rotations, ik.limb_rigs(trot.skeleton), True, trot.contacts)
    kept = ~np.any(eased != trot.rotations, axis=(1, 2))
    assert 0 < kept.sum() < len(kept)
    assert np.allclose(sm.rotations[1][kept], trot.rotations[kept], atol=2e-4)
    feet = map_positions(sm)[:, :, sm.skeleton.foot_joints]
    assert not sm.contacts[[0, -1], 1].any()  # RF's plant lies inside the clip (no wrap)
    for i in (0, 2):
        planted = sm.contacts[:, 1]
        moved = feet[i][planted, 1] - feet[1][planted, 1]
        shift = sm.root_pos[i, planted] - sm.root_pos[1, planted]
        # Across one plant the foot is pinned: it moves by the root's shift at the plant's middle,
        # so within a frame of the root's own shift there and always along +Z (the stride).
        assert np.allclose(moved[:, 0], 0.0, atol=1e-4) and np.allclose(moved[:, 1], 0.0, atol=1e-4)
        assert np.sign(moved[:, 2]).tolist() == np.sign(shift[:, 2]).tolist()
        assert np.abs(moved[:, 2] - shift[:, 2]).max() < np.abs(np.diff(sm.root_pos[i, :, 2])).max() * 6


def test_default_ranges_overlap_and_are_configurable() -> None:
    ranges = default_ranges({"walk": 1.0, "trot": 3.0, "canter": 5.0, "gallop": 10.0}, count=55)
    assert all(r.count == 55 for r in ranges.values())
    assert ranges["walk"].high > ranges["trot"].low  # trot would start at 1.5: pulled down to overlap
    assert ranges["canter"].high > ranges["gallop"].low
    assert SpeedRange(1.0, 2.0, 11).delta == pytest.approx(0.1)
    with pytest.raises(ValueError, match="0 < low <= high"):
        SpeedRange(2.0, 1.0)


def graph_of(lib: Library) -> MotionGraph:
    return lib.graph


def test_graph_nodes_edges_and_connection_both_ways(libraries: dict[str, Library]) -> None:
    g = graph_of(libraries["horse"])
    assert g.nodes == list(HUBS)
    assert g.n_edges == 4 * 60 + 1 + 8
    assert [t.name for t in g.route("static", "gallop")] == ["static2walk", "walk2trot", "trot2canter",
                                                            "canter2gallop"]
    assert [t.name for t in g.route("gallop", "static")] == ["gallop2canter", "canter2trot", "trot2walk",
                                                            "walk2static"]


def test_graph_queries_at_range_edges_and_in_overlaps(libraries: dict[str, Library]) -> None:
    g = graph_of(libraries["horse"])
    walk, trot = g.maps["walk"], g.maps["trot"]
    # Bracketing: exact clip speeds, between two clips, and clamped outside the range.
    assert g.bracket("walk", float(walk.speeds[0])) == (0, 1, 0.0)
    assert g.bracket("walk", float(walk.speeds[-1]))[1:] == (walk.n_clips - 1, 1.0)
    i, j, w = g.bracket("walk", float(0.25 * walk.speeds[3] + 0.75 * walk.speeds[4]))
    assert (i, j) == (3, 4) and w == pytest.approx(0.75)
    assert g.bracket("walk", 0.0)[2] == 0.0 and g.bracket("walk", 99.0)[2] == 1.0
    # Coverage: overlaps list both gaits; the top of the gallop and beyond.
    overlap = 0.5 * (trot.speeds[0] + walk.speeds[-1])
    assert g.gaits_covering(overlap) == ["walk", "trot"]
    assert g.gaits_covering(0.0) == ["static"]
    assert g.gaits_covering(float(g.maps["gallop"].speeds[-1])) == ["gallop"]
    assert g.gaits_covering(50.0) == []
    # Next gait: stay while covered (also in an overlap), else one hub toward the speed.
    assert g.next_gait("walk", overlap) == "walk" and g.next_gait("trot", overlap) == "trot"
    assert g.next_gait("static", 9.0) == "walk"
    assert g.next_gait("walk", 9.0) == "trot"
    assert g.next_gait("gallop", 0.0) == "canter"
    assert g.next_gait("gallop", 50.0) == "gallop"


def test_graph_rejects_bad_hubs_and_reports_a_broken_route(libraries: dict[str, Library]) -> None:
    maps = libraries["dog"].maps
    with pytest.raises(ValueError, match="adjacent"):
        MotionGraph(maps, {"walk2canter": Transition("walk2canter", "walk", "canter", False)})
    broken = MotionGraph(maps, {"static2walk": Transition("static2walk", "static", "walk", False)})
    assert not broken.connected("static", "trot")
    with pytest.raises(ValueError, match="no transition from walk toward trot"):
        broken.route("static", "trot")


GLIDE_BAR = 0.10  # issue 27: near-ground glide, the real MANN dog's 0.066-0.106
STRICT_SKATE_BAR_MM = 3.0  # issue 27: strict plant skate p95, the edge suite's target


def test_the_dogs_slowed_clips_do_not_skim_the_ground(libraries: dict[str, Library]) -> None:
    """Issue 27: feet leave and reach the ground like the real dog's at every speed of the speed
    maps. A slowed stride used to keep its source's ground speed near the ground (the built-in
    dog's slowest canter and gallop clips glided 0.117 and 0.121); now its near-ground speed
    shrinks with the step, and no clip of either animal glides more than the real dog does."""
    for animal, lib in libraries.items():
        ground = library_ground(lib)
        for gait, speed_map in lib.maps.items():
            glide = clip_glide(speed_map, ground)
            assert glide.max() <= GLIDE_BAR, (animal, gait, glide.max(), int(glide.argmax()))


def test_no_speed_map_clip_drags_a_foot_along_the_ground(libraries: dict[str, Library]) -> None:
    """Issue 27: a foot within 1 cm of the ground for 3+ frames does not move, whatever the
    annotation says, at every speed of every speed map. The built-in dog's paws came down still
    moving forward 8-10 mm in their last frame, just under 1 cm up: its fastest gallop clip
    skated 10.3 mm p95, canter 7.2, trot 5.2 (the horse's, higher at that frame, 0)."""
    for animal, lib in libraries.items():
        ground = library_ground(lib)
        for gait, speed_map in lib.maps.items():
            skate = clip_strict_skate(speed_map, ground)
            assert skate.max() <= STRICT_SKATE_BAR_MM, (animal, gait, skate.max(), int(skate.argmax()))
