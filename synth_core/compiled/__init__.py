"""The compiled (numba) kernels behind the run time, their thread pool and reused buffers."""
