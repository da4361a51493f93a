"""The herd commands: ``crowd-sim``, ``synth`` and ``client synth`` (the same outputs, made by a
running service), and what both synth commands write."""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from quadsynth.library_commands import load_library
from synth_core import SIZE_MATCHING, TEMPO_SPREAD

if TYPE_CHECKING:
    from synth_core.motion.skeleton import Skeleton
    from synth_core.runtime.synthesis import Result


def progress(label: str) -> Callable[[int, int], None]:
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
    library = load_library(args.animal, args.library)
    bank = build_bank(library)
    options = Options(sigma=args.sigma, seed=args.seed, scale_range=(args.scale_min, args.scale_max),
                      skip_invalid=args.skip_invalid, resample=args.resample,
                      size_matching=args.size_matching, tempo_spread=args.tempo_spread, ground=ground)
    result = synthesize(bank, traj.positions, traj.fps, options=options, ids=traj.ids,
                        progress=progress("synthesizing"))
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
                                 progress=progress("requests"), seed=args.seed, sigma=args.sigma,
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
        write_bvh_files(skeleton, result, ids, out, fps, progress("writing BVH"))
    if args.glb:
        print(write_glb(skeleton, result, ids, args.glb, fps, bind))
    if args.preview:
        from quadsynth.herd_preview import render_herd

        print(render_herd(skeleton, result, args.preview, fps, herd.hubs))
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary))
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


def add_herd_commands(sub: Any) -> None:
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
