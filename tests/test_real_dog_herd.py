"""A library built from the real dog (tests/fixtures/mann_dog.toml), its clips and a 30-character
herd, measured after FK against issue 28's targets: no limb flip, no paw jump over 6 cm,
penetration <= 2 mm, floating <= 1 cm while slower than 0.1 m/s, and speed-map touchdowns that
drop no further in their last frame than the source mocap's own."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from synth_core import UP_AXIS
from synth_core.build import ik
from synth_core.build.animals import clip_glide, map_positions
from synth_core.build.artifact import Library
from synth_core.build.generated_transitions import walk_frames
from synth_core.build.manifest import build_from_manifest, gait_cycles
from synth_core.build.motion_graph import HUBS
from synth_core.motion import contacts as C
from synth_core.quality import edge, evaluate
from synth_core.quality import herd_sim as crowd
from synth_core.quality import metrics as M
from synth_core.quality.evaluate import edge_suite, feet_after_fk, world_positions
from synth_core.quality.reference import library_reference
from synth_core.runtime.bank import (
    STATIC,
    Bank,
    build_bank,
    library_ground,
    standing_heights,
    table_positions,
)
from synth_core.runtime.live import LOW_LATENCY_MS, LiveSynth
from synth_core.runtime.plan import MARGIN, STILL_S
from synth_core.runtime.synthesis import Options, Result, synthesize
from tests.helpers.live import feed, joined
from tests.helpers.mocap import MANN_DIR
from tests.helpers.motion import clip_flips, looped, stops

FIXTURE = Path(__file__).parent / "fixtures" / "mann_dog.toml"
pytestmark = pytest.mark.skipif(not MANN_DIR.is_dir(), reason="real dog mocap not found beside the repo "
                                "(../shared/mocap/mann_dog)")
JUMP_M = 0.06  # issue 28: no one-frame paw jump over 6 cm
BENT = np.sin(np.radians(10.0))  # a hinge bent less than this has no side to flip


@pytest.fixture(scope="module")
def mann() -> Library:
    return build_from_manifest(FIXTURE)


@pytest.fixture(scope="module")
def herd(mann: Library) -> tuple[Bank, Result, np.ndarray]:
    """30 dogs of the crowd-sim herd (stand, speed up into the gallop, slow to a walk)."""
    bank = build_bank(mann)
    paths = crowd.simulate(30, 900, seed=1, top=5.0)
    result = synthesize(bank, paths, 60.0, options=Options(seed=1, scale_range=(0.8, 1.2)))
    return bank, result, world_positions(bank, result).astype(np.float64)


def hinge_flips(positions: np.ndarray, rigs: tuple[ik.LimbRig, ...]) -> np.ndarray:
    """Per leg, frames where the IK hinge (elbow, stifle) bends the other way than the frame
    before, both bent: thigh x shin reversing. ``positions (..., F, J, 3)`` -> (..., F-1, 4)."""
    out = []
    for rig in rigs:
        thigh = positions[..., rig.hinge, :] - positions[..., rig.upper, :]
        shin = positions[..., rig.ankle, :] - positions[..., rig.hinge, :]
        lengths = np.linalg.norm(thigh, axis=-1) * np.linalg.norm(shin, axis=-1)
        axis = np.cross(thigh, shin) / lengths[..., None]
        bent = np.linalg.norm(axis, axis=-1) >= BENT
        turned = np.sum(axis[..., 1:, :] * axis[..., :-1, :], axis=-1) < 0
        out.append(turned & bent[..., 1:] & bent[..., :-1])
    return np.stack(out, axis=-1)


def paw_jumps(feet: np.ndarray) -> np.ndarray:
    """How much longer each paw's one-frame step is than its steps just before and after (m),
    ``(..., F-3, 4)``: the edge suite's one-frame jump (``metrics.one_frame_jumps_mm``). Not the
    second difference of position: that reads a paw slowing to its plant as a jump, and the real
    dog's own gallop cycle scores 7.1 cm by it (1.3-2.5 cm by this one, every gait)."""
    return np.asarray(M.one_frame_jumps_mm(feet)) / 1000.0


