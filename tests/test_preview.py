"""Previews: PNG contact sheets and GIFs are written and are real images of the right kind."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from quadsynth.cli import main
from quadsynth.preview import load_for_preview, render
from synth_core.motion import bvh
from synth_core.motion.contacts import contacts_json
from tests.helpers.mocap import mann_path
from tests.helpers.motion import random_motion


def test_png_contact_sheet_of_a_real_dog(tmp_path: Path) -> None:
    out = tmp_path / "trot.png"
    assert main([ "preview", str(mann_path("D1_009_KAN01_002")), "--out", str(out),
                 "--start", "296", "--stop", "327"]) == 0
    with Image.open(out) as image:
        assert image.format == "PNG" and image.width > 1000 and image.height > 500
        pixels = np.asarray(image.convert("RGB"))
    # Planted-paw red and the limb colours are drawn: the figure is not blank.
    red = np.all(np.abs(pixels.astype(int) - [214, 39, 40]) < 30, axis=-1)
    blue = np.all(np.abs(pixels.astype(int) - [31, 95, 191]) < 30, axis=-1)
    assert red.sum() > 50 and blue.sum() > 500


def test_gif_has_one_frame_per_sampled_pose(tmp_path: Path) -> None:
    motion = random_motion(np.random.default_rng(0), frames=20)
    out = render(motion, tmp_path / "clip.gif", gif_fps=30)  # 60 fps clip: every 2nd frame
    with Image.open(out) as image:
        assert image.format == "GIF" and image.n_frames == 10


def test_sidecar_contacts_are_used(tmp_path: Path) -> None:
    motion = random_motion(np.random.default_rng(1), frames=10)
    path = tmp_path / "clip.bvh"
    bvh.write(motion, path)
    planted = np.zeros((10, 4), bool)
    planted[2:5, 3] = True
    (tmp_path / "clip.contacts.json").write_text(json.dumps(contacts_json(planted, 60.0)))
    assert np.array_equal(load_for_preview(path).contacts, planted)


def test_bad_arguments_are_clear_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    motion = random_motion(np.random.default_rng(2), frames=10)
    with pytest.raises(ValueError, match="out: expected a .png or .gif"):
        render(motion, tmp_path / "x.jpg")
    with pytest.raises(ValueError, match=r"frames: \[5, 50\) is outside"):
        render(motion, tmp_path / "x.png", start=5, stop=50)
    assert main(["preview", str(tmp_path / "missing.bvh"), "--out", str(tmp_path / "a.png")]) == 2
    assert "missing.bvh" in capsys.readouterr().err
