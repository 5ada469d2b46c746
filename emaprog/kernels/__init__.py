"""Numba kernels: floats, arrays and NamedTuples only; no I/O, no RNG, no globals."""