def test_the_herd_never_flips_a_limb(mann: Library, herd: tuple[Bank, Result, np.ndarray]) -> None:
    bank, _, positions = herd
    assert not hinge_flips(positions, ik.limb_rigs(bank.skeleton)).any()


def test_the_herd_stands_on_the_ground(herd: tuple[Bank, Result, np.ndarray]) -> None:
    """Penetration <= 2 mm; while a dog is slower than 0.1 m/s its lowest paw is within 1 cm of
    the ground (each take's floor and paw markers differ: the clips are put on one ground)."""
    bank, result, positions = herd
    heights = positions[..., bank.skeleton.foot_joints, UP_AXIS] - result.path[..., UP_AXIS, None]
    assert heights.min() >= -0.002
    root = result.root_pos[..., [0, 2]].astype(np.float64)
    slow = np.linalg.norm(np.gradient(root, axis=1), axis=-1) * bank.fps < 0.1
    assert slow.sum() > 1000  # the herd does stand and slow down
    assert heights.min(axis=-1)[slow].max() <= 0.01


def test_the_herd_has_no_paw_jump_over_6_cm(herd: tuple[Bank, Result, np.ndarray]) -> None:
    bank, _, positions = herd
    assert paw_jumps(positions[..., bank.skeleton.foot_joints, :]).max() <= JUMP_M


def test_the_librarys_clips_never_flip_a_limb_or_jump(mann: Library) -> None:
    """Every speed-map clip (looped) and transition: no hinge flip and no leg locked straight
    (a straight leg has no bend side: the synthesis's foot lock then flipped the real dog's
    elbow for a frame); no paw jump over 6 cm."""
    rigs = ik.limb_rigs(mann.skeleton)
    feet = mann.skeleton.foot_joints
    for gait, speed_map in mann.maps.items():
        positions = looped(map_positions(speed_map), speed_map.root_pos)
        assert not hinge_flips(positions, rigs).any(), gait
        assert bends(positions, rigs).min() > ik.HINGE_AXIS_MIN_SIN, gait
        assert paw_jumps(positions[:, :, feet]).max() <= JUMP_M, gait
    for name, clip in mann.transitions.items():
        positions = np.asarray(clip.positions(), np.float64)
        assert not hinge_flips(positions, rigs).any(), name
        assert bends(positions, rigs).min() > ik.HINGE_AXIS_MIN_SIN, name
        assert paw_jumps(positions[:, feet]).max() <= JUMP_M, name


def test_the_librarys_clips_flip_no_joint_at_their_own_rate(mann: Library) -> None:
    """Issue 28: no limb flip after FK. The wrist passes through straight at lift-off and
    touchdown, in the real dog's mocap at up to 60-70 deg in a frame; the speed maps' gallop
    inherited it (4 flips at the wrist before ``straight_crossings`` slowed such passages; 1 in
    canter2gallop while a passage next to a flat stance could only be slowed symmetrically)."""
    flips = clip_flips(mann, 1)
    assert not any(flips.values()), flips


@pytest.mark.xfail(strict=True, reason="60 left (126 before passages next to a flat stance were slowed "
                   "on their swing side), all at the wrist: trot 24, gallop 21, canter 8, walk 4, "
                   "gallop2canter 2, trot2canter 1. Passages are eased to 10 deg a frame where the "
                   "direction reverses within two frames, but the leg's second solve moves the forearm, "
                   "slow sideways passages turn over three frames, and a flat stance's last frame keeps its "
                   "bend (a one-sided window: the frame after the next may straddle it)")
def test_the_librarys_clips_flip_no_joint_skipping_a_frame(mann: Library) -> None:
    """A character faster than its clips' rate (a small one's Froude tempo, up to MAX_RATE 1.6)
    is shown whole clip frames at touchdowns and lift-offs: now and then one is skipped."""
    flips = clip_flips(mann, 2)
    assert not any(flips.values()), flips


