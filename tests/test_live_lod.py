"""Level of detail on the live path's server side: a character whose rotations nobody is sent
(root_gait) is not posed -- no pose, no foot lock -- and still gets its root, gait and its plan's contacts."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.quality import herd_sim as crowd
from synth_core.runtime.bank import Bank
from synth_core.runtime.live_shards import LiveShards
from synth_core.runtime.streaming import Window
from synth_core.runtime.streaming import joined as shards_joined
from synth_core.runtime.trajectory import TrajectoryError
from tests.helpers.motion import assert_far_root

pytest.importorskip("numba")


@pytest.fixture(scope="module")
def herd() -> np.ndarray:
    return crowd.simulate(12, 500, seed=7, fps=30.0)


def run(live: LiveShards, herd: np.ndarray, switch: tuple[int, np.ndarray] | None = None
        ) -> tuple[list[Window], list[int]]:
    """Points 15 at a time (half a second at 30 fps), then finish: the windows, and for each the
    points given before it was rendered. ``switch``: (the point index from which on, the new
    pose flags)."""
    out, given = [], []
    for i in range(0, herd.shape[1], 15):
        if switch is not None and i == switch[0]:
            live.set_posed(switch[1])
        w = live.append(herd[:, i:i + 15])
        if w is not None:
            out.append(shards_joined(w))
            given.append(i + 15)
    while (w := live.finish(live.window_frames)) is not None:
        out.append(shards_joined(w))
        given.append(herd.shape[1])
    return out, given


def cat(windows: list[Window], field: str) -> np.ndarray:
    return np.concatenate([getattr(w, field) for w in windows], axis=1)


def session(bank: Bank, herd: np.ndarray) -> LiveShards:
    # Two shards: the flags are cut along with the characters.
    return LiveShards(bank, len(herd), 30.0, seed=4, scale_range=(0.8, 1.2), shards=2)


def test_far_characters_are_not_posed_and_keep_the_full_sessions_root_gait_and_plan_contacts(
        bank: Bank, herd: np.ndarray) -> None:
    full = session(bank, herd)
    want, _ = run(full, herd)
    far = session(bank, herd)
    far.set_posed(np.zeros(len(herd), bool))
    got, _ = run(far, herd)
    frames = cat(want, "gait").shape[1]
    assert full.posed_frames == len(herd) * frames  # every frame sent
    assert far.posed_frames == 0
    np.testing.assert_array_equal(cat(got, "gait"), cat(want, "gait"))
    # A far character's contacts are its plan's: every foot the full render plants and the
    # frames the lock lifts it off (docs/wire-format.md).
    assert not (cat(want, "contacts") & ~cat(got, "contacts")).any()
    root, root_full = cat(got, "root_pos"), cat(want, "root_pos")
    assert_far_root(bank, root, root_full, far.scales)
    assert (np.abs(root[..., 1] - root_full[..., 1]) < 1e-5).mean() > 0.5  # most frames need neither


def test_characters_switched_to_full_are_posed_as_if_they_always_were(bank: Bank, herd: np.ndarray) -> None:
    """Half the herd far for the first 6 s, then everyone full: the posed characters' frames are
    the full session's throughout, the others' from their first window after the switch (their
    foot lock's context posed whole: the same numbers, to rounding)."""
    C = len(herd)
    full, _ = run(session(bank, herd), herd)
    half = np.arange(C) % 2 == 0
    mixed = session(bank, herd)
    mixed.set_posed(half)
    switch = 180  # points: 6 s
    got, given = run(mixed, herd, (switch, np.ones(C, bool)))
    rot, rot_full = cat(got, "rotations"), cat(full, "rotations")
    np.testing.assert_allclose(rot[half], rot_full[half], rtol=0, atol=1e-5)
    # The first window rendered after the switch: the frames settled by then come before it.
    after = sum(w.stop - w.start for w, n in zip(got, given, strict=True) if n <= switch)
    assert 0 < after < rot.shape[1] - 60
    np.testing.assert_allclose(rot[~half, after:], rot_full[~half, after:], rtol=0, atol=1e-5)
    np.testing.assert_allclose(cat(got, "root_pos")[:, after:], cat(full, "root_pos")[:, after:],
                               rtol=0, atol=1e-5)


def test_the_render_leaves_unposed_rows_unwritten(bank: Bank, herd: np.ndarray) -> None:
    """The kernel itself skips them: their rows of the output keep what was there; the posed
    rows are those of a render of everyone."""
    from synth_core.compiled import kernels
    from synth_core.runtime.synthesis import Options, plan, prepare_batch

    options = Options(seed=5, scale_range=(0.8, 1.2))
    prep, h, keys = prepare_batch(bank, herd, 30.0, None, options, None, None)
    p = plan(bank, prep, h, keys, options.margin, compiled=True)
    C, J = len(herd), bank.skeleton.n_joints
    pose = np.arange(C) % 3 == 0
    a, b = 200, 230
    begin, end = kernels.lock_context(p.contacts, a, b)
    out = np.full((C, b - a, J, 4), np.nan, np.float32)
    root, rot = kernels.render_window(bank, p, a, b, begin, end, True, out=out, pose=pose)
    assert rot is out and np.isnan(rot[~pose]).all()
    root_all, rot_all = kernels.render_window(bank, p, a, b, begin, end, True)
    np.testing.assert_array_equal(rot[pose], rot_all[pose])
    np.testing.assert_array_equal(root[pose], root_all[pose])
    np.testing.assert_allclose(root[~pose][..., [0, 2]], root_all[~pose][..., [0, 2]], rtol=0, atol=1e-5)


def test_pose_flags_of_the_wrong_shape_are_refused(bank: Bank) -> None:
    live = LiveShards(bank, 4, 30.0)
    with pytest.raises(TrajectoryError, match="pose: expected 4 flags"):
        live.set_posed(np.ones(5, bool))
