"""``quadsynth`` console script."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from synth_core import SIZE_MATCHING, TEMPO_SPREAD

if TYPE_CHECKING:
    from synth_core.motion.skeleton import Skeleton
    from synth_core.runtime.synthesis import Result


def _step(message: str) -> None:
    print(f"quadsynth serve: {message}", file=sys.stderr, flush=True)


def _check_port(host: str, port: int) -> None:
    """Fail fast, before minutes of building and compiling, when the port is taken (uvicorn binds
    it again once the workers start: a port taken in between still fails there)."""
    import socket

    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn binds it
        try:
            probe.bind((host, port))
        except OSError as exc:
            why = exc.strerror or str(exc)
            raise OSError(f"cannot listen on {host}:{port}: {why} (--port to choose another)") from None


def _compile_kernels() -> None:
    """Kernels into numba's cache first, in a process of their own: every worker then runs the
    same cached code (see service.warmup.compile_kernels). A note every 15 s while it runs."""
    _step("kernels: compiling into numba's cache (the first start after an install takes 1-2 min; "
          "later starts load them)")
    t0 = time.perf_counter()
    code = "from service.warmup import compile_kernels; compile_kernels()"
    proc = subprocess.Popen([sys.executable, "-c", code])
    while True:
        try:
            proc.wait(timeout=15)
            break
        except subprocess.TimeoutExpired:
            _step(f"kernels: still compiling ({time.perf_counter() - t0:.0f} s)")
    if proc.returncode != 0:  # the workers compile what they need themselves: slower, not fatal
        _step(f"kernels: the compile step failed (exit {proc.returncode}); workers will compile their own")
    else:
        _step(f"kernels: ready in {time.perf_counter() - t0:.1f} s")


def _serve(args: argparse.Namespace, extra: list[str]) -> int:
    import uvicorn

    from service.cpus import available_cpus
    from service.settings import Settings
    from synth_core.build.library_store import ensure_builtin_libraries, library_dir

    if not any(a.split("=")[0] in ("--fd", "--uds") for a in extra):
        _check_port(args.host, args.port)
        _step(f"port {args.host}:{args.port} is free")
    directory = library_dir()
    t0 = time.perf_counter()
    try:
        built = ensure_builtin_libraries(directory)
    except OSError as exc:  # a read-only directory: /readyz names what is missing
        _step(f"libraries: cannot build the missing built-in ones in {directory}: {exc}")
        built = []
    names = sorted(p.name for p in directory.glob("*.qslib.npz")) if directory.is_dir() else []
    made = f" (built {', '.join(p.name for p in built)} in {time.perf_counter() - t0:.1f} s)" if built else ""
    _step(f"libraries: {', '.join(names) or 'none'} in {directory}{made}")
    cores = available_cpus()
    # numba's thread pool as wide as the CPU quota, not the host (service.cpus).
    os.environ.setdefault("NUMBA_NUM_THREADS", str(cores))
    _compile_kernels()

    # Run uvicorn's own CLI so every uvicorn option (--workers, --log-level, ...) passes through.
    # In-flight requests get drain_grace_s after SIGTERM (uvicorn's default is to wait forever).
    grace = [] if any(a.startswith("--timeout-graceful-shutdown") for a in extra) else [
        "--timeout-graceful-shutdown", str(int(Settings.from_env().drain_grace_s))]
    # One worker process per core of the CPU quota unless told (--workers N, or uvicorn's
    # WEB_CONCURRENCY): the event loop, body decoding and packing are single-threaded per process;
    # synthesis kernels use every core in each process, so one busy worker still has the whole machine.
    given = any(a == "--workers" or a.startswith("--workers=") for a in extra)
    workers = [] if given or os.environ.get("WEB_CONCURRENCY") else ["--workers", str(cores)]
    _step(f"starting uvicorn on http://{args.host}:{args.port} ({' '.join(workers) or 'workers as given'}; "
          "/readyz answers 200 once the libraries are loaded)")
    argv = ["service.app:create_app", "--factory", "--host", args.host, "--port", str(args.port),
            "--ws", "websockets-sansio", "--ws-per-message-deflate", "false",
            "--ws-ping-interval", "20", "--ws-ping-timeout", "20",
            "--ws-max-size", str(Settings.from_env().max_body_bytes), *grace, *workers, *extra]
    from service import supervisor

    supervisor.install()  # several workers drain as one on SIGTERM (see service.supervisor)
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
    from synth_core.builtin.clips import export_clips

    written = export_clips(args.animal, Path(args.out))
    print(f"wrote {len(written)} files to {args.out}")
    return 0


def _library_mesh(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.export.gltf import mesh_glb
    from synth_core.export.mesh import standing_rotations

    library = _load_library(args.animal, args.library)
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


def _progress(label: str) -> Callable[[int, int], None]:
    """A one-line progress bar on stderr (only when it is a terminal, or for long runs)."""
    start = time.perf_counter()

    def show(done: int, total: int) -> None:
        if not sys.stderr.isatty() and time.perf_counter() - start < 2.0 and done < total:
            return
        width = 30
        filled = int(width * done / max(total, 1))
        print(f"\r{label} [{'#' * filled}{'.' * (width - filled)}] {done}/{total}", end="",
              file=sys.stderr, flush=True)
        if done >= total:
            print(file=sys.stderr)
    return show


def _load_library(animal: str, library: str | None) -> Any:
    from synth_core.build.artifact import load_library

    if library:
        return load_library(library)
    if animal not in ("horse", "dog"):
        raise ValueError(f"animal: unknown animal {animal!r} (built-in: horse, dog; or --library FILE)")
    from synth_core.build.library_store import builtin_library

    return builtin_library(animal)


def _crowd_sim(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.quality import herd_sim as crowd
    from synth_core.runtime import trajectory_files as crowd_io

    positions = crowd.simulate(args.characters, args.frames, seed=args.seed, fps=args.fps,
                               top=args.top_speed, spacing=args.spacing)
    print(crowd_io.write_npz(args.out, positions, args.fps))
    return 0


def _synth(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.runtime import terrain
    from synth_core.runtime import trajectory_files as crowd_io
    from synth_core.runtime.bank import build_bank
    from synth_core.runtime.synthesis import Options, synthesize

    traj = crowd_io.read(args.trajectories, args.fps)
    ground = terrain.read(args.ground) if args.ground else None
    library = _load_library(args.animal, args.library)
    bank = build_bank(library)
    options = Options(sigma=args.sigma, seed=args.seed, scale_range=(args.scale_min, args.scale_max),
                      skip_invalid=args.skip_invalid, resample=args.resample,
                      size_matching=args.size_matching, tempo_spread=args.tempo_spread, ground=ground)
    result = synthesize(bank, traj.positions, traj.fps, options=options, ids=traj.ids,
                        progress=_progress("synthesizing"))
    ids = [traj.ids[c] for c in result.kept]
    from synth_core.export.mesh import standing_rotations

    bind = standing_rotations(library.skeleton, library.idle.rotations[0])
    return _write_herd(args, _Herd(bank.skeleton, result, ids, traj.ids, bank.fps, bank.hubs, library.animal),
                       bind)


def _client_synth(args: argparse.Namespace, extra: list[str]) -> int:
    import httpx

    from api_schemas.client import ServiceError
    from quadsynth import remote
    from synth_core.runtime import trajectory_files as crowd_io

    traj = crowd_io.read(args.trajectories, args.fps)
    more: dict[str, Any] = {}
    if args.ground:  # checked here, sent as the request's 'ground'
        from api_schemas.client import ground
        from synth_core.runtime import terrain

        field = terrain.read(args.ground)
        more["ground"] = ground(field.heights, field.origin, field.spacing)
    try:
        herd = remote.synthesize(args.url, traj.positions, traj.fps, traj.ids, animal=args.animal,
                                 progress=_progress("requests"), seed=args.seed, sigma=args.sigma,
                                 scale_min=args.scale_min, scale_max=args.scale_max,
                                 skip_invalid=args.skip_invalid, encoding=args.encoding,
                                 resample=args.resample, size_matching=args.size_matching,
                                 tempo_spread=args.tempo_spread, concurrency=args.concurrency, **more)
    except ServiceError as exc:
        raise ValueError(f"the service refused: {exc}") from None
    except httpx.HTTPError as exc:
        raise ValueError(f"cannot reach the service at {args.url}: {exc}") from None
    print(f"{herd.requests} request(s) to {args.url}", file=sys.stderr)
    bind = remote.bind_pose(args.url, args.animal, herd.skeleton) if args.glb else None
    return _write_herd(args, _Herd(herd.skeleton, herd.result, herd.ids, traj.ids, herd.fps, herd.hubs,
                                   args.animal), bind)


@dataclass(frozen=True)
class _Herd:
    """A herd's motion as `synth` and `client synth` write it."""

    skeleton: Skeleton
    result: Result
    ids: list[str]  # the characters made
    all_ids: list[str]  # every character asked for (the result's indices)
    fps: float
    hubs: tuple[str, ...]
    animal: str


