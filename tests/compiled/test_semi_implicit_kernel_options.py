"""The semi-implicit kernel of (25) (``kernels.lf2_run``; lobatto-iiia-iiib-2 on a mechanical
system, and the comparators of Fig. 4) solves an m x m system for the multipliers and factors
it in every step: it has no block LU and no matrix reuse. A run that asks for them through
``fast_integrate`` / ``run_compiled`` is refused in one line naming the engine and the field
(``rootfinder.SUPPORT["compiled-lf2"]``), never run on the dense path with the option dropped.
Through ``integrate`` the same request leaves the semi-implicit kernel for the SPARK kernel of
the same method (21), which honours it."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import ldaspark
from ldaspark.compiled.runner import compile_system, run_kernels
from ldaspark.core.errors import InputError

SKATE = ldaspark.get_scene("skate")          # mechanical form (the kernels' section 7)


def _fast(method, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return ldaspark.fast_integrate(SKATE, method, h=0.1, n_steps=5, **kw)


@pytest.mark.parametrize("method", ["lobatto-iiia-iiib-2", "lobatto-iiia-iiib-2-leapfrog"])
def test_fast_integrate_refuses_the_block_lu_on_the_semi_implicit_kernel(method):
    with pytest.raises(InputError, match="engine 'compiled-lf2' refuses Newton linear_solver='sparse'"):
        _fast(method, linear_solver="sparse")
    # control: the values that kernel honours run it
    for ls in ("auto", "dense"):
        r = _fast(method, linear_solver=ls)
        assert r.stats["kernel"] == "lf2" and r.stats["linear_solver"] == "dense"


def test_run_kernels_refuses_matrix_reuse_on_the_semi_implicit_kernel():
    cs = compile_system(SKATE.system)
    t0, q0, v0 = SKATE.initial()
    with pytest.raises(InputError, match="engine 'compiled-lf2' refuses Newton reuse=True"):
        run_kernels(cs, "lobatto-iiia-iiib-2", t0, q0, v0, 0.1, 5, reuse_matrix=True)
    off = run_kernels(cs, "lobatto-iiia-iiib-2", t0, q0, v0, 0.1, 5, reuse_matrix=False)
    assert off.stats["kernel"] == "lf2"
    # the SPARK kernel of the same method honours both
    on = run_kernels(cs, "lobatto-iiia-iiib-2", t0, q0, v0, 0.1, 5, kernel="spark", reuse_matrix=True,
                     linear_solver="sparse")
    assert on.stats["reuse_matrix"] is True and on.stats["linear_solver"] == "sparse"


def test_integrate_runs_the_block_lu_on_the_spark_kernel_of_the_same_method():
    """The block LU asked for lobatto-iiia-iiib-2 through ``integrate``: the SPARK kernel with
    the sparse solver, the same numbers as the semi-implicit kernel (two solvers of (21) stopped
    by the Newton rule 10 eps (|x| + |v|): 1e-12 over 5 steps of a state of size ~1)."""
    kw = dict(t_span=(0.0, 0.5), h=0.1, engine="compiled")
    lf2 = ldaspark.integrate("skate", "lobatto-iiia-iiib-2", **kw)
    sp = ldaspark.integrate("skate", "lobatto-iiia-iiib-2", newton=ldaspark.Newton(linear_solver="sparse"), **kw)
    assert lf2.stats["kernel"] == "lf2" and sp.stats["kernel"] == "spark"
    assert sp.stats["linear_solver"] == "sparse"
    assert np.max(np.abs(np.asarray(sp.q) - np.asarray(lf2.q))) < 1e-12
