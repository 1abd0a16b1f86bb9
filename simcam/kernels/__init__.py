"""Numba kernels shared by the instruments: array-in, array-out numerical cores, free of orchestration."""
