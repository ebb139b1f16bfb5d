"""The compiled float64 path: code generated from a scene's sympy expressions, numba kernels for
the SPARK step (21a-f) and the semi-implicit comparators, ensembles on any Executor.

* ``fast``: the entry points (``fast_integrate``, ``run_compiled``, ``compile_system``, ``can_compile``);
* ``codegen``: the generated model (mechanical or general form), nonzero entries only;
* ``kernels`` (entry points), ``kernels_mech``, ``kernels_general``, ``newton``: the kernels, real
  source compiled once for every system (``modeltypes``: the types that make this possible);
* ``cache``: the private, content-verified directory of the generated modules;
* ``ode``: the underlying ODE (3a-b) as a compiled right-hand side (for scipy comparisons);
* ``rescue``: the generic full-Newton step as the last link of the Newton fallback chain;
* ``roundoff``: the Kahan summation study. (Ensembles over an executor: ``ldaspark.ensemble``.)

Imports ``ldaspark.core`` and ``ldaspark.models`` only.
"""

# the quasi-Newton root finder registers its runner (``runner.KIND_RUNNERS["quasi"]``) on import:
# the default root finder runs it (``runner.auto_runs_quasi``) wherever a kernel runs
from . import quasi  # noqa: E402,F401
