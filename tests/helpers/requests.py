"""Requests to a test server, the limits its API tests run it with, answers compared."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import httpx
import msgpack
import numpy as np

from api_schemas.wire import blob

MSGPACK = "application/vnd.msgpack"


LIMITS = {"QUADSYNTH_MAX_BODY_BYTES": str(1024 * 1024), "QUADSYNTH_MAX_CHARACTERS": "40",
          "QUADSYNTH_MAX_FRAMES": "2000", "QUADSYNTH_MAX_CHARACTER_FRAMES": "20000",
          "QUADSYNTH_MAX_IN_FLIGHT": "1", "QUADSYNTH_MAX_QUEUED": "1", "QUADSYNTH_DEADLINE_S": "20",
          "QUADSYNTH_TEST_HOOKS": "1"}


def post(url: str, body: Any, **headers: str) -> httpx.Response:
    raw = body if isinstance(body, bytes) else msgpack.packb(body, use_bin_type=True)
    return httpx.post(f"{url}/v1/synthesize", content=raw,
                      headers={"content-type": MSGPACK, **headers}, timeout=60)


def same_motion(a: Path, b: Path) -> None:
    remote, local = np.load(a / "motion.npz"), np.load(b / "motion.npz")
    assert remote["rotations"].shape == local["rotations"].shape
    for key in ("gait", "contacts", "ids", "scales"):
        np.testing.assert_array_equal(remote[key], local[key], err_msg=key)
    for key in ("root_pos", "rotations"):
        np.testing.assert_allclose(remote[key], local[key], atol=1e-5, err_msg=key)


def refused(response: httpx.Response, status: int, field: str, *words: str) -> None:
    assert response.status_code == status, (field, response.text[:300])
    error = response.json()["error"]
    assert error["status"] == status and error["field"] == field, error
    for word in words:
        assert word in error["message"], error


def batch(herd: np.ndarray, **options: Any) -> dict[str, Any]:
    return {"animal": "horse", "seed": 3, **options,
            "characters": [{"id": f"h{c}", "points": blob(herd[c])} for c in range(len(herd))]}