def _write_herd(args: argparse.Namespace, herd: _Herd, bind: np.ndarray | None) -> int:
    """What `synth` and `client synth` write: motion.npz, summary.json, and BVH / glTF / GIF if asked."""
    skeleton, result, ids, all_ids, fps = herd.skeleton, herd.result, herd.ids, herd.all_ids, herd.fps
    from synth_core.export import write_bvh_files, write_glb

    for c, why in sorted(result.rejected.items()):
        print(f"skipped character {all_ids[c]}: {why}", file=sys.stderr)
    for c, why in sorted(result.warnings.items()):
        print(f"warning: character {all_ids[c]}: {why}", file=sys.stderr)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary = {"characters": len(ids), "frames": int(result.root_pos.shape[1]), "fps": fps,
               "resample_rate": result.resample_rate, "animal": herd.animal,
               "skipped": {all_ids[c]: why for c, why in result.rejected.items()},
               "warnings": {all_ids[c]: why for c, why in result.warnings.items()}}
    np.savez_compressed(out / "motion.npz", root_pos=result.root_pos, rotations=result.rotations,
                        gait=result.gait, contacts=result.contacts, scales=result.scales, ids=np.array(ids))
    if args.bvh:
        write_bvh_files(skeleton, result, ids, out, fps, _progress("writing BVH"))
    if args.glb:
        print(write_glb(skeleton, result, ids, args.glb, fps, bind))
    if args.preview:
        from quadsynth.herd_preview import render_herd

        print(render_herd(skeleton, result, args.preview, fps, herd.hubs))
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary))
    return 0


