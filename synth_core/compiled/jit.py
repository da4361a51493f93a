"""One source, two runs: numba compiles the planner's scalar code, and the interpreter runs that
same code as its reference (:func:`interpreted`), so the two cannot drift apart.

No fastmath here (unlike the render kernels' few safe flags): the plan must come out the same bit
for bit whichever runs it -- a rounding apart can move a ``floor()`` (a stride frame, a clip) and so
a contact flag.
"""

from __future__ import annotations

import hashlib
import os
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal, TypeVar, cast

try:
    import numba
    AVAILABLE = True
except ImportError:  # pragma: no cover - numba is a dependency; the interpreter runs the same code
    AVAILABLE = False


def source_stamp(root: Path | None = None) -> str:
    """A hash of every ``.py`` file of the core (``root``: synth_core's folder).

    numba's cache checks only the file a kernel is written in: a kernel compiled with a helper
    from another module (foot_kernels' ground targets into kernels' character) or a constant
    imported from one (footlock's PAD) was loaded from the cache unchanged after only that other
    module changed -- an upgrade would run the old code. Caches are kept per stamp instead."""
    root = Path(__file__).resolve().parents[1] if root is None else root
    digest = hashlib.blake2b(digest_size=8)
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def cache_dir(base: str | None = None) -> str:
    """Where the kernels are cached: ``numba-<stamp>`` under ``NUMBA_CACHE_DIR`` (``base``) if
    set, else under this package's ``__pycache__`` (numba's own default place)."""
    base = base or os.environ.get("NUMBA_CACHE_DIR") or str(Path(__file__).resolve().parent / "__pycache__")
    return os.path.join(base, f"numba-{source_stamp()}")


if AVAILABLE:  # before any kernel is decorated: each takes the cache directory then
    numba.config.CACHE_DIR = cache_dir()  # type: ignore[attr-defined]

F = TypeVar("F", bound=Callable[..., Any])
prange: Any = numba.prange if AVAILABLE else range


def jit(parallel: bool = False, inline: Literal["never", "always"] = "never") -> Callable[[F], F]:
    """numba's ``njit`` (cached; ``nogil``: a service calls these from worker threads, its event
    loop keeps answering), or the function itself without numba. ``inline="always"``: into its
    callers, by numba (a call passing arrays costs their reference counts, per frame)."""
    def wrap(f: F) -> F:
        if not AVAILABLE:
            return f
        return cast(F, numba.njit(cache=True, parallel=parallel, nogil=True, inline=inline)(f))
    return wrap


def interpreted(namespace: dict[str, Any], *callees: dict[str, Any]) -> dict[str, Callable[..., Any]]:
    """The :func:`jit` functions of a module (its ``globals()``) as the interpreter runs them: each
    one's Python source, calling the others' Python source too (and ``prange`` as ``range``).
    ``callees``: the namespaces of other modules whose jit functions these call, run as source too
    (each in its own module's globals)."""
    plain: dict[int, Callable[..., Any]] = {}  # id(dispatcher) -> its source as a function
    scopes = []
    for space in (namespace, *callees):
        scope = dict(space, prange=range)
        scopes.append(scope)
        for obj in space.values():
            f = getattr(obj, "py_func", None)  # a numba dispatcher's own function
            if isinstance(f, types.FunctionType) and f.__module__ == space["__name__"]:
                plain[id(obj)] = types.FunctionType(f.__code__, scope, f.__name__, f.__defaults__,
                                                    f.__closure__)
    for scope in scopes:  # every call from one to another reaches the source
        scope.update({name: plain[id(obj)] for name, obj in scope.items() if id(obj) in plain})
    return {name: plain[id(obj)] for name, obj in namespace.items()
            if id(obj) in plain and plain[id(obj)].__module__ == namespace["__name__"]}


def threads() -> int:
    """Threads a parallel kernel may use here (a render-pool thread's own setting: one)."""
    return int(numba.get_num_threads()) if AVAILABLE else 1


# Fast-math flags that change no finite result's rounding: no reassociation, no contraction to
# fused multiply-adds, no approximate reciprocals or functions. With reassociation, LLVM's
# choices depended on how a kernel's callees reach it -- compiled in the process or loaded from
# numba's cache as bitcode -- and a kernel compiled in one process rounded differently from the
# same kernel loaded from the cache in another (a batch's windows then differed from the whole
# batch in the last bits); the other three can depend on it the same way.
# Keeping only these three cost the kernel 0-5% (one thread, 500 x 500 horses, interleaved).
_FASTMATH = {"nnan", "ninf", "nsz"}


def render_jit(parallel: bool = False, inline: Literal["never", "always"] = "never") -> Callable[[F], F]:
    """:func:`jit` with the render kernels' fast-math flags (above) and numpy's error model."""
    def wrap(f: F) -> F:
        if not AVAILABLE:
            return f
        return cast(F, numba.njit(cache=True, parallel=parallel, fastmath=_FASTMATH, error_model="numpy",
                                  nogil=True, inline=inline)(f))
    return wrap
