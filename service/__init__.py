"""The QuadSynth web service: a thin FastAPI shell over :mod:`synth_core`."""
