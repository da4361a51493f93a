"""Service benchmark: ``python -m bench.bench_service [--url URL]`` (same as ``quadsynth
bench-service --json``; see :mod:`quadsynth.bench_service`). Prints one JSON object. Not a test."""

from __future__ import annotations

import argparse
import json

from quadsynth.bench_service import run

if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", default=None, help="a running service (default: start one)")
    print(json.dumps(run(parser.parse_args().url)))
