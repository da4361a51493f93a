"""``quadsynth`` console script."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path


def _serve(args: argparse.Namespace, extra: list[str]) -> int:
    import uvicorn

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
