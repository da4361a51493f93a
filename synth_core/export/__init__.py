"""Writing synthesized crowds for other tools: BVH per character, one glTF 2.0 binary per herd."""

from synth_core.export.crowd import character_motion, write_bvh_files
from synth_core.export.gltf import write_glb

__all__ = ["character_motion", "write_bvh_files", "write_glb"]
