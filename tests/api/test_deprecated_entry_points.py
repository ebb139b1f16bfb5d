"""``fast_integrate``, ``run_compiled`` and ``ensemble_integrate`` are deprecated wrappers: each
warns once per call with a DeprecationWarning and returns the numbers of the driver's compiled
engine (``ldaspark.integrate(..., engine="compiled")``)."""
import numpy as np
import pytest

import ldaspark
from ldaspark.compiled.fast import compile_system, run_compiled
from ldaspark.ensemble import ensemble_integrate

SK = ldaspark.get_scene("skate")
RUN = dict(h=0.1, n_steps=20)


def reference():
    return ldaspark.integrate("skate", "gauss-2", engine="compiled", **RUN)


def test_fast_integrate_warns_and_agrees():
    ref = reference()
    with pytest.warns(DeprecationWarning, match="fast_integrate is deprecated"):
        sol = ldaspark.fast_integrate(SK, "gauss-2", **RUN)
    assert np.array_equal(sol.q, ref.q) and np.array_equal(sol.v, ref.v)
    assert sol.stats["newton_iterations"] == ref.newton_iterations


def test_run_compiled_warns_and_agrees():
    ref = reference()
    t0, q0, v0 = SK.initial()
    with pytest.warns(DeprecationWarning, match="run_compiled is deprecated"):
        sol = run_compiled(compile_system(SK.system), "gauss-2", t0, q0, v0, 0.1, 20)
    assert np.array_equal(sol.q, ref.q)


def test_ensemble_integrate_warns_and_agrees():
    ref = reference()
    t0, q0, v0 = SK.initial()
    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(1) as ex, pytest.warns(DeprecationWarning, match="ensemble_integrate is deprecated"):
        ens = ensemble_integrate(SK.system, "gauss-2", t0, [q0, q0], [v0, v0], 0.1, 20, executor=ex)
    assert np.array_equal(ens.q[1], ref.q)


def test_the_driver_does_not_warn(recwarn):
    reference()
    assert not [w for w in recwarn if issubclass(w.category, DeprecationWarning)
                and "deprecated" in str(w.message) and "ldaspark" in str(w.filename)]
