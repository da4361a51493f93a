"""Herds out of step (issue 28): a herd of 20 horses of one size, started together (the crowd-sim
herd: stand, speed up to a gallop, slow to a walk), measured after FK on the exported motion --
how often two horses show the same 4-foot contact pattern (metrics.same_pattern_share)."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.build.library_store import builtin_library
from synth_core.motion.mirror import FOOT_SWAP, skeleton_mirror
from synth_core.motion.skeleton import forward_kinematics
from synth_core.quality import herd_sim as crowd
from synth_core.quality import metrics as M
from synth_core.quality.evaluate import world_positions
from synth_core.runtime import plan as plan_module
from synth_core.runtime.bank import Bank, build_bank
from synth_core.runtime.draws import character_keys
from synth_core.runtime.plan import character_leads
from synth_core.runtime.synthesis import Options, synthesize

TARGET = 0.30  # issue 28 (random phases ~0.22; the gait's chance level, a trot ~0.34, a walk ~0.13)
CHARACTERS, FRAMES = 20, 1000


@pytest.fixture(scope="module")
def bank() -> Bank:
    return build_bank(builtin_library("horse"))


def share(bank: Bank, **options: float) -> float:
    """The herd's same-pattern share, feet down = within 1 cm of the ground for 3 frames (FK)."""
    paths = crowd.simulate(CHARACTERS, FRAMES, seed=0)
    result = synthesize(bank, paths, options=Options(scale_range=(1.0, 1.0), seed=0, **options))  # type: ignore[arg-type]
    feet = world_positions(bank, result)[:, :, bank.skeleton.foot_joints]
    return M.same_pattern_share(M.strict_plants(M.foot_heights(feet, result.path[..., 1])))


def test_each_characters_own_tempo_moves_a_herd_of_one_size_out_of_step(bank: Bank) -> None:
    assert share(bank) < share(bank, tempo_spread=0.0) - 0.03


def test_a_herd_of_one_size_started_together_steps_out_of_step(bank: Bank) -> None:
    # Half the herd on the other lead (mirrored clips): it leaves standing with the other fore
    # foot first, so the start and the speed-up no longer step as one (0.374 on one lead).
    assert share(bank) <= TARGET


def test_a_mirror_row_is_the_mirror_image_of_its_row(bank: Bank) -> None:
    """FK of the table's mirror rows: every joint where its partner's is in the row mirrored
    (about the plane x = 0 the canonical clips travel in), each foot's contact its partner's."""
    sk, K = bank.skeleton, bank.mirror
    assert K > 0 and len(bank.poses) == 2 * K
    root = np.zeros((K, 3))
    root[:, 1] = bank.height[:K]
    own = np.asarray(forward_kinematics(sk, root, bank.poses[:K])[0], np.float64)
    mirrored = np.asarray(forward_kinematics(sk, root, bank.poses[K:])[0], np.float64)
    partner = skeleton_mirror(sk).partner  # type: ignore[union-attr]
    assert not np.array_equal(partner, np.arange(sk.n_joints))
    reflected = own[:, partner] * np.array([-1.0, 1.0, 1.0])
    assert np.abs(mirrored - reflected).max() < 1e-4  # m: float32 poses
    assert np.array_equal(bank.contacts[K:], bank.contacts[:K][:, FOOT_SWAP])
    feet = sk.foot_joints  # the canter's and gallop's leads differ: the rows are not their own mirror
    assert np.abs(mirrored[:, feet] - own[:, feet]).max() > 0.1


def test_a_character_on_the_other_lead_moves_as_the_mirror_image(
        bank: Bank, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two characters alike (one key) on a straight path from standing to a gallop, the second
    on the other lead: after the planner, the render (foot lock, IK) and FK, every joint of the
    second is where its partner's of the first is, mirrored about the path's vertical plane."""
    monkeypatch.setattr(plan_module, "character_leads",
                        lambda b, keys: np.array([0, b.mirror] * (len(keys) // 2), np.int64))
    T = 700
    speed = np.clip((np.arange(T) / bank.fps - 1.0) * 2.0, 0.0, 0.8 * bank.top_speed)
    path = np.zeros((T, 3))
    path[:, 2] = np.cumsum(speed) / bank.fps
    result = synthesize(bank, np.stack([path, path]), options=Options(seed=0), seeds=[7, 7])
    pos = world_positions(bank, result).astype(np.float64)
    partner = skeleton_mirror(bank.skeleton).partner  # type: ignore[union-attr]
    assert set(result.gait[0]) >= {0, 1, 2, 3, 4}  # stands, then every gait
    assert np.abs(pos[1][:, partner] * np.array([-1.0, 1.0, 1.0]) - pos[0]).max() < 1e-3  # m
    assert np.array_equal(result.contacts[1], result.contacts[0][:, FOOT_SWAP])


def test_leads_are_drawn_per_character_and_reproducible(bank: Bank) -> None:
    keys = character_keys(0, 200)
    leads = character_leads(bank, keys)
    assert set(leads) == {0, bank.mirror} and 0.35 < np.mean(leads > 0) < 0.65
    assert np.array_equal(leads, character_leads(bank, character_keys(0, 200)))
    assert not np.array_equal(leads, character_leads(bank, character_keys(1, 200)))
