"""A batch streamed in time windows gives, frame for frame, the numbers of the whole batch."""

from __future__ import annotations

import numpy as np
import pytest

from synth_core.compiled import render_pool
from synth_core.compiled.kernels import lock_context
from synth_core.quality import herd_sim as crowd
from synth_core.runtime import streaming
from synth_core.runtime.bank import Bank
from synth_core.runtime.footlock import PAD
from synth_core.runtime.streaming import BatchStream
from synth_core.runtime.synthesis import Options, synthesize


def test_context_covers_whole_plants() -> None:
    F = 8 + 2 * PAD  # the first window reaches PAD past its end: the array's
    contacts = np.zeros((1, F, 4), bool)
    contacts[0, 2:6, 0] = contacts[0, PAD - 1:PAD + 5, 0] = True  # foot 0: two plants, a swing between
    contacts[0, :, 1:] = True  # the others planted throughout
    begin, stop = lock_context(contacts[:, :, :1], PAD + 7, PAD + 8)  # PAD back reaches the swing at 7
    assert begin[0] == 2 and stop[0] == F  # from the plant before that swing
    begin, stop = lock_context(contacts[:, :, :1], 0, 1)  # PAD on reaches the plant [PAD - 1, PAD + 5)
    assert begin[0] == 0 and stop[0] == PAD + 5
    begin, stop = lock_context(contacts, F - 1, F)  # the feet planted throughout: all of it
    assert begin[0] == 0 and stop[0] == F


# The reference backend runs the same render source, interpreted: tests/test_backends.py holds its
# windows to the compiled ones on a smaller herd. Here only the compiled run: interpreted, this
# test took 154 s (foot lock) and 40 s (none) where the numpy render it replaced took 39 s and 5 s.
@pytest.mark.parametrize("foot_lock", [True, False])
def test_windows_equal_the_whole_batch(bank: Bank, foot_lock: bool) -> None:
    paths = crowd.simulate(12, 500, seed=3, top=16.0)  # too fast: resampled, every gait
    opts = Options(scale_range=(0.8, 1.2), foot_lock=foot_lock, seed=5, resample=True)
    whole = synthesize(bank, paths, options=opts)
    for chunk in (1, 7, 30, 10_000):
        stream = BatchStream(bank, paths, options=opts, chunk_frames=chunk)
        assert stream.resample_rate == whole.resample_rate > 1.0
        windows = list(stream.windows())
        assert [w.start for w in windows] == list(range(0, whole.root_pos.shape[1], chunk))
        for name in ("root_pos", "rotations", "gait", "contacts"):
            joined = np.concatenate([getattr(w, name) for w in windows], axis=1)
            assert np.array_equal(joined, getattr(whole, name)), (name, chunk)


@pytest.mark.parametrize(("standing", "slow"), [((), ()), ((0,), ()), ((0, 11), ()), ((), (11,))])
def test_first_window_in_parts_equals_the_whole_batch(bank: Bank, monkeypatch: pytest.MonkeyPatch,
                                                      standing: tuple[int, ...],
                                                      slow: tuple[int, ...]) -> None:
    pytest.importorskip("numba")
    monkeypatch.setattr(streaming, "MIN_PART", 4)  # 12 characters: a part per core
    paths = crowd.simulate(12, 500, seed=3, top=9.0)
    # Standing throughout: a plant runs past every early plan, so that character's part is planned
    # whole -- one part (the rest early), or every part (their plans are then the whole plan).
    paths[list(standing)] = paths[list(standing), :1]
    # A slow walk: its strides reach past the first early plan, not the second.
    paths[list(slow)] = np.arange(500)[:, None] * np.array([0.0, 0.0, 0.4 / 60])
    opts = Options(scale_range=(0.8, 1.2), backend="numba", seed=5)
    whole = synthesize(bank, paths, options=opts)
    parts: list[tuple[slice, bool]] = []
    reaches: list[int | None] = []
    first_part, plan = streaming.BatchStream._first_part, streaming.plan

    def spy(self: BatchStream, rows: slice, stop: int, shared: bool = False) -> object:
        assert shared  # the parts' renders shared among the pool's threads
        window, plan = first_part(self, rows, stop, shared)
        parts.append((rows, plan is not None))
        return window, plan

    def planned(*args: object, frames: int | None = None, **kwargs: object) -> object:
        reaches.append(frames)
        return plan(*args, frames=frames, **kwargs)

    monkeypatch.setattr(streaming.BatchStream, "_first_part", spy)
    monkeypatch.setattr(streaming, "plan", planned)
    for chunk in (7, 30):
        parts.clear()
        reaches.clear()
        stream = BatchStream(bank, paths, options=opts, chunk_frames=chunk)
        windows = list(stream.windows())
        cores = min(render_pool.size(), 3)
        assert sorted((r.start, r.stop) for r, _ in parts) == [(a * 12 // cores, (a + 1) * 12 // cores)
                                                              for a in range(cores)]
        planned_whole = [r for r, taken in parts if taken]
        assert len(planned_whole) == len({c * cores // 12 for c in standing})
        early = [chunk + streaming.PAD + int(s * bank.mean_cycle) for s in streaming.FIRST_PLAN_STRIDES]
        if chunk == 30:  # the crowd's contexts end within the first rung, the others' do not
            assert (early[1] in reaches) == bool(standing or slow)
        for name in ("root_pos", "rotations", "gait", "contacts"):
            joined = np.concatenate([getattr(w, name) for w in windows], axis=1)
            assert np.array_equal(joined, getattr(whole, name)), (name, chunk)
        # As chunks (what the service packs): the first in its parts, characters in order.
        chunks = list(BatchStream(bank, paths, options=opts, chunk_frames=chunk).chunks())
        assert [len(c) for c in chunks] == [cores] + [1] * (len(windows) - 1)
        for name in ("root_pos", "rotations", "gait", "contacts"):
            first = np.concatenate([getattr(w, name) for w in chunks[0]])
            assert np.array_equal(first, getattr(windows[0], name)), name


def test_bad_batches_fail_before_any_window(bank: Bank) -> None:
    paths = crowd.simulate(2, 100, seed=1)
    paths[1, 40] = np.nan
    with pytest.raises(Exception, match="NaN"):
        BatchStream(bank, paths)
    with pytest.raises(ValueError, match="chunk_frames"):
        BatchStream(bank, paths[:1], chunk_frames=0)
