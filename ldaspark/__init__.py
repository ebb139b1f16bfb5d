"""ldaspark: Lagrange-d'Alembert SPARK integrators for nonholonomic Lagrangian systems (L. O. Jay),
with a suite that machine-checks the paper's claims.

Layers (a module imports only from its own room or from the layers to its left; rooms in one
layer do not import each other; ``tests/project/test_layers.py`` checks this on every import statement):

    core  <  models  <  compiled  <  executors  <  ensemble  <  engines  <  solve, plot  <  analysis  <  cli  <  lab

(the paper lab ``ldaspark.lab`` sits above the library and is not imported by it)

* ``ldaspark.core``: errors, arithmetic backend, tableaux (21) and their families, the system (1)
  and its adapter from sympy.physics.mechanics, the SPARK step and loop (21a-f), comparators of
  sections 7-8, dense output and events, the integration options, results and their files.
* ``ldaspark.models``: the scenes of section 8 and more, the classic nonholonomic systems, the
  Whipple bicycle and its linearised benchmark.
* ``ldaspark.compiled``: code generation from a scene's sympy expressions, numba kernels.
* ``ldaspark.executors``: where work runs (local pool, Dask, any Executor); ``ldaspark.ensemble``:
  many initial data or parameters of one system over an executor.
* ``ldaspark.engines``: the engine protocol (``Engine``: prepare, steps or blocks of steps,
  counters, the guard's safe root) and the generic, compiled and comparator engines.
* ``ldaspark.solve``: ``integrate`` (one entry point, the one driver of every engine) returning ``Result``;
  ``ldaspark.plot``: energy, constraint and trajectory plots of a Result.
* ``ldaspark.analysis``: discrete Lagrangian (13), Theorem 1 residuals, well-posedness, symmetry (23),
  the exact conditions (22)/(23), order conditions, the step map's Jacobian.
* ``ldaspark.cli``: the command line (``integrate``, ``methods``; other packages add commands
  through the entry-point group ``ldaspark.commands``).
* ``ldaspark.lab`` (the paper lab, above the library): the theory behind the claims and the tableau
  audit (``lab.theory``), the claims ledger (``lab.claims``, ``ldaspark verify``), the mutation
  tools (``lab.mutants``), one module per section of ``ldaspark report`` (``lab.reports``).

The names below are imported lazily (sympy, numba, scipy and matplotlib load on first use).
Modules that moved to another room keep their old dotted names (``MOVED``, docs/changelog.md):
``import ldaspark.core.scenes`` gives the module object ``ldaspark.models.scenes``.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys

from ._version import __version__

#: old dotted name -> new one, for the modules that moved to another room (a package maps its
#: submodules too: ``ldaspark.reports.catalogue.systems`` -> ``ldaspark.lab.mutants.catalogue.systems``)
MOVED = {
    "ldaspark.core.scenes": "ldaspark.models.scenes",
    "ldaspark.core.systems_classic": "ldaspark.models.systems_classic",
    "ldaspark.core.bicycle": "ldaspark.models.bicycle",
    "ldaspark.theory.bicycle_benchmark": "ldaspark.models.bicycle_benchmark",
    "ldaspark.core.workers": "ldaspark.executors",
    "ldaspark.compiled.ensemble": "ldaspark.ensemble",
    "ldaspark.theory.ledger": "ldaspark.lab.claims.ledger",
    "ldaspark.theory.claims_general": "ldaspark.lab.claims.claims_general",
    "ldaspark.theory.claims_paper": "ldaspark.lab.claims.claims_paper",
    "ldaspark.theory.claims_index": "ldaspark.lab.claims.claims_index",
    "ldaspark.reports.mutation": "ldaspark.lab.mutants.mutation",
    "ldaspark.reports.mutation_catalogue": "ldaspark.lab.mutants.mutation_catalogue",
    "ldaspark.reports.catalogue": "ldaspark.lab.mutants.catalogue",
    # round 5: the paper lab apart from the library (docs/changelog.md)
    "ldaspark.dist": None,            # an emptied package: only its modules moved
    "ldaspark.dist.workers": "ldaspark.executors",
    "ldaspark.dist.ensemble": "ldaspark.ensemble",
    "ldaspark.theory.flow_jacobian": "ldaspark.analysis.flow_jacobian",
    "ldaspark.theory.discrete": "ldaspark.analysis.discrete",
    "ldaspark.theory.memo": "ldaspark.analysis.memo",
    "ldaspark.theory.symmetry": "ldaspark.analysis.symmetry",
    "ldaspark.theory.wellposedness": "ldaspark.analysis.wellposedness",
    "ldaspark.theory.order_conditions": "ldaspark.analysis.order_conditions",
    "ldaspark.theory.conditions": "ldaspark.analysis.conditions",
    "ldaspark.theory": "ldaspark.lab.theory",
    "ldaspark.claims": "ldaspark.lab.claims",
    "ldaspark.reports": "ldaspark.lab.reports",
    "ldaspark.mutants": "ldaspark.lab.mutants",
}


def _moved_to(fullname: str):
    """The new dotted name of a moved module (or of a submodule of a moved package), else None."""
    if fullname in MOVED:
        return MOVED[fullname] or ""
    head, dot, tail = fullname.rpartition(".")
    while dot:
        if MOVED.get(head):
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
        if new is None:                   # "" (an emptied package) is found here too
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        return None                          # a placeholder; exec_module puts the real module in its place

    def exec_module(self, module):
        new = _moved_to(module.__name__)
        if not new:                       # an emptied package (MOVED value None): a namespace for its old modules
            module.__path__ = []
            return
        # importlib returns sys.modules[name] after exec_module: the moved module itself
        moved = sys.modules[module.__name__] = importlib.import_module(new)
        if hasattr(moved, "__path__"):
            _old_children(moved, module.__name__)


def _old_children(package, old: str) -> None:
    """``from <old package> import <child>`` where the child moved elsewhere (``from
    ldaspark.theory import discrete``): the old package is the new package's object, whose
    ``__name__`` is the new one, so Python's from-import looks for the child there and fails. A
    module ``__getattr__`` on the package imports such a child by its old dotted name (through this
    finder: the moved module itself). Nothing else is looked up this way; the package's own
    submodules import as usual."""
    children = getattr(package, "_ldaspark_old_children", None)
    if children is None:
        if "__getattr__" in vars(package):          # a package with its own lookup is left alone
            return
        children = package._ldaspark_old_children = {}

        def __getattr__(name):
            old_name = children.get(name)
            if old_name is None:
                raise AttributeError(f"module {package.__name__!r} has no attribute {name!r}")
            return importlib.import_module(old_name)
        package.__getattr__ = __getattr__
    for key in MOVED:
        head, _, name = key.rpartition(".")
        if head == old and MOVED[key] and MOVED[key] != f"{package.__name__}.{name}":
            children[name] = key


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
    "load_tableau": "ldaspark.core.tableau_file",
    "get_method": "ldaspark.core.families",
    "get_scene": "ldaspark.models.scenes",
    "discrete_lagrangian": "ldaspark.analysis.discrete",
    "theorem1_residuals": "ldaspark.analysis.discrete",
    "check_symmetry": "ldaspark.analysis.symmetry",
    "classify_wellposedness": "ldaspark.analysis.wellposedness",
    "flow_jacobian": "ldaspark.analysis.flow_jacobian",
    "run_many": "ldaspark.ensemble",
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