@pytest.fixture(scope="module")
def hard_turns(mann: Library) -> dict[str, Any]:
    """The edge scenarios where the real dog's transitions play fastest: a gallop's corners and
    U-turns, hard acceleration and braking, sizes 0.5-2.0."""
    return edge_suite(build_bank(mann), names=["corner_gallop", "uturn_gallop", "accel_brake", "mixed_sizes"])


def test_the_foot_lock_flips_no_wrist(hard_turns: dict[str, Any]) -> None:
    """Issue 28: no limb flip after FK, in the scenarios where the real dog flipped most (9-10
    each, 73 over the suite, every one at the wrist): transitions played by distance at 2-3x
    their clip while the lock holds a paw behind the body, the elbow straightened, the forearm
    swinging over the paw at lift-off. The IK keeps each ankle's side from frame to frame."""
    for name, scenario in hard_turns["scenarios"].items():
        assert scenario["figures"]["limb_flips"] == 0, (name, scenario["figures"]["limb_flips_at"])


def test_the_low_latency_mode_flips_no_wrist(mann: Library) -> None:
    """Issue 28's no limb flip, in the low-latency live mode (issue 31): its windows are a frame or
    two, and the IK kept each ankle's bend side only from frame to frame within a window: none.
    Each window now starts from the side of the last frame sent (kernels.Posed.sides): the real
    dog's gallop corners and U-turns flipped 19 and 20 wrists, its edge suite 3 -> 14 of 29."""
    report = edge_suite(build_bank(mann), names=["corner_gallop", "uturn_gallop"], live=True,
                        latency_ms=LOW_LATENCY_MS)
    for name, scenario in report["scenarios"].items():
        assert scenario["figures"]["limb_flips"] == 0, (name, scenario["figures"]["limb_flips_at"])


def test_no_paw_jumps_over_6_cm_where_transitions_play_fastest(hard_turns: dict[str, Any]) -> None:
    """Issue 28's 6 cm, after FK (the edge suite's one-frame jump): accel_brake read 7.41 cm
    before a swing a ramp leaves jumping was retimed along its path (jump_kernels.ease_jumps: a
    paw braked to its plant faster than a ramp can ease)."""
    for name, scenario in hard_turns["scenarios"].items():
        assert scenario["figures"]["jump_cm_max"] <= JUMP_M * 100, (name, scenario["figures"]["jump_cm_max"])


def test_the_root_stays_on_the_path_through_a_tight_turn(hard_turns: dict[str, Any]) -> None:
    """Issue 27's 1 cm, after FK and time mapping: the real dog's clips surge (the root leads and
    lags steady progress by up to 4 cm a stride), and in a 0.5 m U-turn at a gallop the body's
    heading trails the path's by up to ~80 deg (its turn rate is capped): a surge along the heading
    put the root 2.5 cm off the path; along the path's own way (heading_kernels.turn) it stays on it."""
    for name, scenario in hard_turns["scenarios"].items():
        assert scenario["figures"]["path_cm_max"] <= 1.0, (name, scenario["figures"]["path_cm_max"])


def test_a_pivot_walks_round_on_two_paws(mann: Library) -> None:
    """Issue 27's walk support, after FK, where the real dog pivots on a 0.2 m circle at 0.15 m/s
    (turn_on_spot's third dog, under its slowest walk's 0.45 m/s): its start played by the hips'
    distance, a stance lasting a second and more while the body turned ~70 deg, a forepaw hung out
    of reach at its end -- 19 frames on one paw. A walk's stride (and its start) now keeps pace with
    the paws the turn sweeps round the hips (plan_kernels._turning)."""
    bank = build_bank(mann)
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    sc = edge.scenarios(gaits, bank.fps, 0, ["turn_on_spot"])[0]
    result = synthesize(bank, sc.positions, bank.fps, scales=sc.scales, options=Options(seed=0))
    down = feet_after_fk(bank, result, library_reference(bank)).down[2]
    walking = result.gait[2] == HUBS.index("walk")
    assert walking.sum() > 0.5 * len(walking)  # it walks round, not stands
    assert (down[walking].sum(axis=-1) >= 2).all(), np.flatnonzero(walking & (down.sum(axis=-1) < 2))


