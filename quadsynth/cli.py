"""``quadsynth`` console script."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path


def _serve(args: argparse.Namespace, extra: list[str]) -> int:
    import uvicorn

    from service.libraries import ensure_builtin_libraries, library_dir

    for path in ensure_builtin_libraries(library_dir()):
        print(f"built {path}", file=sys.stderr)

    # Run uvicorn's own CLI so every uvicorn option (--workers, --log-level, ...) passes through.
    argv = ["service.app:create_app", "--factory", "--host", args.host, "--port", str(args.port),
            "--ws-per-message-deflate", "false", *extra]
    uvicorn.main.main(args=argv, prog_name="quadsynth serve")
    return 0


def _preview(args: argparse.Namespace, extra: list[str]) -> int:
    from quadsynth.preview import load_for_preview, render

    motion = load_for_preview(args.source, unit=args.unit)
    out = render(motion, args.out, start=args.start, stop=args.stop, panels=args.panels,
                 gif_fps=args.gif_fps)
    print(out)
    return 0


def _library_export(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.library.clips import export_clips

    written = export_clips(args.animal, Path(args.out))
    print(f"wrote {len(written)} files to {args.out}")
    return 0


def _build(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.artifact import save_library

    if args.animal:
        from synth_core.build import build_builtin

        library = build_builtin(args.animal)
    else:
        from synth_core.manifest import build_from_manifest

        library = build_from_manifest(Path(args.manifest))
    print(save_library(library, Path(args.out)))
    return 0


def _report(args: argparse.Namespace, extra: list[str]) -> int:
    import json

    from synth_core.artifact import load_library
    from synth_core.build import report

    figures = report(load_library(args.file))
    print(json.dumps(figures) if args.json else json.dumps(figures, indent=2))
    return 0


def _export_speedmap(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core import bvh
    from synth_core.artifact import load_library

    library = load_library(args.file)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for gait, speed_map in library.maps.items():
        for i in sorted({0, speed_map.n_clips // 2, speed_map.n_clips - 1}):
            path = out / f"{gait}_{speed_map.speeds[i]:.2f}.bvh"
            bvh.write(speed_map.clip(i), path)
            print(path)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="quadsynth", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    serve = sub.add_parser("serve", help="start the synthesis service (extra arguments go to uvicorn)")
    serve.add_argument("--host", default="127.0.0.1")
    serve.add_argument("--port", type=int, default=8000)
    serve.set_defaults(func=_serve, passthrough=True)

    preview = sub.add_parser("preview", help="render a stick-figure PNG contact sheet or GIF")
    preview.add_argument("source", help="a BVH file (a sibling <name>.contacts.json is used if present)")
    preview.add_argument("--out", required=True, help="FILE.png (contact sheet) or FILE.gif")
    preview.add_argument("--unit", default="cm", help="BVH unit: m, cm, mm, in, ft (default cm)")
    preview.add_argument("--start", type=int, default=None, help="first frame (default 0)")
    preview.add_argument("--stop", type=int, default=None, help="frame after the last (default: end)")
    preview.add_argument("--panels", type=int, default=8, help="poses on a PNG contact sheet")
    preview.add_argument("--gif-fps", type=int, default=30, help="GIF frame rate")
    preview.set_defaults(func=_preview, passthrough=False)

    library = sub.add_parser("library", help="the built-in animals")
    library_sub = library.add_subparsers(dest="library_command", required=True)
    export = library_sub.add_parser("export", help="write every clip as BVH (cm) + contacts.json")
    export.add_argument("--animal", required=True, choices=["horse", "dog"])
    export.add_argument("--out", required=True, help="output directory (created if missing)")
    export.set_defaults(func=_library_export, passthrough=False)

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
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and not args.passthrough:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        return int(args.func(args, extra))
    except (ValueError, OSError) as exc:
        print(f"quadsynth {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
