"""Buffers kept from call to call, so hot loops write into pages already touched.

Fresh memory is dear on a VM: its first touch costs 0.5-2.4 ms per MB (measured here), and
first touches taken by a kernel's parallel workers contend for the process's memory map and cost
more again. A caller that renders chunk after chunk (or request after request, one per thread)
keeps a :class:`Scratch` and the pages stay mapped."""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np
from numpy.typing import NDArray


class Scratch:
    """Named buffers, each as large as the largest array asked of it so far. Not thread-safe:
    one per thread."""

    def __init__(self) -> None:
        self._buffers: dict[str, NDArray[np.uint8]] = {}

    def array(self, name: str, shape: tuple[int, ...], dtype: type[np.generic],
              touch: bool = True) -> NDArray[Any]:
        """A C-contiguous array of ``shape`` on the buffer ``name`` (grown when too small; its
        contents are whatever the last user left). ``touch``: a new buffer's pages are touched
        here (else where first written: for a buffer much of which may never be)."""
        size = math.prod(shape) * np.dtype(dtype).itemsize
        buffer = self._buffers.get(name)
        if buffer is None or buffer.nbytes < size:
            buffer = np.empty(size, np.uint8)
            if touch:
                buffer.fill(0)  # touched once, here, in one thread
            self._buffers[name] = buffer
        return buffer[:size].view(dtype).reshape(shape)


class Shelf:
    """Scratches lent and given back, so a later user (the next live session of a worker
    process) writes into the pages an earlier one touched: each session's own chunk buffers,
    touched anew, were 40-50 ms of a 4,000-horse session's serial part. Keeps at most ``keep``
    unused ones; thread-safe."""

    def __init__(self, keep: int = 2) -> None:
        self.keep = keep
        self._free: list[Scratch] = []
        self._lock = threading.Lock()

    def take(self) -> Scratch:
        with self._lock:
            return self._free.pop() if self._free else Scratch()

    def give(self, scratch: Scratch) -> None:
        """Back on the shelf: only once nothing uses its arrays any more."""
        with self._lock:
            if len(self._free) < self.keep and all(s is not scratch for s in self._free):
                self._free.append(scratch)
