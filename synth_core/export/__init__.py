"""Writing synthesized crowds for other tools: BVH per character (with a gait and contact
sidecar), one glTF 2.0 binary per herd with a skinned mesh per character, and each library's
procedural skinned mesh (:mod:`synth_core.export.mesh`, :func:`synth_core.export.gltf.mesh_glb`)."""

from synth_core.export.character import character_motion, write_bvh_files
from synth_core.export.gltf import mesh_glb, write_glb

__all__ = ["character_motion", "mesh_glb", "write_bvh_files", "write_glb"]
