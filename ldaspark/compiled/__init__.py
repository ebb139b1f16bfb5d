"""The compiled float64 path: code generated from a scene's sympy expressions, numba kernels for
the SPARK step (21a-f) and the semi-implicit comparators, ensembles on any Executor.

Imports ``ldaspark.core`` only.
"""
