"""Numba kernels: array-in, array-out numerical cores, free of orchestration."""
