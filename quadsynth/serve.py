"""``quadsynth serve``: check the port, build the missing built-in libraries, compile the kernels
once into numba's cache, then run uvicorn's own CLI on the service's app factory."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time


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


def run_serve(args: argparse.Namespace, extra: list[str]) -> int:
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
