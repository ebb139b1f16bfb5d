"""The step-acceptance guard (``ldaspark.core.guard``) at its edges: the threshold is strict on
both the step-by-step test (``StepGuard.suspect``) and the vectorised one (``flagged``), at an
energy change equal to it in float64 (found by search, then one ulp above); the safe start
extrapolated from the previous step's collocation polynomial is exact for a velocity linear in
time, for nodes that include the end point (Lobatto: c = 0, 1, which must not be entered twice)
and nodes that do not (Gauss)."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from ldaspark.core import guard
from ldaspark.core.families import get_method


def _boundary():
    """(p, E1): with the previous energy change p and E0 = 0, E1 - E0 equals the threshold
    SAFETY p + round(E0, E1) exactly in float64."""
    for k in range(10, 40):
        E1 = 2.0 ** -k
        base = (E1 - guard._round(0.0, E1)) / guard.SAFETY
        for u in range(-8, 9):
            p = base + u * math.ulp(base)
            if p > 0 and guard.SAFETY * p + guard._round(0.0, E1) == E1:
                return p, E1
    raise AssertionError("no exact boundary found")


def test_a_change_equal_to_the_threshold_is_not_flagged_one_ulp_more_is():
    p, E1 = _boundary()
    above = float(np.nextafter(E1, 1.0))
    g = guard.StepGuard()
    g.accept(-p, 0.0)
    assert not g.suspect(1, 0.0, E1) and g.suspect(1, 0.0, above)
    assert list(guard.flagged([-p, 0.0, E1])) == [] and list(guard.flagged([-p, 0.0, above])) == [1]


def _start(name, h=0.1):
    tab = get_method(name).arrays(None)           # what SparkMethod.tab holds in float64
    c = np.asarray([float(x) for x in tab.c])
    a, b = np.array([0.3, -1.2]), np.array([2.0, 0.5])        # v(tau) = a + b tau, tau in units of h
    V = a + np.outer(c, b)
    Psi = np.array([[0.25]] * len(c))
    meth = SimpleNamespace(tab=tab, pack=lambda V, Lam, v1: np.concatenate([np.ravel(V), np.ravel(Lam), v1]))
    x = guard._extrapolated_start(meth, (V, Psi, h), a + b)
    s = len(c)
    return x, a + np.outer(1 + c, b), a + 2 * b, Psi * h, s


def test_the_extrapolated_start_is_exact_for_a_linear_velocity():
    for name in ("lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3", "gauss-1", "gauss-2"):   # >= 2 distinct nodes
        x, V_want, v_want, lam_want, s = _start(name)
        assert np.isfinite(x).all(), name
        n = V_want.shape[1]
        assert np.allclose(x[:s * n].reshape(s, n), V_want, rtol=0, atol=1e-12), name
        assert np.allclose(x[s * n:s * n + s], lam_want.ravel(), rtol=0, atol=1e-15), name
        assert np.allclose(x[-n:], v_want, rtol=0, atol=1e-12), name


def test_same_root_at_root_agree_relative_to_the_safe_root():
    # ROOT_AGREE (1e-8) relative to 1 + max(|q1'|, |v1'|): both roots are converged to ~1e-15, so a
    # difference of 0.9 ROOT_AGREE (1 + 4) is one root and 1.1 ROOT_AGREE (1 + 4) or a 1e-6 one are two
    import numpy as np
    from ldaspark.core import guard
    q, v = np.array([4.0, -1.0]), np.array([0.5, 2.0])
    tol = guard.ROOT_AGREE * (1 + 4.0)
    assert guard.same_root(q + [0.9 * tol, 0], v, q, v)
    assert guard.same_root(q, v - [0, 0.9 * tol], q, v)
    assert not guard.same_root(q + [1.1 * tol, 0], v, q, v)
    assert not guard.same_root(q, v + [0, 1e-6], q, v)
    assert not guard.same_root(q + [np.nan, 0], v, q, v)


def test_the_vectorised_test_flags_what_the_step_by_step_test_flags():
    """``flagged`` (block engines, vectorised) and ``StepGuard.suspect`` (stepping engines) are one
    threshold: on random energy sequences, quiet and with jumps of every size (so both outcomes
    occur), they flag the same steps."""
    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(400):
        N = int(rng.integers(0, 60))
        E = 1.0 + rng.standard_normal(N) * 10.0 ** rng.uniform(-17, -4)
        if N and rng.random() < 0.6:
            E[rng.integers(0, N)] += 10.0 ** rng.uniform(-15, 0)
        sg, ref = guard.StepGuard(), []
        for n in range(N - 1):
            if sg.suspect(n, E[n], E[n + 1]):
                ref.append(n)
            sg.accept(E[n], E[n + 1])
        got = guard.flagged(E)
        assert got.dtype.kind == "i" and list(got) == ref
        seen.add(bool(ref))
    assert seen == {True, False}


def test_the_iteration_test_is_against_the_window_s_largest_count():
    # the generic engine flags a step whose Newton took more than ITER_FACTOR times the largest
    # count of the previous WINDOW steps plus ITER_EXTRA: after counts 2, 10, 2, 2 (largest 10)
    # a step of 22 iterations stands and one of 23 is flagged (the energy does not change)
    g = guard.StepGuard()
    for its in (2, 10, 2, 2):
        g.accept(1.0, 1.0, its)
    limit = guard.ITER_FACTOR * 10 + guard.ITER_EXTRA
    assert not g.suspect(4, 1.0, 1.0, limit) and g.suspect(4, 1.0, 1.0, limit + 1)
