"""What several test modules share: servers started for a test, requests built for them, test
data (the real dog mocap, a toy quadruped, synthetic gaits). Tests import from here, not from
each other; fixtures stay in conftest.py."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
