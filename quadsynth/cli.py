"""``quadsynth`` console script."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

from quadsynth.figure_commands import add_figure_commands
from quadsynth.herd_commands import add_herd_commands
from quadsynth.library_commands import add_library_commands
from quadsynth.serve import run_serve


def _preview(args: argparse.Namespace, extra: list[str]) -> int:
    from quadsynth.preview import load_for_preview, render

    motion = load_for_preview(args.source, unit=args.unit)
    out = render(motion, args.out, start=args.start, stop=args.stop, panels=args.panels,
                 gif_fps=args.gif_fps)
    print(out)
    return 0


def _add_serve_and_preview(sub: Any) -> None:
    """`serve` and `preview`."""
    serve = sub.add_parser("serve", help="start the synthesis service (extra arguments go to uvicorn)")
    serve.add_argument("--host", default="127.0.0.1")
    serve.add_argument("--port", type=int, default=8000)
    serve.set_defaults(func=run_serve, passthrough=True)

    preview = sub.add_parser("preview", help="render a stick-figure PNG contact sheet or GIF")
    preview.add_argument("source", help="a BVH file (a sibling <name>.contacts.json is used if present)")
    preview.add_argument("--out", required=True, help="FILE.png (contact sheet) or FILE.gif")
    preview.add_argument("--unit", default="cm", help="BVH unit: m, cm, mm, in, ft (default cm)")
    preview.add_argument("--start", type=int, default=None, help="first frame (default 0)")
    preview.add_argument("--stop", type=int, default=None, help="frame after the last (default: end)")
    preview.add_argument("--panels", type=int, default=8, help="poses on a PNG contact sheet")
    preview.add_argument("--gif-fps", type=int, default=30, help="GIF frame rate")
    preview.set_defaults(func=_preview, passthrough=False)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="quadsynth", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    for add in (_add_serve_and_preview, add_library_commands, add_herd_commands, add_figure_commands):
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if getattr(args, "command", None) == "eval" and not args.animal:
        args.animal = ["horse"]
    if extra and not args.passthrough:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        return int(args.func(args, extra))
    except (ValueError, OSError) as exc:
        print(f"quadsynth {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
