"""The built-in animals' clip set: idle, four cyclic gaits, eight transitions (the paper's 12 + idle)."""

from __future__ import annotations

import json
from pathlib import Path

from synth_core.builtin.gaits import GAIT_SPECS
from synth_core.builtin.generator import cyclic_clip, idle_clip, transition_clip
from synth_core.builtin.skeletons import build_skeleton
from synth_core.builtin.tracks import static_spec
from synth_core.motion import bvh
from synth_core.motion.clip import Motion
from synth_core.motion.contacts import contacts_json

GAITS = ("walk", "trot", "canter", "gallop")
TRANSITIONS = ("static2walk", "walk2static", "walk2trot", "trot2walk", "trot2canter", "canter2trot",
               "canter2gallop", "gallop2canter")
CLIP_NAMES = ("idle", *GAITS, *TRANSITIONS)
# Strides each transition's blend takes: short, as animals change gait within a stride or so,
# but long enough for the generator to keep the feet planted and clear (tests/test_library_clips):
# starting and stopping take longer, and a canter's lead is slow to unwind into a trot.
TRANSITION_STRIDES = {"static2walk": 2.0, "walk2static": 2.0, "canter2trot": 1.5}
# The horse gathers from its transverse gallop into a canter within a stride: blended over longer,
# canter strides after it (synthesis labels the blend's second half canter) still had the diagonal
# pair apart. (The dog's rotary gallop keeps its 1.25 strides: shorter, its stitches pop more.)
ANIMAL_TRANSITION_STRIDES = {"horse": {"gallop2canter": 1.0}}


def build_clips(animal: str) -> dict[str, Motion]:
    """Every clip of a built-in animal, by name (CLIP_NAMES order), at 60 fps with contacts."""
    skeleton = build_skeleton(animal)
    specs = dict(GAIT_SPECS[animal])
    specs["static"] = static_spec(specs["walk"])
    clips = {"idle": idle_clip(skeleton)}
    starts = {}
    strides = {**TRANSITION_STRIDES, **ANIMAL_TRANSITION_STRIDES.get(animal, {})}
    for gait in GAITS:
        clips[gait], starts[gait] = cyclic_clip(skeleton, specs[gait])
    for name in TRANSITIONS:
        source, target = name.split("2")
        clips[name] = transition_clip(skeleton, specs[source], specs[target], name,
                                      strides=strides.get(name, 1.25),
                                      start=starts.get(source, 0))
    return clips


def export_clips(animal: str, out: Path) -> list[Path]:
    """Write ``<clip>.bvh`` (centimetres) and ``<clip>.contacts.json`` for every clip."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, motion in build_clips(animal).items():
        path = out / f"{name}.bvh"
        bvh.write(motion, path)
        sidecar = out / f"{name}.contacts.json"
        sidecar.write_text(json.dumps(contacts_json(motion.contacts, motion.fps)))
        written += [path, sidecar]
    return written
