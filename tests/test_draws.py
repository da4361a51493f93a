"""Counter-based draws: a character's draws depend on its key and the stream only."""

import numpy as np

from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank
from synth_core.runtime.draws import character_keys, uniform, uniform_streams
from synth_core.runtime.synthesis import Options, synthesize


def test_draws_are_uniform_and_independent_of_the_batch() -> None:
    keys = character_keys(7, 20_000)
    u = uniform(keys, 3, 5)
    assert u.shape == (20_000, 5) and 0.0 <= u.min() and u.max() < 1.0
    assert abs(u.mean() - 0.5) < 0.01 and abs(u.var() - 1 / 12) < 0.005
    # Streams and lanes are not correlated with each other.
    assert abs(np.corrcoef(u[:, 0], u[:, 1])[0, 1]) < 0.03
    assert abs(np.corrcoef(u[:, 0], uniform(keys, 4)[:, 0])[0, 1]) < 0.03
    # A character's draws do not depend on how many come after it.
    assert np.array_equal(uniform(character_keys(7, 3), 3, 5), u[:3])
    assert not np.array_equal(uniform(character_keys(8, 3), 3, 5), u[:3])


def test_many_streams_at_once_are_the_streams_one_by_one() -> None:
    keys = character_keys(3, 50)
    many = uniform_streams(keys, 2, 6, 5)
    assert many.shape == (50, 6, 5)
    for k in range(6):
        assert np.array_equal(many[:, k], uniform(keys, 2 + k, 5))


def test_own_seed_overrides_the_batch_seed() -> None:
    mixed = character_keys(1, 3, [-1, 42, -1])
    assert mixed[0] == character_keys(1, 3)[0] and mixed[2] == character_keys(1, 3)[2]
    assert mixed[1] == character_keys(99, 3, [5, 42, 5])[1]  # batch seed and index do not matter


def test_a_characters_motion_depends_on_its_own_seed_only(bank: Bank) -> None:
    paths = crowd.simulate(4, 400, seed=5, top=6.0)
    opts = Options(scale_range=(0.8, 1.2))
    whole = synthesize(bank, paths, options=opts, seeds=[11, 12, 13, 14])
    alone = synthesize(bank, paths[2:3], options=opts, seeds=[13])
    assert whole.resample_rate == alone.resample_rate == 1.0
    assert np.array_equal(whole.rotations[2], alone.rotations[0])
    assert np.array_equal(whole.gait[2], alone.gait[0]) and whole.scales[2] == alone.scales[0]
