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
