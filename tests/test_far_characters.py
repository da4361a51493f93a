"""Far characters in a batch (REST, WebSocket batch, synthesize): a character whose rotations
nobody is sent (root_gait detail) is not posed -- no pose, no foot lock -- and still gets the
root and gait the full render gives it, and its plan's contacts (the feet a render would plant
are those, less the lock's steps: docs/wire-format.md); the posed characters' motion is unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank
from synth_core.runtime.streaming import BatchStream, joined
from synth_core.runtime.synthesis import Options, synthesize
from synth_core.runtime.trajectory import TrajectoryError
from tests.helpers.motion import assert_far_root

pytest.importorskip("numba")

POSED = np.array([True, False, False, True, False, True, False, False])


@pytest.fixture(scope="module")
def herd() -> np.ndarray:
    return crowd.simulate(len(POSED), 400, seed=11)


def test_a_batch_poses_only_the_characters_wanted(bank: Bank, herd: np.ndarray) -> None:
    full = synthesize(bank, herd, options=Options(seed=3, scale_range=(0.8, 1.2)))
    far = synthesize(bank, herd, options=Options(seed=3, scale_range=(0.8, 1.2), posed=POSED))
    np.testing.assert_array_equal(far.rotations[POSED], full.rotations[POSED])
    np.testing.assert_array_equal(far.root_pos[POSED], full.root_pos[POSED])
    np.testing.assert_array_equal(far.gait, full.gait)
    np.testing.assert_array_equal(far.contacts[POSED], full.contacts[POSED])
    plan = synthesize(bank, herd, options=Options(seed=3, scale_range=(0.8, 1.2), foot_lock=False))
    np.testing.assert_array_equal(far.contacts[~POSED], plan.contacts[~POSED])  # (unlocked: the plan's)
    assert_far_root(bank, far.root_pos[~POSED], full.root_pos[~POSED], full.scales[~POSED])


def test_a_batch_stream_poses_only_the_characters_wanted(bank: Bank, herd: np.ndarray) -> None:
    def frames(options: Options) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        stream = BatchStream(bank, herd, options=options, chunk_frames=50)
        windows = [joined(w) for w in stream.chunks()]
        return tuple(np.concatenate([getattr(w, f) for w in windows], axis=1)  # type: ignore[return-value]
                     for f in ("root_pos", "rotations", "contacts"))
    root, rot, contacts = frames(Options(seed=3, posed=POSED))
    root_full, rot_full, contacts_full = frames(Options(seed=3))
    np.testing.assert_array_equal(rot[POSED], rot_full[POSED])
    np.testing.assert_array_equal(root[POSED], root_full[POSED])
    np.testing.assert_array_equal(contacts[POSED], contacts_full[POSED])
    assert not (contacts_full & ~contacts).any()  # a far one's plan has every foot the render plants
    scales = synthesize(bank, herd[:1], options=Options(seed=3)).scales  # scale 1: the range's default
    assert_far_root(bank, root[~POSED], root_full[~POSED], np.full((~POSED).sum(), scales[0]))


def test_flags_for_another_number_of_characters_are_refused(bank: Bank, herd: np.ndarray) -> None:
    with pytest.raises(TrajectoryError, match=r"posed: expected 8 flags"):
        synthesize(bank, herd, options=Options(posed=POSED[:5]))
