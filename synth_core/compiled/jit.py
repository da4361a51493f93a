"""One source, two runs: numba compiles the planner's scalar code, and the interpreter runs that
same code as its reference (:func:`interpreted`), so the two cannot drift apart.

No fastmath here (unlike the render kernels' few safe flags): the plan must come out the same bit
for bit whichever runs it -- a rounding apart can move a ``floor()`` (a stride frame, a clip) and so
a contact flag.
"""

from __future__ import annotations

import types
from collections.abc import Callable
from typing import Any, Literal, TypeVar, cast

try:
    import numba
    AVAILABLE = True
except ImportError:  # pragma: no cover - numba is a dependency; the interpreter runs the same code
    AVAILABLE = False

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
