"""A live session's points may come with the simulator's velocity (issue 31): the low-latency mode
reads it for speed (so gait) and heading instead of a fit of the points; the exact mode's frames
stay the batch's; a bad velocity is refused naming the field, the character and the limit."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.build.animals import build_builtin
from synth_core.build.motion_graph import HUBS
from synth_core.quality import edge, evaluate
from synth_core.quality import herd_sim as crowd
from synth_core.quality.live_run import play
from synth_core.quality.reference import library_reference
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.live import LiveSynth
from synth_core.runtime.live_shards import LiveShards
from synth_core.runtime.trajectory import TrajectoryError


@pytest.fixture(scope="module")
def dog() -> Bank:
    return build_bank(build_builtin("dog"))


def test_a_10hz_simulators_velocity_keeps_the_gait_and_the_feet(dog: Bank) -> None:
    """A 10 Hz simulator's points, each tick's held for six frames with 2 cm noise, on a gentle
    curve at the dog's walk, trot and canter speeds: a fit reading two points ahead reads the held
    ticks as speed ripples (walk to trot and back) and the noise as heading jitter. With the velocity
    the simulator sends with each point (its own, held with the tick), each character keeps the gait
    of its speed -- the middle of that gait's range -- and its feet slide less: issue 31's targets."""
    gaits = {HUBS[h]: (float(s[0]), float(s[-1])) for h, s in dog.speeds.items()}
    (sc,) = edge.scenarios(gaits, dog.fps, 0, ["jitter_10hz"])
    ref = library_reference(dog)
    figures, gait = {}, {}
    for sent in (False, True):
        run = play(dog, sc.positions, sc.scales, latency_ms=100.0,
                   velocity=sc.velocity(dog.fps) if sent else None)
        figures[sent] = evaluate.edge_figures(dog, run.result, sc.reference, sc.positions.shape[1], ref,
                                              sent=sc.positions)
        gait[sent] = run.result.gait[:, int(3 * dog.fps):]  # up to speed and through its transitions
    wanted = [HUBS.index(g) for g in ("walk", "trot", "canter")]
    for c, hub in enumerate(wanted):
        assert np.mean(gait[True][c] == hub) >= 0.95, (c, np.unique(gait[True][c], return_counts=True))
    assert min(np.mean(gait[False][c] == h) for c, h in enumerate(wanted)) < 0.95  # the fit's ripples
    # (without it the glide read 0.127 until swings cleared the ground by 3.5 cm: 0.117 now)
    assert figures[True]["glide_ratio"] <= min(0.12, figures[False]["glide_ratio"]), figures
    assert figures[True]["strict_skate_mm_p95"] <= min(5.0, figures[False]["strict_skate_mm_p95"])
    assert figures[True]["nan_count"] == 0


def test_the_velocity_sent_is_the_speed_and_the_way_faced(bank: Bank) -> None:
    """Points standing still, sent with a velocity of 3 m/s along +X: the low-latency mode's speed
    is the velocity's, and the body turns to face +X (yaw pi/2), not the default heading (+Z)."""
    C, T = 2, 240
    points = np.zeros((C, T, 3))
    velocity = np.broadcast_to([3.0, 0.0], (C, T, 2))
    live = LiveSynth(bank, C, 60.0, latency_ms=100.0)
    live.append(points[:, :120], velocity=velocity[:, :120])
    np.testing.assert_allclose(live.frame_speed * live.pace[:, None], 3.0)
    live.append(points[:, 120:])  # no velocity: the fit's (standing) again, past the fit's window
    assert np.all(live.frame_speed[:, -1] == 0.0)
    np.testing.assert_allclose(live.heading_state.last_yaw, np.pi / 2, atol=1e-6)


def test_the_exact_mode_makes_the_batchs_frames_whatever_velocity_is_sent(bank: Bank) -> None:
    herd = crowd.simulate(3, 300, seed=8)
    wrong = np.full((3, 300, 2), 7.0)  # nothing like the points' own: it must not be read
    frames = []
    for velocity in (None, wrong):
        live = LiveSynth(bank, 3, 60.0, seed=2)
        windows = [live.append(herd[:, i:i + 20],
                               velocity=None if velocity is None else velocity[:, i:i + 20])
                   for i in range(0, 300, 20)] + [live.finish()]
        frames.append([(w.root_pos, w.rotations, w.gait) for w in windows if w is not None])
    for a, b in zip(*frames, strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("latency_ms", [None, 100.0])
def test_a_bad_velocity_is_refused_naming_it(bank: Bank, latency_ms: float | None) -> None:
    points = np.cumsum(np.full((3, 4, 3), [0.02, 0.0, 0.0]), axis=1)
    live = LiveSynth(bank, 3, 30.0, latency_ms=latency_ms)
    with pytest.raises(TrajectoryError, match=r"velocity: expected shape \(3, 4, 2\)"):
        live.append(points, velocity=np.zeros((3, 4, 3)))
    bad = np.zeros((3, 4, 2))
    bad[1, 2, 0] = np.nan
    with pytest.raises(TrajectoryError, match="velocity: NaN or Inf at its point 2") as nan:
        live.append(points, velocity=bad)
    assert nan.value.character == 1
    bad = np.zeros((3, 4, 2))
    bad[2, 0] = [120.0, 90.0]  # 150 m/s: 5 m a point at 30 fps is the limit (a teleport)
    live.append(points, velocity=bad)
    bad[2, 0] = [120.0, 91.0]
    with pytest.raises(TrajectoryError, match=r"velocity: 150.6 m/s is over the limit of 150 m/s") as fast:
        live.append(points, velocity=bad)
    assert fast.value.character == 2
    assert live.n_inputs == 4  # the refused messages took nothing
    shards = LiveShards(bank, 3, 30.0, shards=2, latency_ms=latency_ms)
    with pytest.raises(TrajectoryError, match="velocity") as shard:
        shards.append(points, velocity=bad)
    assert shard.value.character == 2  # named by its index in the session, not in its shard
