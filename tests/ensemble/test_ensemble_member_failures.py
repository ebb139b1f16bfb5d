"""Ensembles keep every member: one member's failure is that member's status on every path (the
compiled kernel task through an executor, the loop), (B, n) initial data is an ensemble at mpmath
precision too, and an executor whose map hands back futures (a dask Client) gives the Results."""
from concurrent.futures import Executor, Future, ThreadPoolExecutor

import numpy as np
import pytest
import sympy as sp

import ldaspark
from ldaspark.core.errors import LdasparkError

x, y, vx, vy = sp.symbols("x y vx vy")
# U = sqrt(x): the second member walks into x < 0 (NonFiniteError at some step), the first does not
ROOT = ldaspark.LagrangianSystem((vx**2 + vy**2) / 2 - sp.sqrt(x), [vy - x * vx], [x, y], [vx, vy], name="root")
Q, V = [[1.0, 0.0], [0.3, 0.0]], [[0.1, 0.1], [-1.0, -0.3]]


def _run(**kw):
    return ldaspark.integrate(ROOT, "gauss-2", t_span=(0, 2), h=0.1, q0=Q, v0=V, guard=False, **kw)


def test_a_failing_member_keeps_the_others_through_an_executor():
    """Through an executor the compiled kernel task raised UnitsFailed for the whole ensemble (the
    loop, the control, returned statuses [0, -3]); now both paths give the same members."""
    loop = _run()
    with ThreadPoolExecutor(2) as ex:
        pooled = _run(executor=ex)
    # the member's domain error inside Newton (sqrt(x) at an iterate with x < 0) is the same
    # NonFiniteStepError, status -3, as the member's single run on the generic engine
    alone = ldaspark.integrate(ROOT, "gauss-2", t_span=(0, 2), h=0.1, q0=Q[1], v0=V[1], guard=False, engine="generic")
    assert list(loop.status) == list(pooled.status) == [0, alone.status] == [0, -3]
    for r in range(2):
        np.testing.assert_array_equal(np.asarray(loop.q[r], float), np.asarray(pooled.q[r], float))


def test_initial_data_rows_are_an_ensemble_at_mpmath_precision():
    """q0 of shape (B, n) with dps ran the last row alone (a plain Result starting at row 2); now
    B members, each its single run at that precision (control: the rows differ)."""
    q0, v0 = [[0, 0, 0.0], [0.1, 0, 0]], [[0, 0, 1.0], [0, 0, 1.0]]
    ens = ldaspark.integrate("skate", "gauss-2", t_span=(0, 0.3), h=0.1, q0=q0, v0=v0, dps=30)
    assert np.shape(ens.q)[:2] == (2, 4)
    for r in range(2):
        one = ldaspark.integrate("skate", "gauss-2", t_span=(0, 0.3), h=0.1, q0=q0[r], v0=v0[r], dps=30)
        assert all(a == b for a, b in zip(ens.q[r][-1], one.q[-1]))
    assert ens.q[0][0][0] != ens.q[1][0][0]


class _FutureMap(Executor):
    """map returns futures (as dask.distributed.Client.map does), not results."""

    def __init__(self, wrap=True):
        self.wrap = wrap

    def submit(self, fn, *args, **kw):
        f = Future()
        try:
            f.set_result(fn(*args, **kw) if self.wrap else object())
        except Exception as exc:    # a future holds its task's error, as a real executor's does
            f.set_exception(exc)
        return f

    def map(self, fn, *iterables, **kw):
        out = [self.submit(fn, *a) for a in zip(*iterables)]
        return out if self.wrap else [object() for _ in out]


def test_an_executor_whose_map_returns_futures_gives_the_results():
    """With the guard on (the loop of single runs through executor.map), a Client's futures were
    refused as "not Results"; now they are waited for (since probe t16 each member goes through the
    checked ``submit``, as run_many's units, not ``map``). Control: futures that resolve to objects
    that are not Results are still one LdasparkError."""
    res = ldaspark.integrate(ROOT, "gauss-2", t_span=(0, 2), h=0.1, q0=Q, v0=V, executor=_FutureMap())
    assert list(res.status) == [0, -3]           # the generic engine's status of that member (NonFiniteStepError)
    with pytest.raises(LdasparkError, match="not Results"):
        ldaspark.integrate(ROOT, "gauss-2", t_span=(0, 2), h=0.1, q0=Q, v0=V, executor=_FutureMap(wrap=False))
