"""A REST answer's rotations packed a group of characters at a time (service.answer) are the
bytes and maps of packing each character alone (service.encode.rotations, the reference)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from service import encode
from service.answer import _packed_rotations
from synth_core.build.animals import build_builtin


@pytest.mark.parametrize("encoding", ["delta", "s48", "i16", "f32"])
@pytest.mark.parametrize("frame_step", [1, 3])
def test_grouped_packing_is_each_characters_own(encoding: Any, frame_step: int) -> None:
    sk = build_builtin("horse").skeleton
    rng = np.random.default_rng(0)
    C, T, J = 12, 50, sk.n_joints
    q = rng.normal(size=(C, T, J, 4)).astype(np.float32)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    # Details and frame counts mixed: groups of scattered rows as well as runs.
    details: list[Any] = ["full", "legs_spine", "root_gait", "full", "full", "legs_spine", "root_gait",
                          "full", "full", "full", "legs_spine", "full"]
    frames = [50, 50, 50, 40, 50, 50, 30, 50, 50, 50, 50, 50]
    p = encode.packing(encoding, frame_step, "full", details, sk, rng.uniform(0.8, 1.2, C))
    first = 3  # the chunk's characters: [3, C) of the request's
    chunk = SimpleNamespace(characters=slice(first, C), rotations=q[first:])
    got = _packed_rotations(chunk, frames, p)  # type: ignore[arg-type]
    assert len(got) == C - first
    for i, (packed, meta) in enumerate(got):
        c = first + i
        d = p.details[c]
        joints = None if d == "full" else p.joints(d)
        want, want_meta = encode.rotations(q[c:c + 1, 0:frames[c]:frame_step], p, np.array([c]), joints)
        if encoding == "delta":
            want_meta["decoded_shape"] = want_meta["decoded_shape"][1:]
        else:
            want = want[0]
            want_meta["shape"] = want_meta["shape"][1:]
        assert np.asarray(packed).dtype == want.dtype
        np.testing.assert_array_equal(np.asarray(packed), want)
        assert list(meta.items()) == list(want_meta.items())  # the same keys in the same order
