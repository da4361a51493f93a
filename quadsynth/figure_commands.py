"""The figure commands: ``eval`` (the standard scenario or the edge suite), ``bench`` and
``bench-service``, each printing JSON."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from quadsynth.library_commands import load_library


def _eval(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.quality import evaluate
    from synth_core.runtime.bank import build_bank

    if args.suite == "standard" and (args.scenario or args.out):  # before any library is built
        raise ValueError("--scenario and --out: only with --suite edge")
    if args.suite == "standard" and args.live:
        raise ValueError("--live: only with --suite edge")
    if args.latency_ms is not None and args.live != "low_latency":
        raise ValueError("--latency-ms: only with --live low_latency")
    if args.velocity and args.live != "low_latency":
        raise ValueError("--velocity: only with --live low_latency (the exact mode reads no velocity)")

    libraries: dict[str, Any] = {}
    for name in args.animal:
        if name == "mann_dog":
            from synth_core.build.manifest import build_from_manifest

            libraries[name] = build_from_manifest(Path(args.manifest))
        else:
            libraries[name] = load_library(name, None)
    if args.suite == "edge":
        return _eval_edge(args, {name: build_bank(lib) for name, lib in libraries.items()})
    figures = {name: evaluate.standard(build_bank(lib), args.characters, args.frames, args.seed)
               for name, lib in libraries.items()}
    result = figures[args.animal[0]] if len(figures) == 1 else figures
    print(json.dumps(result) if args.json else json.dumps(result, indent=2))
    return 0


def _eval_edge(args: argparse.Namespace, banks: dict[str, Any]) -> int:
    """``eval --suite edge``: the edge scenarios per animal (JSON); with ``--out DIR`` also
    DIR/edge.json, DIR/edge.md (a table per animal) and DIR/edge_worst_<animal>.png."""
    from synth_core.quality import evaluate
    from synth_core.runtime.live import LOW_LATENCY_MS

    suites: dict[str, Any] = {}
    kept: dict[str, dict[str, Any]] = {}
    for name, bank in banks.items():
        kept[name] = {}
        budget = (args.latency_ms or LOW_LATENCY_MS) if args.live == "low_latency" else None
        suites[name] = evaluate.edge_suite(bank, args.seed, args.scenario, keep=kept[name],
                                           live=args.live is not None, latency_ms=budget,
                                           velocity=args.velocity)
        scenarios = suites[name]["scenarios"]
        failed = sum(bool(s["failed"]) for s in scenarios.values())
        print(f"{name}: {failed} of {len(scenarios)} scenarios miss a target", file=sys.stderr)
    result = suites[args.animal[0]] if len(suites) == 1 else suites
    if args.out:
        from quadsynth.edge_report import markdown, render_worst

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "edge.json").write_text(json.dumps(result, indent=2))
        (out / "edge.md").write_text(markdown(suites))
        for name, suite in suites.items():
            worst = evaluate.worst_scenario(suite)
            if worst in kept[name]:
                scenario, res = kept[name][worst]
                sheet = render_worst(banks[name], scenario, res, suite["scenarios"][worst],
                                     out / f"edge_worst_{name}.png")
                print(f"{name}: worst scenario {worst}: {sheet}", file=sys.stderr)
    print(json.dumps(result) if args.json else json.dumps(result, indent=2))
    return 0


def _bench(args: argparse.Namespace, extra: list[str]) -> int:
    from quadsynth.bench import run

    figures = run(args.quick)
    print(json.dumps(figures) if args.json else json.dumps(figures, indent=2))
    return 0


def _bench_service(args: argparse.Namespace, extra: list[str]) -> int:
    from quadsynth.bench_service import run

    figures = run(args.url, args.repeats, args.encodings, args.live_scale, args.latency)
    print(json.dumps(figures) if args.json else json.dumps(figures, indent=2))
    return 0


def add_figure_commands(sub: Any) -> None:
    """`eval`, `bench`, `bench-service`."""
    ev = sub.add_parser("eval", help="quality figures of the standard scenario or the edge suite (JSON)")
    ev.add_argument("--animal", action="append", choices=["horse", "dog", "mann_dog"],
                    help="repeatable (default: horse)")
    ev.add_argument("--manifest", default="tests/fixtures/mann_dog.toml", help="for mann_dog")
    ev.add_argument("--characters", type=int, default=500)
    ev.add_argument("--frames", type=int, default=500)
    ev.add_argument("--seed", type=int, default=0)
    ev.add_argument("--json", action="store_true", help="one JSON object on one line")
    ev.add_argument("--suite", choices=["standard", "edge"], default="standard",
                    help="standard: one crowd-sim herd (--characters, --frames); edge: stops, creeps, "
                    "turns, jitter, a too-fast character, sizes (synth_core/quality/edge.py), against "
                    "issue 27's "
                    "targets")
    ev.add_argument("--scenario", action="append", default=None,
                    help="edge suite: only this scenario (repeatable; default: all)")
    ev.add_argument("--out", default=None, help="edge suite: also write DIR/edge.json, DIR/edge.md and a "
                    "contact sheet of each animal's worst scenario, DIR/edge_worst_<animal>.png")
    ev.add_argument("--live", choices=["exact", "low_latency"], default=None,
                    help="edge suite: each scenario played through a live session in this mode, fed a "
                    "point a tick (default: the batch)")
    ev.add_argument("--latency-ms", type=float, default=None,
                    help="with --live low_latency: the budget (default: the low_latency profile's)")
    ev.add_argument("--velocity", action="store_true",
                    help="with --live low_latency: each scenario's simulator sends every point's velocity "
                    "(its path's, at the frame the point was sampled at)")
    ev.set_defaults(func=_eval, passthrough=False)

    be = sub.add_parser("bench", help="synthesis speed on the built-in horse (JSON)")
    be.add_argument("--quick", action="store_true", help="stop at 1,000 characters / 1,000 frames")
    be.add_argument("--json", action="store_true", help="one JSON object on one line")
    be.set_defaults(func=_bench, passthrough=False)

    bs = sub.add_parser("bench-service", help="REST and WebSocket speed over loopback (JSON)")
    bs.add_argument("--url", default=None, help="a running service (default: start one on a free port)")
    bs.add_argument("--repeats", type=int, default=4, help="runs per figure; the best counts")
    bs.add_argument("--json", action="store_true", help="one JSON object on one line")
    bs.add_argument("--encodings", action="store_true",
                    help="only the bytes per joint-frame and per second of each encoding and LOD mix")
    bs.add_argument("--live-scale", action="store_true",
                    help="only the largest live herd held at 30 fps per encoding and LOD mix, and its "
                         "bytes per second on the wire (with --encodings: both)")
    bs.add_argument("--latency", action="store_true",
                    help="only the live pose latency (p50/p99 from point sent to pose received) per mode")
    bs.set_defaults(func=_bench_service, passthrough=False)
