"""Stopping (issue 27): a character whose path stops settles into the idle stance -- four feet
down, the body still -- within about one stride, judged after FK on the output motion, in the
batch and in a live session; a pause goes through standing and starting again leaves it by the
static -> walk transition."""

from __future__ import annotations

import dataclasses
import functools
import zlib

import numpy as np
import pytest

from synth_core.build.animals import build_builtin
from synth_core.build.motion_graph import HUBS
from synth_core.motion.skeleton import forward_kinematics
from synth_core.quality import edge, evaluate
from synth_core.quality.reference import library_reference
from synth_core.runtime.bank import STATIC, Bank, build_bank
from synth_core.runtime.live import LiveSynth
from synth_core.runtime.plan import decision_step, lookahead
from synth_core.runtime.synthesis import Options, Result, synthesize
from tests.helpers.motion import stops

WALK = HUBS.index("walk")
ANIMALS = ["horse", "dog"]


@functools.lru_cache(maxsize=2)
def animal_bank(animal: str) -> Bank:
    return build_bank(build_builtin(animal))


def stop_scenario(bank: Bank, name: str) -> edge.Scenario:
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    return edge.scenarios(gaits, bank.fps, 0, [name])[0]


def idle_foot_sway(bank: Bank) -> float:
    """How far (m, over the ground) the idle clip's own feet move from its first frame: an idle
    shifts its weight, so a standing foot without the foot lock moves as much."""
    idle = slice(bank.idle.offset, bank.idle.offset + bank.idle.frames)
    root = np.zeros((bank.idle.frames, 3), np.float32)
    pos, _ = forward_kinematics(bank.skeleton, root, bank.poses[idle])
    feet = np.asarray(pos, np.float64)[:, bank.skeleton.foot_joints][..., [0, 2]]
    return float(np.linalg.norm(feet - feet[:1], axis=-1).max())


def stride_before(bank: Bank, result: Result, c: int, stop: int) -> int:
    """The stride period (frames) of the gait the character had as it began to brake."""
    gait = int(result.gait[c, max(stop - int(bank.fps), 0)])
    return int(bank.gaits[gait].frames)


def assert_settles(bank: Bank, result: Result, positions: np.ndarray) -> int:
    """Every stop of ``positions`` long enough: from one stride after it on, the character
    stands (the idle), all four feet strictly planted after FK, and its body still (root over
    the ground within 1 cm of where it is a stride after the stop and moving under 1 mm a frame,
    as the idle breathes; every foot within the idle clip's own sway + 5 mm) -- up to the plan's
    look-ahead before it moves again (a start is anticipated); returns
    how many stops were checked."""
    fk = evaluate.feet_after_fk(bank, result, library_reference(bank))
    sway = idle_foot_sway(bank) + 0.005
    checked = 0
    for c, stop, again in stops(positions):
        stride = stride_before(bank, result, c, stop)
        # Gaits are chosen on the speed ahead: a start may begin that far before the path moves.
        ahead = lookahead(bank.mean_cycle) + decision_step(bank.mean_cycle)
        end = again - ahead if again < positions.shape[1] else again
        settled = stop + stride
        if end <= settled:
            continue
        t = slice(settled, end)
        assert (result.gait[c, t] == STATIC).all(), (c, stop)
        down = fk.down[c, t].all(axis=-1)
        assert down.all(), (c, stop, settled + int(np.argmin(down)))
        assert np.abs(fk.heights[c, t]).max() < 0.01
        root = result.root_pos[c, t].astype(np.float64)
        body = np.linalg.norm((root - root[0])[:, [0, 2]], axis=-1)  # (the idle breathes: up and down)
        body_step = np.linalg.norm(np.diff(root, axis=0), axis=-1)
        feet = np.linalg.norm(fk.feet[c, t] - fk.feet[c, settled], axis=-1)
        assert body.max() < 0.01 and body_step.max() < 0.001 and feet.max() < sway, (
            c, stop, body.max(), body_step.max(), feet.max())
        checked += 1
    return checked