def test_a_trotting_corner_keeps_two_paws_down_through_its_walk_to_trot(mann: Library) -> None:
    """Issue 27's walk support, after FK, where the real dog starts into a trotting corner and
    U-turn (1.5 m/s, its body turning up to 170 deg/s): its walk -> trot, played by the hips'
    distance, stood on a forepaw the turn swept 43 cm under it -- out of reach at both ends of its
    stance, a walk on one paw as it ended (0.9971 and 0.9941 of walk frames with two down). A
    transition now keeps pace with the paws' distance there too (plan_kernels._walk_on)."""
    report = edge_suite(build_bank(mann), names=["corner_trot", "uturn_trot"])
    for name, scenario in report["scenarios"].items():
        share = scenario["figures"]["walk_support_share"]
        assert evaluate.passes("walk_support_share", share), (name, share)


def bends(positions: np.ndarray, rigs: tuple[ik.LimbRig, ...]) -> np.ndarray:
    """Sine of each IK hinge's bend, ``(..., F, 4)``."""
    out = []
    for rig in rigs:
        thigh = positions[..., rig.hinge, :] - positions[..., rig.upper, :]
        shin = positions[..., rig.ankle, :] - positions[..., rig.hinge, :]
        lengths = np.linalg.norm(thigh, axis=-1) * np.linalg.norm(shin, axis=-1)
        out.append(np.linalg.norm(np.cross(thigh, shin), axis=-1) / lengths)
    return np.stack(out, axis=-1)


def touchdown_drops(heights: np.ndarray, contacts: np.ndarray) -> np.ndarray:
    """Per foot, the largest fall (m) in the frame before a touchdown of a looped clip."""
    return np.array([max((heights[d - 1, k] - heights[d, k] for d in downs), default=0.0)
                     for k, downs in enumerate(C.touchdowns(contacts, cyclic=True))])


def test_speed_map_touchdowns_drop_no_further_than_the_source(mann: Library) -> None:
    """Issue 28: the exported speed-map clips dropped a paw 3-10 cm in the frame before it lands,
    the source's largest 1.6-4.6. Now no clip of any speed drops a paw further than its source
    cycle's largest drop (a paw that slid in at the ground in the source lands from the
    centimetre or so a paw clears the ground by, issue 27, not from further up)."""
    cycles = gait_cycles(FIXTURE)
    for gait, speed_map in mann.maps.items():
        source = cycles[gait]
        want = touchdown_drops(source.foot_positions()[..., UP_AXIS], source.contacts).max()
        heights = map_positions(speed_map)[:, :, mann.skeleton.foot_joints, UP_AXIS]
        got = np.stack([touchdown_drops(h, speed_map.contacts) for h in heights])
        assert np.all(got <= want + 0.001), (gait, got.max(axis=0), want)


def test_speed_map_paws_do_not_skim_the_ground(mann: Library) -> None:
    """Issue 27's glide bar (0.10) for every clip of every speed map, over the ground the
    synthesis stands the clips on. The slowest pace clips slid their paws along the ground at
    0.18 of the body's speed (now 0.095; trot 0.13 -> 0.10): the swing kept the source's ground speed near the
    ground at a third of the source's speed, and sank by the paw's late-stance rise."""
    ground = library_ground(mann)
    for gait, speed_map in mann.maps.items():
        glide = clip_glide(speed_map, ground)
        assert glide.max() <= 0.10, (gait, glide.max(), int(glide.argmax()))


def test_a_start_stands_where_the_idle_stands(mann: Library) -> None:
    """Issue 27: floating <= 1 cm while the body is slower than 0.1 m/s, after FK, as the edge
    suite measures it (over the paws' standing heights in the idle). A start (static2walk) is
    put on the ground by its own, mostly walking, plants: its standing frames stood 0.8-0.9 cm
    above the idle's, and every real dog of every edge scenario started 1.07 cm up."""
    suite = edge_suite(build_bank(mann), names=["cruise_straight", "stop_and_stand"])
    for name, scenario in suite["scenarios"].items():
        assert scenario["figures"]["floating_cm_max"] <= 1.0, name


