"""The ``quadsynth`` command line: serve, preview (and, as issues land, build, synth, bench)."""