@pytest.mark.parametrize("animal", ANIMALS)
def test_a_stop_settles_into_the_idle_within_a_stride(animal: str) -> None:
    """Stopping from a walk, a trot and a canter: before, the horse stood on two diagonal legs
    for the whole stand (its trot -> walk and walk -> static transitions play by distance, and a
    stopped path covers none)."""
    bank = animal_bank(animal)
    sc = stop_scenario(bank, "stop_and_stand")
    result = synthesize(bank, sc.positions, bank.fps, scales=sc.scales, options=Options(seed=0))
    assert assert_settles(bank, result, sc.positions) == len(sc.positions)


@pytest.mark.parametrize("animal", ANIMALS)
def test_a_live_session_settles_as_the_batch(animal: str) -> None:
    """The same stops fed to a live session in random ticks: its motion settles as well. (The
    plan's, without the live foot lock: with it, a standing foot is moved 4-8 cm once or twice
    over the stand, where the batch's lock keeps it -- the live lock's, not the plan's.)"""
    bank = animal_bank(animal)
    sc = stop_scenario(bank, "stop_and_stand")
    batch = synthesize(bank, sc.positions, bank.fps, scales=sc.scales, options=Options(seed=0))
    live = LiveSynth(bank, len(sc.positions), bank.fps, scales=sc.scales, seed=0, foot_lock=False)
    rng = np.random.default_rng(1)
    windows = []
    i = 0
    while i < sc.positions.shape[1]:
        n = int(rng.integers(1, 45))
        windows.append(live.append(sc.positions[:, i:i + n]))
        i += n
    windows.append(live.finish())
    sent = [w for w in windows if w is not None]
    root, rotations, gait, contacts = (np.concatenate([getattr(w, f) for w in sent], axis=1)
                                       for f in ("root_pos", "rotations", "gait", "contacts"))
    result = dataclasses.replace(batch, root_pos=root, rotations=rotations, gait=gait, contacts=contacts)
    assert assert_settles(bank, result, sc.positions) == len(sc.positions)


@pytest.mark.parametrize("animal", ANIMALS)
def test_a_pause_stands_and_starting_again_goes_through_static_to_walk(animal: str) -> None:
    """Stop-go with pauses of 0.3 s to 3 s: a pause long enough to settle settles (not a march on
    the spot), and every character leaves standing by the walk (static -> walk), never straight
    into a trot."""
    bank = animal_bank(animal)
    sc = stop_scenario(bank, "stop_go")
    result = synthesize(bank, sc.positions, bank.fps, scales=sc.scales, options=Options(seed=0))
    assert assert_settles(bank, result, sc.positions) >= 1
    for c in range(len(sc.positions)):
        g = result.gait[c]
        left = np.flatnonzero((g[:-1] == STATIC) & (g[1:] != STATIC))
        assert (g[left + 1] == WALK).all(), c
    for c, stop, again in stops(sc.positions):
        if again - stop > 2 * stride_before(bank, result, c, stop):
            assert (result.gait[c, stop:again] == STATIC).any(), (c, stop)


@pytest.mark.parametrize("animal", ANIMALS)
def test_a_creeping_path_is_walked_not_slid_over_standing_feet(animal: str) -> None:
    """Creeping at 0.05-0.4 m/s, below the slowest walk: the animal walks slowly (the walk's
    stride played slower, its feet keeping pace), never standing while its body slides on over
    pinned feet (before: the horse at 0.05 m/s stood for 12 s while its root slid 57 cm over its
    hooves). Judged after FK: over four feet down while the body is slow, the root moves over
    them no more than the edge suite's limit (a standing animal's weight shift), and the
    hooves are still planted where they are down."""
    bank = animal_bank(animal)
    sc = stop_scenario(bank, "creep")
    result = synthesize(bank, sc.positions, bank.fps, scales=sc.scales, options=Options(seed=0))
    figures = evaluate.edge_figures(bank, result, sc.reference, sc.positions.shape[1],
                                    library_reference(bank))
    for name in ("stand_drift_cm_max", "strict_skate_mm_p95", "glide_ratio", "stretch_pct_max"):
        assert evaluate.passes(name, figures[name]), (name, figures[name])


