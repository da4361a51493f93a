"""What ``quadsynth eval --suite edge --out DIR`` writes beside the JSON: a Markdown table per
animal (every scenario's targeted figures, failures marked) and a picture of the worst moment of
the worst scenario (a contact sheet around the largest one-frame foot jump of its worst
character, the feet marked planted where they are within 1 cm of the ground for 3+ frames)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from synth_core.export.character import scaled_skeleton
from synth_core.motion.clip import Motion
from synth_core.quality import evaluate
from synth_core.quality import metrics as M
from synth_core.quality.edge import Scenario
from synth_core.quality.reference import library_reference
from synth_core.runtime.bank import Bank
from synth_core.runtime.synthesis import Result

SHORT = {"glide_ratio": "glide", "strict_skate_mm_p95": "skate p95 mm", "jump_cm_max": "jump cm",
         "limb_flips": "flips", "walk_support_share": "walk >=2 down",
         "single_support_ratio_max": "alone / stance",
         "stretch_pct_max": "stretch %", "floating_cm_max": "float cm", "stand_drift_cm_max": "drift cm",
         "path_cm_max": "path cm",
         "clock_kept": "clock"}


def _cell(entry: dict[str, Any], figure: str) -> str:
    if "error" in entry:
        return "refused"
    value = entry["figures"].get(figure)
    text = "-" if value is None else f"{value:g}"
    return f"**{text}** x" if figure in entry["failed"] else text


def markdown(suites: dict[str, dict[str, Any]]) -> str:
    """One table per animal: rows scenarios, columns the targeted figures (failures bold, x)."""
    lines = []
    for animal, suite in suites.items():
        passed, total = suite["scenarios_passed"], len(suite["scenarios"])
        header = " | ".join(f"{SHORT[f]} ({t})" for f, t in suite["targets"].items())
        lines += [f"### {animal}: {passed} of {total} scenarios meet every target", "",
                  f"| scenario | {header} |",
                  "|---" * (len(suite["targets"]) + 1) + "|"]
        for name, entry in suite["scenarios"].items():
            lines.append(f"| {name} | " + " | ".join(_cell(entry, f) for f in suite["targets"]) + " |")
        worst = suite["worst"]
        lines.append("| **worst** | " + " | ".join(
            f"{worst[f]['value']:g} ({worst[f]['scenario']})" if f in worst else "-"
            for f in suite["targets"]) + " |")
        lines.append("")
    return "\n".join(lines)


def worst_moment(bank: Bank, scenario: Scenario, result: Result, figure: str) -> tuple[int, int]:
    """(character, frame) where ``figure`` is at its worst: the largest off-path distance
    (``path_cm_max``), the largest strict-plant slide (``strict_skate_mm_p95``), else the
    largest one-frame foot jump."""
    fk = evaluate.feet_after_fk(bank, result, library_reference(bank))
    if figure == "path_cm_max":
        at = M.path_distance_cm(result.root_pos, scenario.reference[result.kept])
    elif figure == "strict_skate_mm_p95":
        step = np.linalg.norm(np.diff(fk.feet[..., [0, 2]], axis=1), axis=-1)
        at = np.where(fk.down[:, 1:] & fk.down[:, :-1], step, 0.0).max(axis=-1)
    else:
        at = np.pad(M.one_frame_jumps_mm(fk.feet).max(axis=-1), ((0, 0), (2, 1)))  # frame of the step's end
    c, f = np.unravel_index(int(at.argmax()), at.shape)
    return int(c), int(f)


def render_worst(bank: Bank, scenario: Scenario, result: Result, entry: dict[str, Any], out: Path,
                 window: int = 45, panels: int = 10) -> Path:
    """A contact sheet of ``window`` frames either side of the worst moment of the figure the
    scenario ``entry`` (its figures) misses by the most (:func:`worst_moment`); its feet are
    marked planted where they are down (strict plants)."""
    from quadsynth.preview import render

    misses = entry.get("beyond_target", {})
    targets = evaluate.EDGE_TARGETS | evaluate.TERRAIN_TARGETS  # a terrain scenario misses either
    figure = max(misses, key=lambda f: misses[f] / (abs(targets[f][1]) or 1.0),
                 default="jump_cm_max")
    c, f = worst_moment(bank, scenario, result, figure)
    fk = evaluate.feet_after_fk(bank, result, library_reference(bank))
    skeleton = scaled_skeleton(bank.skeleton, float(result.scales[c]))
    motion = Motion(skeleton, result.root_pos[c], result.rotations[c], bank.fps, fk.down[c],
                    f"{scenario.name} #{c}, worst {figure}")
    T = result.root_pos.shape[1]
    return render(motion, out, start=max(0, f - window), stop=min(T, f + window), panels=panels)
