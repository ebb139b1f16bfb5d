"""ldaspark: Lagrange-d'Alembert SPARK integrators for nonholonomic Lagrangian systems (L. O. Jay),
with a suite that machine-checks the paper's claims.

Layers (a module imports only from its own room or from the layers to its left; rooms in one
layer do not import each other; ``tests/test_layers.py`` checks this on every import statement):

    core  <  models  <  compiled  <  dist  <  solve, plot  <  theory  <  claims, mutants  <  reports  <  cli

* ``ldaspark.core``: errors, arithmetic backend, tableaux (21) and their families, the system (1)
  and its adapter from sympy.physics.mechanics, the SPARK step and loop (21a-f), comparators of
  sections 7-8, dense output and events, the integration options, results and their files.
* ``ldaspark.models``: the scenes of section 8 and more, the classic nonholonomic systems, the
  Whipple bicycle and its linearised benchmark.
* ``ldaspark.compiled``: code generation from a scene's sympy expressions, numba kernels.
* ``ldaspark.dist``: where work runs (local pool, Dask, any Executor) and ensembles.
* ``ldaspark.solve``: ``integrate`` (one entry point for every engine) returning ``Result``;
  ``ldaspark.plot``: energy, constraint and trajectory plots of a Result.
* ``ldaspark.theory``: discrete Lagrangian (13), Theorem 1 residuals, well-posedness, symmetry (23),
  order conditions, the tableau audit, observed orders, the step map's Jacobian.
* ``ldaspark.claims``: the claims ledger (``ldaspark verify``); ``ldaspark.mutants``: the
  mutation catalogue (``ldaspark mutants``).
* ``ldaspark.reports``: one module per section of ``ldaspark report``; ``ldaspark.cli``: the command line.

The names below are imported lazily (sympy, numba, scipy and matplotlib load on first use).
Modules that moved to another room keep their old dotted names (``MOVED``, docs/changelog.md):
``import ldaspark.core.scenes`` gives the module object ``ldaspark.models.scenes``.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys

__version__ = "0.2.0"

#: old dotted name -> new one, for the modules that moved to another room (a package maps its
#: submodules too: ``ldaspark.reports.catalogue.systems`` -> ``ldaspark.mutants.catalogue.systems``)
MOVED = {
    "ldaspark.core.scenes": "ldaspark.models.scenes",
    "ldaspark.core.systems_classic": "ldaspark.models.systems_classic",
    "ldaspark.core.bicycle": "ldaspark.models.bicycle",
    "ldaspark.theory.bicycle_benchmark": "ldaspark.models.bicycle_benchmark",
    "ldaspark.core.workers": "ldaspark.dist.workers",
    "ldaspark.compiled.ensemble": "ldaspark.dist.ensemble",
    "ldaspark.theory.ledger": "ldaspark.claims.ledger",
    "ldaspark.theory.claims_general": "ldaspark.claims.claims_general",
    "ldaspark.theory.claims_paper": "ldaspark.claims.claims_paper",
    "ldaspark.theory.claims_index": "ldaspark.claims.claims_index",
    "ldaspark.reports.mutation": "ldaspark.mutants.mutation",
    "ldaspark.reports.mutation_catalogue": "ldaspark.mutants.mutation_catalogue",
    "ldaspark.reports.catalogue": "ldaspark.mutants.catalogue",
}


def _moved_to(fullname: str):
    """The new dotted name of a moved module (or of a submodule of a moved package), else None."""
    if fullname in MOVED:
        return MOVED[fullname]
    head, dot, tail = fullname.rpartition(".")
    while dot:
        if head in MOVED:
            return f"{MOVED[head]}.{fullname[len(head) + 1:]}"
        head, dot, tail = head.rpartition(".")
    return None


class _MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Import an old dotted name as the moved module itself (the same object under both names, so
    module state, monkeypatching and isinstance checks are shared), not as a copy of its file.
    First on ``sys.meta_path``: a submodule of a moved package must not be found again by the
    path finder (it would load the file a second time under the old name)."""

    def find_spec(self, fullname, path=None, target=None):
        new = _moved_to(fullname) if fullname.startswith("ldaspark.") else None
        if new is None:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        return None                          # a placeholder; exec_module puts the real module in its place

    def exec_module(self, module):
        # importlib returns sys.modules[name] after exec_module: the moved module itself
        sys.modules[module.__name__] = importlib.import_module(_moved_to(module.__name__))


if not any(isinstance(f, _MovedModules) for f in sys.meta_path):
    sys.meta_path.insert(0, _MovedModules())

_EXPORTS = {
    "LagrangianSystem": "ldaspark.core.system",
    "integrate": "ldaspark.solve",
    "Newton": "ldaspark.core.rootfinder",
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
    "get_scene": "ldaspark.models.scenes",
    "discrete_lagrangian": "ldaspark.theory.discrete",
    "theorem1_residuals": "ldaspark.theory.discrete",
    "check_symmetry": "ldaspark.theory.symmetry",
    "classify_wellposedness": "ldaspark.theory.wellposedness",
    "flow_jacobian": "ldaspark.theory.flow_jacobian",
    "run_many": "ldaspark.dist.ensemble",
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