@pytest.mark.parametrize("animal", ANIMALS)
def test_an_agent_standing_with_a_simulators_jitter_stands(animal: str) -> None:
    """A standing agent whose simulator adds a millimetre or two of noise a frame (its root on
    the points sent, the noise's zig-zag and all) stands: the speed a gait is chosen on is the
    positions' smoothed, not the zig-zag's length (1 mm a frame read 0.07 m/s; such horses walked
    in 78% of their frames). Batch and live alike; after FK every foot stays within the idle's own
    sway. (Noisier still, 3-5 mm a frame, a dog reads as creeping, which it walks.)"""
    bank = animal_bank(animal)
    rng = np.random.default_rng(3)
    T = 600
    positions = np.zeros((4, T, 3))
    positions[:, :, 0] = np.arange(4)[:, None] * 3.0
    noise = np.array([0.0005, 0.001, 0.0015, 0.002])  # m a frame (sd), each character's
    positions[..., [0, 2]] += rng.normal(0.0, 1.0, (4, T, 2)) * noise[:, None, None]
    result = synthesize(bank, positions, bank.fps, options=Options(seed=0))
    assert (result.gait == STATIC).all(), np.mean(result.gait != STATIC, axis=1)
    live = LiveSynth(bank, len(positions), bank.fps, seed=0)
    windows = [w for i in range(0, T, 30) if (w := live.append(positions[:, i:i + 30])) is not None]
    windows += [w] if (w := live.finish()) is not None else []
    assert all((w.gait == STATIC).all() for w in windows)
    fk = evaluate.feet_after_fk(bank, result, library_reference(bank))
    moved = np.linalg.norm((fk.feet - fk.feet[:, :1])[..., [0, 2]], axis=-1)
    assert moved.max() < idle_foot_sway(bank) + 0.005


@pytest.mark.parametrize("animal", ANIMALS)
def test_a_transition_braked_to_a_crawl_gives_way_to_the_walk(animal: str) -> None:
    """Braking from a canter or a gallop to a crawl (0.15-0.5 m/s, the edge suite's
    brake_to_crawl): no stop, so nothing settled, and the transition under way, played by
    distance, crept (a dog's trot -> walk 3.4-4.1 s into the crawl; in other herds a dog on one
    hind paw 2.6 times its canter's longest stance, a horse on one foreleg for 1.5 s). A
    transition shown slower than MIN_TRANSITION_RATE of its pace gives way to the walk: once
    the path crawls, no transition plays past the plan's view of the speed (a decision step
    and its look-ahead), and after FK the walk keeps two feet down and nothing floats."""
    from synth_core.runtime.synthesis import plan, prepare_batch

    bank = animal_bank(animal)
    sc = stop_scenario(bank, "brake_to_crawl")
    options = Options(seed=0)
    prep, h, keys = prepare_batch(bank, sc.positions, bank.fps, sc.scales, options, None, None)
    row = plan(bank, prep, h, keys, options.margin).rows[..., 0] % (bank.mirror or np.iinfo(np.int32).max)
    first = min(p.offset for p in bank.transitions.values())
    playing = (row >= first) & (row < max(p.offset + p.frames for p in bank.transitions.values()))
    speed = np.linalg.norm(np.diff(sc.reference[..., [0, 2]], axis=1), axis=-1) * bank.fps
    view = lookahead(bank.mean_cycle) + decision_step(bank.mean_cycle)
    for c in range(len(row)):
        crawl = int(np.flatnonzero(np.abs(speed[c] - speed[c, -1]) > 1e-3)[-1]) + 1  # steady from here
        assert not playing[c, crawl + view:].any(), (c, crawl, np.flatnonzero(playing[c, crawl:])[-1])
    figures = evaluate.edge_suite(bank, names=["brake_to_crawl"])["scenarios"]["brake_to_crawl"]["figures"]
    assert figures["walk_support_share"] >= 1.0
    assert figures["floating_cm_max"] <= 1.0
    assert figures["gait_frames"]["walk"] > 0


