"""What a live session's render windows keep of the frames they posed, for the later windows
over the same plan (:func:`synth_core.compiled.kernels.render_window`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import NDArray

from synth_core.compiled.foot_kernels import LEG_WIDTH, NOWHERE
from synth_core.runtime.footlock import PAD

if TYPE_CHECKING:
    from synth_core.runtime.plan import Plan


class Posed(NamedTuple):
    """What a live session's windows keep of the frames they posed, for the later windows over
    the same plan (see :func:`~synth_core.compiled.kernels.render_window`): the feet
    ``(T, C, 4, 3)`` float64, C-contiguous (frames first: every view of them is, so the kernel is
    compiled for one layout), of each character's plan frames ``[0, frames[c])``; what the sink
    reads of the legs on the PAD frames before ``legs_at[c]`` (``(C, PAD, 4, LEG_WIDTH)``;
    ``NOWHERE``: none kept); where plants are pinned at their first frames
    (``kernels.render_window``'s ``plant_frames``), each foot's plant through plan frame
    ``pinned[c, f]`` and its target ``pins[c, f]`` as sent (``(C, 4)``, ``(C, 4, 3)``;
    ``NOWHERE``: none), so that a plant longer than the context kept stays there when its first
    frames are dropped; there too, the foot targets ``(C, 2, 4, 3)`` of plan frames
    ``sent_at[c] - 1``, ``sent_at[c]`` as sent (``(C,)``; ``NOWHERE``: none), from which the next
    window's unsent frames' jumps are eased (jump_kernels.ease_unsent), and each leg's ankle bend
    side on frame ``sent_at[c]`` (``sides (C, 4, 4)``: limb_kernels.solve_legs; a window starting
    on the frame after it keeps it)."""

    feet: NDArray[np.float64]
    frames: NDArray[np.int64]
    legs: NDArray[np.float64]
    legs_at: NDArray[np.int64]
    pins: NDArray[np.float64]
    pinned: NDArray[np.int64]
    sent: NDArray[np.float64]
    sent_at: NDArray[np.int64]
    sides: NDArray[np.float64]

    @classmethod
    def none(cls, C: int, feet: NDArray[np.float64]) -> Posed:
        """Nothing posed yet, the feet to be kept in ``feet``."""
        return cls(feet, np.zeros(C, np.int64), np.empty((C, PAD, 4, LEG_WIDTH)), np.full(C, NOWHERE),
                   np.zeros((C, 4, 3)), np.full((C, 4), NOWHERE), np.zeros((C, 2, 4, 3)), np.full(C, NOWHERE),
                   np.zeros((C, 4, 4)))


def checked(known: Posed | None, plan: Plan) -> Posed:
    """``known`` (see :func:`~synth_core.compiled.kernels.render_window`), its arrays checked; none
    known: an empty one."""
    C = plan.yaw.shape[0]
    if known is None:
        return Posed(np.empty((0, C, 4, 3)), np.zeros(C, np.int64), np.empty((0, PAD, 4, LEG_WIDTH)),
                     np.zeros(C, np.int64), *Posed.none(C, np.empty((0, C, 4, 3)))[4:])
    assert known.feet.shape == (*plan.yaw.shape[::-1], 4, 3) and known.feet.dtype == np.float64
    assert known.feet.flags.c_contiguous
    assert known.legs.shape == (C, PAD, 4, LEG_WIDTH) and known.legs.flags.c_contiguous
    assert known.pins.shape == (C, 4, 3) and known.pins.flags.c_contiguous and known.pinned.shape == (C, 4)
    assert known.sent.shape == (C, 2, 4, 3) and known.sent.flags.c_contiguous
    assert known.sides.shape == (C, 4, 4) and known.sides.dtype == np.float64
    assert known.sides.flags.c_contiguous
    for frames in (known.frames, known.legs_at, known.pinned, known.sent_at):
        assert frames.dtype == np.int64 and frames.flags.c_contiguous
    return known
