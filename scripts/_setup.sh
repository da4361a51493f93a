# Sourced by scripts/serve and scripts/test: make .venv and install the project into it.
# Re-installs only when pyproject.toml or the lock changes (a stamp holds their hash), so repeat runs are fast.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

find_python() {
    for candidate in "${PYTHON:-}" python3.11 python3 python; do
        [ -n "$candidate" ] || continue
        command -v "$candidate" >/dev/null 2>&1 || continue
        if "$candidate" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' 2>/dev/null; then
            echo "$candidate"; return 0
        fi
    done
    echo "QuadSynth needs Python >= 3.11 (set PYTHON=/path/to/python3.11)" >&2
    return 1
}

if [ ! -x .venv/bin/python ]; then
    PY="$(find_python)"
    echo "==> creating .venv with $PY" >&2
    "$PY" -m venv .venv
fi

STAMP=.venv/.quadsynth-installed
WANT="$(cat pyproject.toml requirements-dev.lock | sha256sum | cut -d' ' -f1)"
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$WANT" ]; then
    echo "==> installing quadsynth and its dependencies into .venv (requirements-dev.lock)" >&2
    # Exact versions, every file checked against its hash (refresh with ./scripts/lock); then the
    # project itself, built with the locked setuptools rather than whatever is newest.
    .venv/bin/python -m pip install --quiet --require-hashes -r requirements-dev.lock
    .venv/bin/python -m pip install --quiet --no-deps --no-build-isolation -e .
    echo "$WANT" > "$STAMP"
fi
export PATH="$ROOT/.venv/bin:$PATH"
# A checkout serves and tests the libraries its own code builds (the installed default is a
# per-user data directory, shared by every checkout).
export QUADSYNTH_LIBRARY_DIR="${QUADSYNTH_LIBRARY_DIR:-$ROOT/library}"