def test_a_planted_paw_reads_on_its_sole(mann: Library) -> None:
    """Issue 27: the edge figures measure a paw's height over where it stands in the library's
    clips (its sole: the real dog's paw end sites stand 1-3 cm up). A paw the synthesis holds on
    a plant of a steady walk stands there: within 1 mm (the real dog's clips stand 2.7 mm over
    the bank's ground, which the reference took off twice: every planted paw read 2.7 mm up,
    and lifted off and landed a frame early and late against the strict plants' 1 cm)."""
    bank = build_bank(mann)
    ref = library_reference(bank)
    assert abs(bank.ground) > 0.001  # the case: clips whose ground is not at 0
    path = np.zeros((1, 400, 3), np.float32)
    path[0, :, 2] = np.arange(400) * float(np.mean(bank.speeds[1][[0, -1]])) / bank.fps
    result = synthesize(bank, path, bank.fps, options=Options(seed=0))
    fk = feet_after_fk(bank, result, ref)
    steady = (result.gait == 1) & (np.arange(400) > 200)[None]  # walking, past the start
    planted = fk.heights[steady][result.contacts[steady]]
    assert planted.size > 100
    assert np.abs(np.median(planted)) <= 0.001


def test_a_paw_leaving_the_ground_does_not_drag_along_it(mann: Library) -> None:
    """Issue 27: strict plant skate p95 <= 3 mm (feet within 1 cm for 3+ frames, their motion
    a frame), after FK, on the edge suite's walk corners. The real dog's paw end sites stay
    within 1 cm of the ground for 2-3 frames after lift-off while the paw rolls forward 2-4 cm a
    frame: played as is, the corner_walk herd's paws slid 10 mm p95 (its walk clips 5-13 mm),
    and over the true soles 5.5-5.8 mm where the pace's handover kept the lifting paw low (now
    held planted until its partner lands, and cleared as it lifts). The canters' first swing
    frame rose 8 mm while moving 5-15 mm, inside the 1 cm band (corner_canter 5.5, uturn_canter
    5.0, mixed_sizes 5.0 mm): a swing now rises over its first 15 % (footlock.CLEAR_UP)."""
    names = ["corner_walk", "uturn_walk", "corner_canter", "uturn_canter", "mixed_sizes"]
    suite = edge_suite(build_bank(mann), names=names)
    for name, scenario in suite["scenarios"].items():
        assert scenario["figures"]["strict_skate_mm_p95"] <= 3.0, name


def test_the_walk_keeps_two_paws_down(mann: Library) -> None:
    """Issue 27: a walk has >= 2 feet down in every frame. The real dog's pace hands over from one
    lateral pair to the other with one paw down for 1-4 frames (annotated; 1-2 by the strict
    plants' 1 cm), and its walk to trot, trot to walk and start did too: the edge suite read
    0.94-0.985. Every frame of the walk's speed map and of the transitions where they play as
    the walk has two down, and so has every walking frame after FK of a start, a stop and a
    trot and back (the turns and the scaled herd are the foot lock's and the tempo's)."""
    assert mann.maps["walk"].contacts.sum(axis=1).min() >= 2
    for name, clip in mann.transitions.items():
        walking = walk_frames(name, clip.n_frames)
        assert np.all(clip.contacts[walking].sum(axis=1) >= 2), name
    suite = edge_suite(build_bank(mann), names=["cruise_straight", "stop_and_stand", "stop_go"])
    for name, scenario in suite["scenarios"].items():
        assert scenario["figures"]["walk_support_share"] >= 1.0, name