def test_a_trot_stopped_short_does_not_freeze_its_transition_in_the_air() -> None:
    """A trotting horse stopped abruptly (0.06 s of braking, 0.375 s standing: a crowd
    simulator's stutter) for less than the plan's speed segments see (their average stays at a
    trot's) and less than STILL_S: the trot -> walk under way, played by distance, stalled over
    its flight -- all four hooves 3.6 cm up for 14 frames while the body stood (found on paths
    the suite had not tried). Its pace is read from the distance it plays by, so it gives way
    like a crawl's: after FK the lowest hoof is within issue 27's floating target (1 cm) while
    the body is slower than 0.1 m/s, whatever the stride's phase at the stop (8 characters,
    drawn phases)."""
    bank = animal_bank("horse")
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    v = edge.cruise(gaits, "trot")
    knots = [(0.0, 0.0), (0.3, v), (1.233, v), (1.293, 0.0), (1.668, 0.0), (1.728, v), (4.0, v)]
    s = edge.distance(edge.speed_profile(int(4 * bank.fps) + 1, bank.fps, knots), bank.fps)
    ground = edge.curve(s, [(3.0, 0.8, 8.0)], heading=0.73)
    positions = np.zeros((8, len(s), 3))
    positions[..., 0] = ground[:, 0] + edge.SPACING * np.arange(8)[:, None]
    positions[..., 2] = ground[:, 1]
    result = synthesize(bank, positions, bank.fps, scales=np.ones(8), options=Options(seed=0))
    ref = library_reference(bank)
    figures = evaluate.edge_figures(bank, result, positions, positions.shape[1], ref, None)
    assert figures["floating_cm_max"] <= 1.0


def stutter_herd(bank: Bank, seed: int, characters: int = 8) -> np.ndarray:
    """A crowd simulator's stop-and-go herd: each character at its walk's or trot's cruise
    speed, stopping every 0.6-1.5 s -- braking in 0.05-0.2 s, standing 0.1-0.5 s, starting as
    fast -- for 10 s, along a gentle curve; positions ``(C, F, 3)`` at the library's rate. (Seed 23:
    the herd of the audit, a checker of paths the edge suite had not tried, that found it.)"""
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in bank.speeds.items()}
    rng = np.random.default_rng([seed, zlib.crc32(b"stutter")])
    frames = int(10 * bank.fps) + 1
    positions = np.zeros((characters, frames, 3))
    for c in range(characters):
        v = edge.cruise(gaits, ("walk", "trot")[c % 2])
        knots, t = [(0.0, 0.0), (0.3, v)], 0.3
        while t < 10:
            t += float(rng.uniform(0.6, 1.5))
            brake = float(rng.uniform(0.05, 0.2))
            knots += [(t, v), (t + brake, 0.0)]
            t += brake + float(rng.uniform(0.1, 0.5))
            knots += [(t, 0.0), (t + brake, v)]
            t += brake
        s = edge.distance(edge.speed_profile(frames, bank.fps, knots), bank.fps)
        ground = edge.curve(s, [(3.0, 0.8, 8.0)], heading=float(rng.uniform(-np.pi, np.pi)))
        positions[c, :, 0] = ground[:, 0] + c * edge.SPACING
        positions[c, :, 2] = ground[:, 1]
    return positions


def stutter_floating_cm(animal: str, seed: int) -> float:
    """Issue 27's floating figure (cm, after FK) of :func:`stutter_herd`."""
    bank = animal_bank(animal)
    positions = stutter_herd(bank, seed)
    result = synthesize(bank, positions, bank.fps, scales=np.ones(len(positions)), options=Options(seed=0))
    ref = library_reference(bank)
    figures = evaluate.edge_figures(bank, result, positions, positions.shape[1], ref, None)
    return float(figures["floating_cm_max"])


@pytest.mark.parametrize("animal", [
    "horse",
    pytest.param("dog", marks=pytest.mark.xfail(strict=True, reason=(
        "not yet: a dog trotting into a 0.05-0.2 s brake plays its trot at its slowest clip's pace "
        "until the path stands, its flight a frame before the stop settles (2.05 cm, 1 of 24 "
        "characters; docs/edge_suite.md)"))),
])
def test_stuttering_herds_never_hang_every_foot_in_the_air(animal: str) -> None:
    """Stops shorter than the plan's speed segments see (0.7 s) and than STILL_S of standing: a
    gait whose segment still read a trot played on at its pace over the stop, trotting on the
    spot, its flight 1.8 cm up a frame before the stop settled (the horse in the audit's herd,
    seed 23; and a transition stood still over its flight: the test above). A path walked slower
    than a standing character's pace settles at once, as a stop does: after FK, issue 27's
    floating target (1 cm) while the body is slower than 0.1 m/s, in three herds."""
    assert max(stutter_floating_cm(animal, seed) for seed in (23, 31, 41)) <= 1.0