def _eval(args: argparse.Namespace, extra: list[str]) -> int:
    from synth_core.quality import evaluate
    from synth_core.runtime.bank import build_bank

    if args.suite == "standard" and (args.scenario or args.out):  # before any library is built
        raise ValueError("--scenario and --out: only with --suite edge")
    if args.suite == "standard" and args.live:
        raise ValueError("--live: only with --suite edge")
    if args.latency_ms is not None and args.live != "low_latency":
        raise ValueError("--latency-ms: only with --live low_latency")

    libraries: dict[str, Any] = {}
    for name in args.animal:
        if name == "mann_dog":
            from synth_core.build.manifest import build_from_manifest

            libraries[name] = build_from_manifest(Path(args.manifest))
        else:
            libraries[name] = _load_library(name, None)
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
                                           live=args.live is not None, latency_ms=budget)
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

    figures = run(args.url, args.repeats, args.encodings, args.latency)
    print(json.dumps(figures) if args.json else json.dumps(figures, indent=2))
    return 0


def _herd_arguments(parser: argparse.ArgumentParser) -> None:
    """The options `synth` and `client synth` share."""
    parser.add_argument("--trajectories", required=True, help="traj.npz (positions (C, F, 3)) or traj.csv "
                        "(header id,frame,x,y,z in any order)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fps", type=float, default=None, help="trajectory frame rate (default: the "
                        "file's, CSV 60)")
    parser.add_argument("--sigma", type=float, default=4.0, help="trajectory smoothing, frames (default 4)")
    parser.add_argument("--scale-min", type=float, default=0.8)
    parser.add_argument("--scale-max", type=float, default=1.2)
    parser.add_argument("--skip-invalid", action="store_true", help="skip bad characters instead of failing")
    parser.add_argument("--resample", action="store_true",
                        help="the paper's global resampling: a character too fast for the library slows "
                             "the whole herd's clock (default: the clock is kept; a character too fast "
                             "even at its fastest stride rate is reported on stderr)")
    parser.add_argument("--size-matching", choices=SIZE_MATCHING, default="froude",
                        help="froude (default): a character of scale h takes the gait of the same Froude "
                             "number and steps at 1/sqrt(h) the frequency; geometric: the paper's s/h")
    parser.add_argument("--tempo-spread", type=float, default=TEMPO_SPREAD,
                        help=f"each character's stride frequency varies by up to this share (default "
                             f"{TEMPO_SPREAD}; 0: none)")
    parser.add_argument("--ground", help="the terrain: FILE.npz (heights (rows z, columns x), origin (x, z), "
                                         "spacing) or FILE.json with the same keys (docs/terrain.md); "
                                         "default: the trajectories' y is the ground")
    parser.add_argument("--out", required=True, help="output directory: motion.npz, summary.json, BVH files")
    parser.add_argument("--bvh", action="store_true", help="write DIR/<id>.bvh per character (centimetres) "
                        "and DIR/<id>.contacts.json (gaits and foot contacts)")
    parser.add_argument("--glb", help="write the herd as one glTF 2.0 binary FILE.glb: a skinned mesh per "
                        "character, one animation, gaits and contacts in each mesh node's extras")
    parser.add_argument("--preview", help="write a herd preview: FILE.gif (animated) or FILE.png "
                        "(a contact sheet)")


