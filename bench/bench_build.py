"""Library build benchmark: the built-in animals' clips, speed maps and artifact. Prints one JSON object.

    python -m bench.bench_build

Issue 4 asks for the horse "well under 10 s" on a 2-core machine. Best of three; not a test.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

from synth_core.build.animals import build_builtin
from synth_core.build.artifact import load_library, save_library


def main() -> None:
    results: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for animal in ("horse", "dog"):
            build, save, load = [], [], []
            for _ in range(3):
                t0 = time.perf_counter()
                library = build_builtin(animal)
                t1 = time.perf_counter()
                path = save_library(library, Path(tmp) / f"{animal}.qslib.npz")
                t2 = time.perf_counter()
                load_library(path)
                t3 = time.perf_counter()
                build.append(t1 - t0)
                save.append(t2 - t1)
                load.append(t3 - t2)
            clips = sum(m.n_clips for m in library.maps.values())
            results[animal] = {"build_s": round(min(build), 3), "save_s": round(min(save), 3),
                               "load_s": round(min(load), 3), "speed_map_clips": clips,
                               "file_mb": round(path.stat().st_size / 1e6, 2)}
    print(json.dumps({"benchmark": "build", "results": results}))


if __name__ == "__main__":
    main()
