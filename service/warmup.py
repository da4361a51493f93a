"""Kernels and packers compiled (or loaded from numba's cache) before a worker says ready."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from service.libraries import LibraryRegistry
from synth_core.build.library_store import library_dir


def compile_kernels(directory: Path | None = None) -> None:
    """Compile (or load) every kernel the service uses, so numba's on-disk cache holds them.

    ``quadsynth serve`` runs this in a process of its own before the workers start: then every
    worker loads the same machine code from the cache. A kernel compiled in the process that
    uses it and the same kernel loaded from the cache differ in the last bit of some leg
    rotations (float32, measured), so without this the first process after an empty cache
    would answer slightly differently from every later one."""
    registry = LibraryRegistry(directory if directory is not None else library_dir())
    registry.load()
    warm_up(registry)


def warm_up(registry: LibraryRegistry) -> None:
    """Load (or compile) the kernels and packers before /readyz says ready, so the first
    request does not pay for it."""
    from api_schemas import delta
    from api_schemas.packing import pack_rotations
    from synth_core.runtime.live import LiveSynth
    from synth_core.runtime.streaming import BatchStream
    from synth_core.runtime.synthesis import synthesize

    path = np.zeros((1, 30, 3))
    path[0, :, 2] = np.linspace(0.0, 0.3, 30)
    # A live session's kernels take views of its buffers: two characters, so that they are views
    # as in any real session (of one, numba sees contiguous arrays and compiles another version).
    walk = np.zeros((2, 200, 3))
    walk[:, :, 2] = np.linspace(0.0, 8.0, 200)
    for bank in registry.banks.values():
        result = synthesize(bank, path)
        for encoding in ("s48", "i16"):
            pack_rotations(result.rotations, encoding)
        delta.encode(result.rotations, delta.joint_steps(bank.skeleton.parents, bank.skeleton.offsets))
        for _ in BatchStream(bank, path, chunk_frames=10).windows():
            pass
        live = LiveSynth(bank, 2, 30.0)
        live.append(walk)
        live.finish()
