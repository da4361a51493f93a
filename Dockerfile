# QuadSynth synthesis service. Build: docker build -t quadsynth .   Run: docker run -p 8000:8000 quadsynth
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 \
    QUADSYNTH_LIBRARY_DIR=/srv/quadsynth/library NUMBA_CACHE_DIR=/srv/quadsynth/numba-cache

RUN useradd --create-home --uid 10001 quadsynth
WORKDIR /srv/quadsynth
COPY pyproject.toml README.md ./
COPY synth_core ./synth_core
COPY api_schemas ./api_schemas
COPY service ./service
# The JS client the viewer runs on (its one home is js/, the npm package; service.web finds it here).
COPY js/src ./service/static/client
COPY quadsynth ./quadsynth
RUN pip install . \
    # The libraries (speed maps + motion graph) are built into the image, not at start-up.
    && python -c "from pathlib import Path; from service.libraries import ensure_builtin_libraries as e; e(Path('$QUADSYNTH_LIBRARY_DIR'))" \
    && mkdir -p "$NUMBA_CACHE_DIR" \
    # ... and the kernels compiled into numba's cache, so every worker runs the same code.
    && python -c "from service.app import compile_kernels; compile_kernels()" \
    && chown -R quadsynth "$NUMBA_CACHE_DIR"

USER quadsynth
EXPOSE 8000
HEALTHCHECK --interval=10s --timeout=2s --start-period=60s --retries=3 \
    CMD python -c "import urllib.request,sys; sys.exit(urllib.request.urlopen('http://127.0.0.1:8000/livez', timeout=2).status != 200)"
# One uvicorn worker process per core (WORKERS overrides); SIGTERM drains (QUADSYNTH_DRAIN_GRACE_S).
CMD ["sh", "-c", "exec quadsynth serve --host 0.0.0.0 --port 8000 --workers ${WORKERS:-$(nproc)}"]
