"""Which code runs: the one place a backend name becomes the compiled kernels or the reference.

``"numba"``: the compiled kernels; ``"numpy"``: the references -- the kernels' own source run by the
interpreter, the planner's (:data:`synth_core.compiled.plan_kernels.REFERENCE`) and the render's
(:data:`synth_core.compiled.kernels.REFERENCE`, whose wrappers take ``compiled=``:func:`compiled`
``(name)``: importing them here would close an import circle through the runtime); ``"auto"``:
numba where it is installed.
"""

from __future__ import annotations

from synth_core.compiled.jit import AVAILABLE
from synth_core.compiled.plan_kernels import COMPILED, REFERENCE, Kernels

BACKENDS = ("auto", "numba", "numpy")


def compiled(name: str) -> bool:
    """Whether backend ``name`` runs the compiled kernels."""
    if name not in BACKENDS:
        raise ValueError(f"backend: must be one of {BACKENDS}, got {name!r}")
    return name == "numba" or (name == "auto" and AVAILABLE)


def planner(name: str) -> Kernels:
    """The planner's kernels of backend ``name``."""
    return COMPILED if compiled(name) else REFERENCE