def test_a_stop_inside_the_start_stands(mann: Library) -> None:
    """Issue 27: a stop settles into the idle, four feet down. The real dog's start (static ->
    walk, 2.3 s of its mocap, 1.1 m of walking) is longer than the walk before a stop in the
    edge suite's turn_on_spot; a start was let play on through a stop (it waits for the path to
    move, so it was never taken for a stand) and, played by distance, crept on over the second's
    stand with a hind paw 4.4 cm up, then two paws up. Now from a standing body's STILL_S and
    the idle's fade in, to the path moving again, the dog stands on four paws after FK."""
    bank = build_bank(mann)
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    sc = edge.scenarios(gaits, bank.fps, 0, ["turn_on_spot"])[0]
    paths = sc.positions[:2]  # (arrive, stop, leave; the third pivots without stopping)
    result = synthesize(bank, paths, bank.fps, scales=sc.scales[:2], options=Options(seed=0))
    fk = feet_after_fk(bank, result, library_reference(bank))
    checked = 0
    for c, stop, again in stops(paths):
        stood = slice(stop + round(STILL_S * bank.fps) + MARGIN, again)
        assert (result.gait[c, stood] == STATIC).all(), (c, stop)
        assert fk.down[c, stood].all(), (c, stop)
        checked += 1
    assert checked == 2


def test_a_transition_braked_to_a_crawl_does_not_creep(mann: Library) -> None:
    """Issue 27: no foot alone past its gait's longest stance. Braked from a canter to a crawl
    (the edge suite's brake_to_crawl), the real dog's canter -> trot played by distance at a
    crawl's pace and stood it on one paw 2.5 times its longest stance; it now gives way to the
    walk (plan.MIN_TRANSITION_RATE)."""
    suite = edge_suite(build_bank(mann), names=["brake_to_crawl"])
    assert suite["scenarios"]["brake_to_crawl"]["figures"]["single_support_ratio_max"] <= 1.0


APPROACH_FRAMES = 2  # the frames before a touchdown where the real dog's paw swept in low


def test_speed_map_paws_land_from_above(mann: Library) -> None:
    """Issue 27: strict plant skate p95 <= 3 mm (a foot within 1 cm of the ground for 3+ frames
    counts as standing, its motion a frame as skate). The real dog's paw sweeps in low before a
    touchdown, at a gallop 3-4 cm a frame within 1 cm of its plant (the speed-map clips' gallop
    read 30 mm p95). In the frames before each touchdown of every clip, a paw within 1 cm of its
    plant moves at most 3 mm a frame -- but where it is the second paw down (the pace's
    handover: it lands low, as the source does, so that two paws carry the walk)."""
    feet = mann.skeleton.foot_joints
    for gait, speed_map in mann.maps.items():
        F = speed_map.n_frames
        paws = looped(map_positions(speed_map), speed_map.root_pos)[:, :, feet]  # (N, F + 2, 4, 3)
        contacts = speed_map.contacts
        for k, downs in enumerate(C.touchdowns(contacts, cyclic=True)):
            for d in downs:
                d = int(d) if d >= APPROACH_FRAMES else int(d) + F
                for j in range(d - APPROACH_FRAMES, d):
                    if contacts[j % F].sum() - contacts[j % F, k] == 1:
                        continue  # the second support
                    above = paws[:, j, k, UP_AXIS] - paws[:, d, k, UP_AXIS]
                    step = np.linalg.norm((paws[:, j + 1, k] - paws[:, j, k])[:, [0, 2]], axis=-1)
                    assert not np.any((above < 0.01) & (step > 0.003)), (gait, k, j, above.min(), step.max())


def test_the_foot_lock_stretches_no_leg_past_the_clips_reach(mann: Library) -> None:
    """Issue 27: leg stretch <= 3 % past each leg's longest hip-to-paw reach in the library's own
    clips, after FK. The real dog's hind legs never straighten (their longest reach is 0.92 of
    their chain): a lock that let a leg reach 98 % of its chain stretched them 4.6-5.5 % in these
    (a hind paw held onto its plant at the gallop, at a walk's touchdown while braking, down a
    slope). Its limit is now the leg's own longest reach and a share of the target."""
    suite = edge_suite(build_bank(mann), names=["cruise_straight", "accel_brake", "slope_down_30"])
    for name, scenario in suite["scenarios"].items():
        assert scenario["figures"]["stretch_pct_max"] <= 3.0, name