def _add_serve_and_preview(sub: Any) -> None:
    """`serve` and `preview`."""
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


def _add_library_commands(sub: Any) -> None:
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


def _add_herd_commands(sub: Any) -> None:
    """`crowd-sim`, `synth`, `client synth`."""
    sim = sub.add_parser("crowd-sim", help="herd trajectories on a looped path (positions (C, F, 3) .npz)")
    sim.add_argument("--characters", type=int, required=True)
    sim.add_argument("--frames", type=int, required=True)
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--fps", type=float, default=60.0)
    sim.add_argument("--top-speed", type=float, default=7.0, help="m/s the herd reaches (default 7)")
    sim.add_argument("--spacing", type=float, default=3.0, help="metres between neighbours (default 3)")
    sim.add_argument("--out", required=True, help="FILE.npz")
    sim.set_defaults(func=_crowd_sim, passthrough=False)

    syn = sub.add_parser("synth", help="synthesize a herd's motion from trajectories (.npz or .csv)")
    syn.add_argument("--animal", default="horse", help="built-in animal: horse or dog (default horse)")
    syn.add_argument("--library", help="a library file (.qslib.npz) instead of a built-in animal")
    _herd_arguments(syn)
    syn.set_defaults(func=_synth, passthrough=False)

    client = sub.add_parser("client", help="use a running QuadSynth service")
    client_sub = client.add_subparsers(dest="client_command", required=True)
    csyn = client_sub.add_parser("synth", help="`synth` done by the service at --url (same outputs)")
    csyn.add_argument("--url", required=True, help="the service, e.g. http://127.0.0.1:8000")
    csyn.add_argument("--animal", default="horse", help="a library the service has (default horse)")
    csyn.add_argument("--encoding", default="f32", choices=["f32", "i16", "s48"],
                      help="rotations on the wire (default f32: the files get full precision)")
    csyn.add_argument("--concurrency", type=int, default=1, metavar="N",
                      help="requests in flight at once: the herd in >= N pieces, shared by the replicas "
                           "behind a load balancer (default 1)")
    _herd_arguments(csyn)
    csyn.set_defaults(func=_client_synth, passthrough=False)


def _add_figures(sub: Any) -> None:
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
    bs.add_argument("--latency", action="store_true",
                    help="only the live pose latency (p50/p99 from point sent to pose received) per mode")
    bs.set_defaults(func=_bench_service, passthrough=False)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="quadsynth", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    for add in (_add_serve_and_preview, _add_library_commands, _add_herd_commands, _add_figures):
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
