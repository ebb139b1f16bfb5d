"""A member of an ensemble keeps the promises of its single run (probe t16): the same warnings on
every executor, the same stats keys, the same refusals."""
import concurrent.futures as cf
import multiprocessing
import warnings

import numpy as np
import pytest
import sympy as sp

import ldaspark
from ldaspark.core.errors import LdasparkWarning


def _singular_mass():
    # M = [[1, 1], [1, 1]] (rank 1), K = [1, -1] covers its null vector: (4) regular, (5) fails
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = (vx + vy) ** 2 / 2 - (x ** 2 + 2 * y ** 2) / 2
    return ldaspark.LagrangianSystem(L, [vx - vy], [x, y], [vx, vy], name="singular-M")


def _regular():
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = (vx ** 2 + vy ** 2) / 2 - (x ** 2 + 2 * y ** 2) / 2
    return ldaspark.LagrangianSystem(L, [vx - vy], [x, y], [vx, vy], name="regular-M")


def _said(call):
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        res = call()
    return res, [(w.category, str(w.message)) for w in rec if issubclass(w.category, LdasparkWarning)]


def test_a_process_pool_says_the_warnings_of_the_run_in_this_process():
    """A member (or a single run) on a process pool warned in the worker, where the caller never
    saw it: project=True's change of v0 and the singular L_vv of (5) were 0 warnings through a
    ProcessPoolExecutor against 3 (one projection, one (5) per member) without an executor. Now
    the tasks hand their warnings back and they are said here, in member order, the same list.
    Control: a regular L with consistent v0 says nothing on either path."""
    kw = dict(q0=[[1.0, 0.5], [0.9, 0.4]], v0=[[0.3, 0.2], [0.2, 0.2]], h=0.05, n_steps=2, project=True,
              engine="generic")
    with cf.ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("fork")) as ex:
        for system, expect in ((_singular_mass(), 3), (_regular(), 0)):
            kw_sys = dict(kw, v0=[[0.3, 0.3], [0.2, 0.2]]) if expect == 0 else kw
            here, said_here = _said(lambda: ldaspark.integrate(system, "gauss-2", **kw_sys))
            there, said_there = _said(lambda: ldaspark.integrate(system, "gauss-2", executor=ex, **kw_sys))
            assert len(said_here) == expect and said_there == said_here
            assert np.array_equal(there.q, here.q)
            one = dict(kw_sys, q0=kw_sys["q0"][0], v0=kw_sys["v0"][0])
            assert _said(lambda: ldaspark.integrate(system, "gauss-2", executor=ex, **one))[1] == \
                _said(lambda: ldaspark.integrate(system, "gauss-2", **one))[1]


def test_member_0_failing_its_first_kernel_step_is_reported_as_any_member():
    """run_many warmed the kernels on member 0's first step in this process and let its failure
    escape: a bare NewtonError naming no member (member 1 failing is UnitsFailed), and
    integrate(q0=(B, n), executor=..., guard=False) raised it where the same call without an
    executor returns status 0 for both members (2 steps rescued by the generic step each, singular
    L_vv of (5), gauss-2). Now it is UnitsFailed naming the unit, and integrate falls back to the
    loop of single runs: the same numbers bit for bit. Control: a regular L runs on the kernels."""
    from ldaspark.ensemble import RunSpec, run_many
    from ldaspark.executors import UnitsFailed
    Q, V = [[1.0, 0.5], [0.9, 0.4]], [[0.3, 0.3], [0.2, 0.2]]
    kw = dict(q0=Q, v0=V, h=0.05, n_steps=2, guard=False)
    S = _singular_mass()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LdasparkWarning)
        loop = ldaspark.integrate(S, "gauss-2", **kw)
        with cf.ThreadPoolExecutor(2) as ex:
            with pytest.raises(UnitsFailed, match=r"^2 work unit\(s\) failed \(0 finished\): 0: NewtonError"):
                run_many([RunSpec(S, "gauss-2", 0.0, Q, V, 0.05, 2)], where=ex)
            there = ldaspark.integrate(S, "gauss-2", executor=ex, **kw)
            ok = run_many([RunSpec(_regular(), "gauss-2", 0.0, Q, V, 0.05, 2)], where=ex)[0]
    assert list(loop.status) == [0, 0] and [m.stats["rescued_steps"] for m in loop.members] == [2, 2]
    assert list(there.status) == [0, 0] and np.array_equal(there.q, loop.q) and np.array_equal(there.v, loop.v)
    assert ok.q.shape == (2, 3, 2)