def test_the_real_dogs_plants_hold_where_its_transitions_meet_its_gaits(mann: Library) -> None:
    """Issue 27's strict plant skate (p95 <= 3 mm) and issue 33's planted height on a terrain
    (p95 <= 5 mm), after FK. A transition's swings before its first plant and after its last
    skimmed the ground while moving (cruise 10.0 mm, jitter 11.1, a trotting corner 7.2), and
    its plants stood at another take's paw height (8.3 mm on every terrain): docs/real_dog_plants.md."""
    names = ["cruise_straight", "corner_trot", "jitter_10hz", "slope_down_30"]
    suite = edge_suite(build_bank(mann), names=names)
    for name, scenario in suite["scenarios"].items():
        figures = scenario["figures"]
        assert figures["strict_skate_mm_p95"] <= 3.0, (name, figures["strict_skate_mm_p95"])
        assert figures["planted_ground_mm_p95"] <= 5.0, (name, figures["planted_ground_mm_p95"])


def test_a_generated_transition_stands_on_the_soles_of_the_gaits_it_joins(mann: Library) -> None:
    """A transition the data lacks is two gaits' clips cross-faded: its paws stand at the first
    gait's height where it starts and at the second's where it ends (within 1 mm). The second
    clip's root was moved to the first's last position, height included, which stood the real
    dog's trot2canter 15 mm over the canter's soles and its canter2gallop 13 mm under."""
    bank = build_bank(mann)
    soles = library_reference(bank).soles
    standing = standing_heights(bank, table_positions(bank))
    generated = [(a, b) for (a, b) in bank.transitions if f"{HUBS[a]}2{HUBS[b]}" in mann.generated]
    assert generated, "the fixture has generated transitions"
    for a, b in generated:
        piece = bank.transitions[(a, b)]
        first, last = standing[piece.offset], standing[piece.offset + piece.frames - 1]
        assert np.abs(first - soles[a]).max() <= 1e-3, (HUBS[a], HUBS[b], first, soles[a])
        assert np.abs(last - soles[b]).max() <= 1e-3, (HUBS[a], HUBS[b], last, soles[b])


@pytest.mark.parametrize("fps", [60.0, 30.0])
def test_live_roots_are_the_batch_roots_where_the_clips_surge(mann: Library, fps: float) -> None:
    """The real dog's clips surge (the built-in animals' do not, so tests/test_live.py cannot see
    it), along the path's way (heading_kernels.turn: each frame from its neighbours on the path).
    Live, points arriving in random pieces and frame blocks cut anywhere, the exact mode's roots
    and rotations are the batch's (no foot lock: the plan and the render alone); at 30 fps, every
    other library frame's, as tests/test_live.py has them."""
    bank = build_bank(mann)
    assert np.abs(bank.surge).max() > 0.02  # (in the library's unit: the real dog's 4.4 cm)
    herd = crowd.simulate(12, int(700 * fps / 60), seed=3, top=5.0, fps=fps)
    batch = synthesize(bank, herd, fps, options=Options(seed=5, scale_range=(0.8, 1.2), foot_lock=False))
    assert batch.resample_rate == 1.0
    live = LiveSynth(bank, len(herd), fps, seed=5, scale_range=(0.8, 1.2), foot_lock=False)
    root, rot, _, _ = joined(feed(live, herd)[0])
    step = int(bank.fps // fps)
    want_root, want_rot = batch.root_pos[:, ::step], batch.rotations[:, ::step]
    t = slice(0, root.shape[1] - 3 * bank.mean_cycle // step)  # (the batch's last segments: test_live)
    tol = 1e-6 if step == 1 else 1e-4  # (tests/test_live.py's, each rate)
    np.testing.assert_allclose(root[:, t], want_root[:, t], atol=tol)
    np.testing.assert_allclose(rot[:, t], want_rot[:, t], atol=tol)
