# QuadSynth synthesis service.
#   docker build -t quadsynth .          docker run -p 8000:8000 quadsynth
# The base is pinned by version (and can be pinned by digest, or replaced: scripts/container-test
# builds on a Debian image of its own) through a build argument:
#   docker build --build-arg BASE_IMAGE=python:3.11.14-slim-bookworm@sha256:<digest> -t quadsynth .
# Any base with python3 >= 3.11, its venv module and useradd will do.
ARG BASE_IMAGE=python:3.11.14-slim-bookworm
FROM ${BASE_IMAGE}

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1 \
    VIRTUAL_ENV=/opt/quadsynth PATH=/opt/quadsynth/bin:$PATH \
    QUADSYNTH_LIBRARY_DIR=/srv/quadsynth/library NUMBA_CACHE_DIR=/srv/quadsynth/numba-cache

RUN useradd --create-home --uid 10001 quadsynth

# Dependencies first, exactly as locked (versions and hashes: scripts/lock), in a layer of their
# own that a change to the code does not rebuild.
COPY requirements.lock /tmp/requirements.lock
RUN python3 -m venv "$VIRTUAL_ENV" \
    && pip install --require-hashes -r /tmp/requirements.lock \
    && rm /tmp/requirements.lock

# The code, installed into the venv and its sources removed: one copy, the one every process imports
# (a copy left in the working directory would shadow it, and numba would cache the wrong one).
COPY pyproject.toml README.md /tmp/src/
COPY synth_core /tmp/src/synth_core
COPY api_schemas /tmp/src/api_schemas
COPY service /tmp/src/service
# The JS client the viewer runs on (its one home is js/, the npm package; service.web finds it here).
COPY js/src /tmp/src/service/static/client
COPY quadsynth /tmp/src/quadsynth
RUN pip install --no-deps --no-build-isolation /tmp/src && rm -rf /tmp/src

# The libraries (speed maps + motion graph) are built into the image, owned by root and readable by
# all, each stamped with the code that built it: the service reads them and cannot change them.
RUN python -c "from pathlib import Path; from synth_core.build.library_store import ensure_builtin_libraries as e; e(Path('$QUADSYNTH_LIBRARY_DIR'))" \
    && mkdir -p "$NUMBA_CACHE_DIR" && chown quadsynth: "$NUMBA_CACHE_DIR"

# The kernels compiled into numba's cache by the service user, for the installed package: a start
# loads them instead of compiling (numba keys the cache by source file and CPU: an image run on a
# different CPU model compiles once more at its first start, into the same writable cache).
USER quadsynth
WORKDIR /home/quadsynth
RUN python -c "from service.warmup import compile_kernels; compile_kernels()"

ENV PORT=8000
EXPOSE 8000
# Healthy = ready: every configured library loaded (/readyz is 503 while one is missing or failed,
# and while draining), so nothing routes to a replica that cannot serve.
HEALTHCHECK --interval=10s --timeout=2s --start-period=30s --retries=3 \
    CMD python -c "import urllib.request,sys; sys.exit(urllib.request.urlopen('http://127.0.0.1:$PORT/readyz', timeout=2).status != 200)"
# Worker processes: one per core of the container's CPU quota (service.cpus), or WORKERS; PORT.
# SIGTERM drains (QUADSYNTH_DRAIN_GRACE_S).
CMD ["sh", "-c", "exec quadsynth serve --host 0.0.0.0 --port $PORT ${WORKERS:+--workers $WORKERS}"]
