"""Import .glb files with Blender's glTF importer and print what it made, one JSON line per file
prefixed ``QUADSYNTH_REPORT``:  blender -b --factory-startup --python blender_import.py -- FILE.glb ...
(tests/test_gltf_skin.py runs it when scripts/ensure-blender finds or installs Blender)."""

import json
import sys

import bpy  # type: ignore[import-not-found]
import numpy

# Debian 12's Blender 3.4 glTF importer still says numpy.bool, which numpy 1.24 (Debian's)
# removed: the builtin is what it meant.
if not hasattr(numpy, "bool"):
    numpy.bool = bool  # type: ignore[attr-defined]

for path in sys.argv[sys.argv.index("--") + 1:]:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)
    objects = list(bpy.data.objects)
    armatures = [o for o in objects if o.type == "ARMATURE"]
    meshes = [o for o in objects if o.type == "MESH"]
    bound = [m for m in meshes if any(mod.type == "ARMATURE" and mod.object is not None
                                      for mod in m.modifiers)]
    print("QUADSYNTH_REPORT " + json.dumps({
        "file": path,
        "armatures": [{"name": a.name, "bones": [b.name for b in a.data.bones]} for a in armatures],
        "meshes": len(meshes), "skinned_meshes": len(bound),
        "empties": sum(o.type == "EMPTY" for o in objects),
        "actions": len(bpy.data.actions),
    }))
