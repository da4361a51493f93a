"""How a synthesis worker process asks for memory: freed memory kept for the next request, and
no transparent huge pages for numpy's arrays.

Synthesis makes and drops arrays of megabytes to tens of megabytes many times a second (a live
tick of 4,000 horses: its plan's columns, windows, chunks). By default glibc hands large freed
blocks back to the OS (munmap, heap trim), so the next tick faults the same amount in again,
zeroed; and numpy asks for transparent huge pages on every array of 4 MB or more (madvise),
which on a kernel with THP ``defrag=madvise`` (this machine's) may reclaim and compact memory
in the faulting thread. Four 4,000-horse live sessions in a row in-process here (two shards): 0.1-0.7 s of
each one's 1.8-2.3 s wall in the kernel, varying session to session; with both set, 0.2 s in
the first, then down to 0.03 (the memory reused), wall 1.7-1.9 s (see the commit that brought
this module).

The cost: a process keeps up to ``TRIM_THRESHOLD`` of freed memory at its heap's top (and each
worker thread's arena up to its size) instead of returning it -- its resident size stays near
its high-water mark. ``QUADSYNTH_MEMORY_TUNING=0`` leaves both as they are.
"""

from __future__ import annotations

import ctypes
import platform

import numpy as np

# mallopt(3) parameters (glibc's malloc.h).
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
# Blocks up to this size come from the heap and are reused there; glibc takes at most 32 MiB
# on 64-bit (most of a live tick's arrays are below it). Setting it also
# stops glibc's own threshold from moving.
MMAP_THRESHOLD = 32 << 20
TRIM_THRESHOLD = 256 << 20  # freed memory at the heap's top kept up to this
TOP_PAD = 64 << 20  # the heap grows by this much more than asked: fewer, larger growths


class _Mallinfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
        "keepcost")]


def _libc() -> ctypes.CDLL | None:
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return None
    try:
        return ctypes.CDLL("libc.so.6")
    except OSError:
        return None


def kept() -> int | None:
    """Bytes freed and kept by malloc for reuse, over all its arenas (None: not glibc >= 2.33)."""
    libc = _libc()
    if libc is None or not hasattr(libc, "mallinfo2"):
        return None
    libc.mallinfo2.restype = _Mallinfo2
    return int(libc.mallinfo2().fordblks)


def give_back() -> None:
    """Return the memory malloc keeps to the OS (every arena): the answers' memory budget
    (service.budget) bounds what is kept for reuse too -- the worker calls this when an answer
    ends and what is kept passes the budget's free part."""
    libc = _libc()
    if libc is not None:
        libc.malloc_trim(0)


def tune() -> dict[str, bool]:
    """Set this process's allocation behaviour (see the module's doc); which of the two took."""
    return {"numpy_hugepages_off": _numpy_hugepages_off(), "glibc_malloc": _glibc_malloc()}


def _numpy_hugepages_off() -> bool:
    # NUMPY_MADVISE_HUGEPAGE=0 does this, but is read at numpy's import only: this is the
    # function numpy's import calls with it.
    setter = getattr(getattr(getattr(np, "_core", None), "multiarray", None), "_set_madvise_hugepage", None)
    if setter is None:
        return False
    setter(False)
    return True


def _glibc_malloc() -> bool:
    libc = _libc()
    if libc is None:
        return False  # musl and others: their allocators have no such knobs
    return all(libc.mallopt(param, value) == 1 for param, value in (
        (_M_MMAP_THRESHOLD, MMAP_THRESHOLD), (_M_TRIM_THRESHOLD, TRIM_THRESHOLD), (_M_TOP_PAD, TOP_PAD)))
