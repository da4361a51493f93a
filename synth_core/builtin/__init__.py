"""QuadSynth's built-in animals: procedural skeletons (and, in later issues, their gait clips).

No licensed mocap ships in the product; these animals are made from published anatomy and gait
biomechanics. Each module cites where its numbers come from.
"""

from synth_core.builtin.skeletons import BUILTIN_ANIMALS, build_skeleton, dog_skeleton, horse_skeleton

LIBRARY_FPS = 60.0
"""Frame rate of every built-in clip (the paper's horse data is 60 fps too)."""

__all__ = ["BUILTIN_ANIMALS", "LIBRARY_FPS", "build_skeleton", "dog_skeleton", "horse_skeleton"]
