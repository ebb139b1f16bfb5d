"""ldaspark: Lagrange-d'Alembert SPARK integrators for nonholonomic Lagrangian systems (L. O. Jay),
with a suite that machine-checks the paper's claims.

Layers (a module imports only from its own layer or the ones to its left):

    core  <-  theory, compiled  <-  reports  <-  cli

* ``ldaspark.core``: errors, arithmetic backend, tableaux (21) and their families, the system (1),
  the SPARK step and loop (21a-f), comparators of sections 7-8, scenes of section 8, file i/o.
* ``ldaspark.theory``: discrete Lagrangian (13), Theorem 1 residuals, well-posedness, symmetry (23),
  order conditions, the tableau audit, observed orders, the claims ledger.
* ``ldaspark.compiled``: code generation from a scene's sympy expressions, numba kernels, ensembles.
* ``ldaspark.solve``: ``integrate`` (one entry point for every engine) returning ``Result``;
  ``ldaspark.plot``: energy, constraint and trajectory plots of a Result.
* ``ldaspark.reports``: one module per section of ``ldaspark report``.

The names below are imported lazily (sympy, numba, scipy and matplotlib load on first use).
"""
from __future__ import annotations

import importlib

__version__ = "0.2.0"

_EXPORTS = {
    "LagrangianSystem": "ldaspark.core.system",
    "integrate": "ldaspark.solve",
    "Result": "ldaspark.core.result",
    "load_result": "ldaspark.core.resultio",
    "save_result": "ldaspark.core.resultio",
    "fast_integrate": "ldaspark.compiled.fast",
    "gauss": "ldaspark.core.families",
    "lobatto_iiia_iiib": "ldaspark.core.families",
    "lobatto_iiia_iiib_iiid": "ldaspark.core.families",
    "euler_i": "ldaspark.core.families",
    "euler_ii": "ldaspark.core.families",
    "SparkTableau": "ldaspark.core.tableau",
    "load_tableau": "ldaspark.core.tableau",
    "get_method": "ldaspark.core.families",
    "get_scene": "ldaspark.core.scenes",
    "discrete_lagrangian": "ldaspark.theory.discrete",
    "theorem1_residuals": "ldaspark.theory.discrete",
    "check_symmetry": "ldaspark.theory.symmetry",
    "classify_wellposedness": "ldaspark.theory.wellposedness",
    "flow_jacobian": "ldaspark.theory.flow_jacobian",
    "run_many": "ldaspark.compiled.ensemble",
    "LdasparkError": "ldaspark.core.errors",
}

__all__ = sorted(_EXPORTS) + ["__version__", "plot"]


def __getattr__(name):
    if name == "plot":   # the submodule ldaspark.plot (energy, constraint, trajectory)
        return importlib.import_module("ldaspark.plot")
    mod = _EXPORTS.get(name)
    if mod is None:
        raise AttributeError(f"module 'ldaspark' has no attribute {name!r}")
    value = getattr(importlib.import_module(mod), name)
    globals()[name] = value
    return value


def __dir__():
    return __all__
