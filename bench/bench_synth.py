"""Run-time synthesis benchmark: ``python -m bench.bench_synth [--quick]`` (same as
``quadsynth bench --json``; see :mod:`quadsynth.bench`). Prints one JSON object. Not a test."""

from __future__ import annotations

import argparse
import json

from quadsynth.bench import run

if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="stop at 1,000 characters / 1,000 frames")
    print(json.dumps(run(parser.parse_args().quick), indent=2))
