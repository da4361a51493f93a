"""Counter-based random numbers: every draw is a pure function of a character's key and what is
drawn (a stream number), not of a generator's position.

So a character's motion depends on its own seed only -- not on the characters around it in the
batch, nor on how the work is cut up (characters in chunks, frames in streamed windows). A
shared ``np.random.Generator`` gives neither: whoever draws first shifts everyone after.

The mixer is SplitMix64's finalizer (Steele, Lea & Flood 2014), whose output passes BigCrush
when fed a counter; here the counter is ``key + stream * golden``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
SCALE_STREAM = 0  # the scale drawn for a character given none
SCHEDULE_STREAM = 1  # + the decision step: the gait picked where several cover the speed
TEMPO_STREAM = 1 << 40  # a character's own stride tempo (far past any decision step's stream)
LEAD_STREAM = TEMPO_STREAM + 1  # its lead: the library's clips or their mirror images
LANES = 8  # draws per stream and character, at most


def _mix(x: NDArray[np.uint64]) -> NDArray[np.uint64]:
    with np.errstate(over="ignore"):
        x = (x ^ (x >> np.uint64(30))) * _M1
        x = (x ^ (x >> np.uint64(27))) * _M2
        return np.asarray(x ^ (x >> np.uint64(31)))


def character_keys(seed: int, n: int, seeds: ArrayLike | None = None, first: int = 0) -> NDArray[np.uint64]:
    """One key per character: from its own seed where ``seeds`` gives one (``-1``: none), else
    from the batch ``seed`` and its index, counted from ``first`` (a herd sent in several
    batches, each with its own ``first``, draws as one batch would)."""
    index = np.arange(first, first + n, dtype=np.uint64)
    with np.errstate(over="ignore"):
        batch = _mix(np.array([seed & 0xFFFFFFFFFFFFFFFF], np.uint64))
        keys = _mix(batch + index * _GOLDEN)
        if seeds is not None:
            own = np.asarray(seeds, np.int64)
            mine = _mix(_mix(own.astype(np.uint64) ^ np.uint64(0x5EED)))
            keys = np.where(own >= 0, mine, keys)
    return np.asarray(keys)


def uniform(keys: NDArray[np.uint64], stream: int, lanes: int = 1) -> NDArray[np.float64]:
    """``(len(keys), lanes)`` floats in [0, 1): draw ``stream`` of each character."""
    return uniform_streams(keys, stream, 1, lanes)[:, 0]


def uniform_streams(keys: NDArray[np.uint64], first: int, count: int, lanes: int = 1) -> NDArray[np.float64]:
    """``(len(keys), count, lanes)``: streams ``first ... first + count - 1`` of each character at
    once (a compiled schedule takes all its decisions' draws beforehand)."""
    if not 0 < lanes <= LANES:
        raise ValueError(f"lanes: 1 to {LANES}, got {lanes}")
    stream = np.arange(first, first + count, dtype=np.uint64)
    counter = stream[:, None] * np.uint64(LANES) + np.arange(lanes, dtype=np.uint64)[None, :]
    with np.errstate(over="ignore"):
        bits = _mix(keys[:, None, None] + (counter + np.uint64(1))[None] * _GOLDEN)
    return np.asarray((bits >> np.uint64(11)).astype(np.float64) * 2.0**-53)
