"""What the edge figures compare a synthesized crowd with: the library's own clips after FK --
each foot's standing height per hub, each limb's reach, each gait's longest stance and the strict
plants of every pose row (:func:`library_reference`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from synth_core.quality import metrics as M
from synth_core.runtime.bank import STATIC, Bank, Piece, table_positions
from synth_core.runtime.synthesis import N_HUBS

Floats = NDArray[np.float64]

SOLE_PERCENTILE = 10.0


@dataclass(frozen=True, eq=False)
class LibraryReference:
    """What the edge figures compare the output with, from the library's own clips after FK."""

    soles: Floats  # (N_HUBS, 4) per hub each foot joint's height when it stands (SOLE_PERCENTILE)
    reach: Floats  # (4,) each limb's longest hip-to-foot reach in the clips, m
    stance: Floats  # (N_HUBS,) per hub its clips' longest strict plant, frames (static: the slowest gait's)
    clip_plants: NDArray[np.bool_]  # (K, 4) strict plants of every pose row (cyclic clips wrapped)
    mirror_soles: Floats  # soles and reach of the mirror rows (bank.mirror; else the same): a
    mirror_reach: Floats  # character on the other lead is measured against these


def _rows(piece: Piece) -> slice:
    return slice(piece.offset, piece.offset + piece.frames * piece.clips)


def _clip_plants(heights: Floats, piece: Piece, cyclic: bool) -> tuple[NDArray[np.bool_], int]:
    """Strict plants of a piece's rows ``(clips * frames, 4)``, and its longest plant (frames;
    0 unless ``cyclic``, where a plant over a clip's end goes on at its start)."""
    clips = heights.reshape(piece.clips, piece.frames, 4)
    if not cyclic:
        return M.strict_plants(clips).reshape(-1, 4), 0
    thrice = M.strict_plants(np.concatenate([clips] * 3, axis=1))
    longest = int(M.run_lengths(np.moveaxis(thrice, -1, -2)).max())
    # A foot that never lifts would have a plant as long as the tiling: a stride at most.
    return thrice[:, piece.frames:2 * piece.frames].reshape(-1, 4), min(longest, piece.frames)


def _soles(raw: M.Floats, planted: NDArray[np.bool_], fallback: Floats) -> Floats:
    """(4,) each foot's standing height in ``raw (n, 4)`` heights, where ``planted``."""
    return np.array([np.percentile(raw[planted[:, k], k], SOLE_PERCENTILE) if planted[:, k].any()
                     else fallback[k] for k in range(4)])


def _lead(bank: Bank, first: int) -> tuple[Floats, Floats, Floats, NDArray[np.bool_]]:
    """Soles, reach, stance and clip plants (:class:`LibraryReference`) of the table's rows
    ``[first, first + bank.own)``: the library's own clips, or their mirror images."""
    sk = bank.skeleton
    own = slice(first, first + bank.own)
    pos = table_positions(bank, own)
    # The root stands at bank.height, already over the clips' ground (build_bank subtracts it):
    # taking bank.ground off again put every sole that much low (the real dog's 2.7 mm), and
    # every paw the synthesis plants on its sole read 2.7 mm up -- lifting off and landing a frame
    # sooner and later against the strict plants' 1 cm.
    raw = M.foot_heights(pos[:, sk.foot_joints])
    contacts = bank.contacts[own]
    overall = _soles(raw, contacts, np.zeros(4))
    soles = np.tile(overall, (N_HUBS, 1))
    plants = np.zeros((bank.own, 4), bool)
    stance = np.zeros(N_HUBS)
    # Per piece: a mocap paw's end site stands higher in one take than in another (the real
    # dog's right hind: 0.9 cm over all its clips, 2 cm in its walk).
    for hub, piece in [(STATIC, bank.idle), *bank.gaits.items()]:
        rows = _rows(piece)
        soles[hub] = _soles(raw[rows], contacts[rows], overall)
        plants[rows], longest = _clip_plants(raw[rows] - soles[hub], piece, cyclic=hub != STATIC)
        stance[hub] = longest
    for piece in bank.transitions.values():
        rows = _rows(piece)
        plants[rows] = _clip_plants(raw[rows] - _soles(raw[rows], contacts[rows], overall), piece,
                                    cyclic=False)[0]
    stance[[h for h in range(N_HUBS) if h not in bank.speeds]] = stance.max()
    stance[STATIC] = stance[min(bank.speeds)]
    return soles, M.limb_reach(pos, sk).max(axis=0), stance, plants


def library_reference(bank: Bank) -> LibraryReference:
    soles, reach, stance, plants = _lead(bank, 0)
    if not bank.mirror:
        return LibraryReference(soles, reach, stance, plants, soles, reach)
    # The mirror rows measured as themselves: a captured skeleton's sides differ by a millimetre
    # or two (the real dog's), so a mirrored paw's standing height is not quite its partner's.
    mirror_soles, mirror_reach, _, mirror_plants = _lead(bank, bank.mirror)
    return LibraryReference(soles, reach, stance, np.concatenate([plants, mirror_plants]), mirror_soles,
                            mirror_reach)


