"""The planner (synth_core.runtime.plan): one state machine for the batch and the live mode, so a
live session's plan is the batch plan of the whole trajectory (up to its end), and a plan of the
first frames is the whole plan's."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from synth_core.quality import evaluate
from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank
from synth_core.runtime.live import LiveSynth
from synth_core.runtime.plan import TURN_S, Plan, Planner, plan
from synth_core.runtime.synthesis import Options, prepare_batch


def live_plan(live: LiveSynth, positions: np.ndarray, rng: np.random.Generator) -> Plan:
    """The plan a live session makes of ``positions`` fed in random-sized ticks, block by block as
    each is planned (frames sent only), up to what the points settle before the end."""
    blocks: list[Plan] = []
    plan_block = live._plan_block

    def spy(t0: int, t1: int, decisions: object) -> None:
        plan_block(t0, t1, decisions)  # type: ignore[arg-type]
        k = live.out_step
        n = -(-t1 // k) - -(-t0 // k)
        kept = live.buffer.plan()
        T = kept.yaw.shape[1]
        block = kept.window(T - n, T)
        blocks.append(Plan(**{f.name: np.array(getattr(block, f.name)) for f in fields(Plan)}))

    live._plan_block = spy  # type: ignore[method-assign]
    i = 0
    while i < positions.shape[1]:
        n = int(rng.integers(1, 60))
        live.append(positions[:, i:i + n])
        i += n
    whole = {f.name: np.concatenate([getattr(b, f.name) for b in blocks], axis=1) for f in fields(Plan)
             if f.name != "scales"}
    return Plan(scales=blocks[0].scales, **whole)


def assert_live_is_batch(bank: Bank, herd: np.ndarray, fps: float, seed: int) -> Plan:
    """A live session of ``herd`` (random ticks) planned as the batch plan, bit for bit, up to
    the last segments (at the end the batch reads its last, shorter segment's speed)."""
    options = Options(seed=seed, scale_range=(0.7, 1.3))
    prep, h, keys = prepare_batch(bank, herd, fps, None, options, None)
    batch = plan(bank, prep, h, keys, compiled=True)
    live = LiveSynth(bank, len(herd), fps, seed=seed, scale_range=(0.7, 1.3))
    got = live_plan(live, herd, np.random.default_rng(seed))
    k = live.out_step
    n = min(got.yaw.shape[1], (batch.yaw.shape[1] - 3 * bank.mean_cycle) // k)
    assert n > (batch.yaw.shape[1] - 5 * bank.mean_cycle) // k
    assert np.array_equal(live.scales, batch.scales)
    for f in fields(Plan):
        if f.name != "scales":
            want = getattr(batch, f.name)[:, ::k][:, :n]
            assert np.array_equal(getattr(got, f.name)[:, :n], want), f.name
    return got


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_live_plan_is_the_batch_plan_bit_for_bit(bank: Bank, seed: int) -> None:
    """Random herds (some stop dead, mixed sizes and tempi), random tick sizes, at the library's
    rate and at half of it: every frame planned live is the batch plan's frame, bit for bit."""
    fps = [60.0, 30.0][seed % 2]
    herd = crowd.simulate(16, 500, seed=seed, top=evaluate.crowd_top_speed(bank), fps=fps)
    herd[:3, 200:] = herd[:3, 200:201]
    got = assert_live_is_batch(bank, herd, fps, seed)
    assert len(np.unique(got.gait)) == 5 and got.stitches.sum() > 3 * len(herd)  # every gait, many changes


def test_a_live_session_whose_characters_stop_dead_keeps_planning(bank: Bank) -> None:
    """Stopping, a walk's stride slows down to STAND_SHARE: its transition to standing waited
    for an entry phase past the look-ahead the live plan searched, and the session failed an
    assertion ("the horizon covers a stride"); stepped frame by frame, it plans as the batch."""
    herd = crowd.simulate(24, 700, seed=3, top=evaluate.crowd_top_speed(bank))
    herd[:3, 300:] = herd[:3, 300:301]
    got = assert_live_is_batch(bank, herd, 60.0, 5)
    assert (got.gait[:3, -1] == 0).any()  # planned on past the stop, into standing


def test_a_plan_of_the_first_frames_is_the_whole_plans(bank: Bank) -> None:
    herd = crowd.simulate(12, 600, seed=7, top=evaluate.crowd_top_speed(bank))
    herd[:2, 150:] = herd[:2, 150:151]
    prep, h, keys = prepare_batch(bank, herd, None, None, Options(seed=7, scale_range=(0.7, 1.3)), None)
    whole = plan(bank, prep, h, keys, compiled=True)
    for frames in (1, 37, 90, 333):
        first = plan(bank, prep, h, keys, frames=frames, compiled=True)
        assert first.yaw.shape[1] == frames
        for f in fields(Plan):
            if f.name != "scales":
                want = getattr(whole, f.name)[:, :frames]
                assert np.array_equal(getattr(first, f.name), want), (frames, f.name)
    # Asked for nearly all of it, it is all of it.
    assert plan(bank, prep, h, keys, frames=590, compiled=True).yaw.shape[1] == 600


def test_the_low_latency_modes_averaged_turn_is_the_same_in_blocks(bank: Bank) -> None:
    """The low-latency mode reads the body's turn averaged over plan.TURN_S (Planner.averaged: a
    low-pass whose state is carried from block to block): fed in blocks of any size, the same
    average as in one, and a steady turn read as itself. (Carrying lfilter's own state, (1 - a)
    times the average, dropped a factor each block: a steady turn read 0.52 of itself fed a frame at
    a time, 0.86 in 10 Hz ticks -- the plan depended on how a client cut its points.)"""
    rng = np.random.default_rng(3)
    C, T = 4, 300
    turned = np.cumsum(rng.normal(0.0, 0.002, (C, T)), axis=1) + 0.02 * np.sin(np.arange(T) / 7.0)
    one = Planner(bank, np.ones(C), np.ones(C), np.zeros(C, np.int64), turn_s=TURN_S)
    whole = one.averaged(turned)
    cut = Planner(bank, np.ones(C), np.ones(C), np.zeros(C, np.int64), turn_s=TURN_S)
    edges = np.unique(np.r_[0, rng.integers(1, T, 40), T])
    pieces = [cut.averaged(turned[:, a:b]) for a, b in zip(edges[:-1], edges[1:], strict=True)]
    assert np.allclose(np.concatenate(pieces, axis=1), whole, rtol=0.0, atol=1e-12)
    steady = Planner(bank, np.ones(C), np.ones(C), np.zeros(C, np.int64), turn_s=TURN_S)
    for _ in range(T):  # a frame a tick, well past the average's time
        last = steady.averaged(np.full((C, 1), 0.03))
    assert np.allclose(last, 0.03, rtol=1e-6)
    exact = Planner(bank, np.ones(C), np.ones(C), np.zeros(C, np.int64))
    assert exact.averaged(turned) is turned  # the batch and the exact mode: each frame's
