"""The library commands: ``library export``, ``library mesh``, ``build``, ``report``,
``export-speedmap``; and :func:`load_library`, a built-in animal or a library file."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any


def load_library(animal: str, library: str | None) -> Any:
    from synth_core.build.artifact import load_library

    if library:
        return load_library(library)
    if animal not in ("horse", "dog"):
        raise ValueError(f"animal: unknown animal {animal!r} (built-in: horse, dog; or --library FILE)")
    from synth_core.build.library_store import builtin_library

    return builtin_library(animal)


def _library_export(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.builtin.clips import export_clips

    written = export_clips(args.animal, Path(args.out))
    print(f"wrote {len(written)} files to {args.out}")
    return 0


def _library_mesh(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.export.gltf import mesh_glb
    from synth_core.export.mesh import standing_rotations

    library = load_library(args.animal, args.library)
    bind = standing_rotations(library.skeleton, library.idle.rotations[0])
    if args.out:
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(mesh_glb(library.skeleton, library.animal, bind))
        print(out)
    if args.png:
        from quadsynth.mesh_preview import render_mesh

        print(render_mesh(library, args.png, args.gait))
    return 0


def _build(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.build.artifact import save_library

    if args.animal:
        from synth_core.build.animals import build_builtin

        library = build_builtin(args.animal)
    else:
        from synth_core.build.manifest import build_from_manifest

        library = build_from_manifest(Path(args.manifest))
        for doubt in library.extra.get("warnings", []):
            print(f"warning: {doubt}", file=sys.stderr)
    print(save_library(library, Path(args.out)))
    return 0


def _report(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.build.animals import report
    from synth_core.build.artifact import load_library

    figures = report(load_library(args.file))
    print(json.dumps(figures) if args.json else json.dumps(figures, indent=2))
    return 0


def _export_speedmap(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.build.artifact import load_library
    from synth_core.motion import bvh

    library = load_library(args.file)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for gait, speed_map in library.maps.items():
        for i in sorted({0, speed_map.n_clips // 2, speed_map.n_clips - 1}):
            path = out / f"{gait}_{speed_map.speeds[i]:.2f}.bvh"
            bvh.write(speed_map.clip(i), path)
            print(path)
    return 0


def add_library_commands(sub: Any) -> None:
    """`library`, `build`, `report`, `export-speedmap`."""
    library = sub.add_parser("library", help="the built-in animals")
    library_sub = library.add_subparsers(dest="library_command", required=True)
    export = library_sub.add_parser("export", help="write every clip as BVH (cm) + contacts.json")
    export.add_argument("--animal", required=True, choices=["horse", "dog"])
    export.add_argument("--out", required=True, help="output directory (created if missing)")
    export.set_defaults(func=_library_export, passthrough=False)
    mesh = library_sub.add_parser("mesh", help="the animal's skinned mesh as glTF (what GET "
                                  "/v1/libraries/{animal}/mesh.glb serves) and/or a picture of it")
    mesh.add_argument("--animal", default="horse", help="horse or dog (built-in), or with --library its name")
    mesh.add_argument("--library", help="a library file (.qslib.npz) instead of a built-in animal")
    mesh.add_argument("--out", help="write the mesh to FILE.glb")
    mesh.add_argument("--png", help="write a picture: bind pose and a pose of --gait, side and 3/4 views")
    mesh.add_argument("--gait", default="gallop", help="the gait of the picture's second pose (gallop)")
    mesh.set_defaults(func=_library_mesh, passthrough=False)

    build = sub.add_parser("build", help="build a library file: speed maps, motion graph, clips")
    what = build.add_mutually_exclusive_group(required=True)
    what.add_argument("--animal", choices=["horse", "dog"], help="a built-in animal")
    what.add_argument("--manifest", help="a TOML manifest naming your own BVH mocap")
    build.add_argument("--out", required=True, help="the library file to write (.qslib.npz)")
    build.set_defaults(func=_build, passthrough=False)

    rep = sub.add_parser("report", help="quality figures of a library file")
    rep.add_argument("file")
    rep.add_argument("--json", action="store_true", help="one JSON object on one line")
    rep.set_defaults(func=_report, passthrough=False)

    exp = sub.add_parser("export-speedmap", help="the slowest, middle and fastest clip per gait as BVH (cm)")
    exp.add_argument("file")
    exp.add_argument("--out", required=True, help="output directory (created if missing)")
    exp.set_defaults(func=_export_speedmap, passthrough=False)
