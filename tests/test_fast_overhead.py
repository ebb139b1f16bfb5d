"""The compiled path's per-call savings keep every check: the set-up checks of (4) and of
consistency through the model's own compiled functions give the verdicts (and the reciprocal
condition) of the lambdified ones; a remembered initial point is the only one skipped; the
kernels called through their compiled entry points give the dispatchers' numbers bit for bit."""
import numpy as np
import pytest
import sympy

from ldaspark.compiled import fast
from ldaspark.core.backend import Backend
from ldaspark.core.errors import InconsistentInitialDataError, SingularSaddleError
from ldaspark.core.system import LagrangianSystem


@pytest.fixture(scope="module")
def rank_system():
    """Mechanical form; K = [[-q2, 0, 1], [-q2, q1, 1]] loses rank at q1 = 0 (4 fails there)."""
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    L = sum(x ** 2 for x in v) / 2 - (q[0] ** 2 + q[1] ** 2) / 2
    sysm = LagrangianSystem(L, [v[2] - q[1] * v[0], v[2] - q[1] * v[0] + q[0] * v[1]], q, v, name="rank-q1")
    fast.fast_integrate(sysm, "gauss-2", 0.0, [1.0, 0.5, 0.0], [0.0, 0.0, 0.0], 0.1, 2)   # loads the model
    assert fast._loaded(sysm) is not None and fast._loaded(sysm).form == "mechanical"
    return sysm


def _verdict(fn):
    try:
        return "ok", fn()
    except (SingularSaddleError, InconsistentInitialDataError) as exc:
        return type(exc).__name__, str(exc)


@pytest.mark.parametrize("q1", [1.0, 1e-6, 1e-14, 0.0])
def test_compiled_saddle_check_equals_lambdified(rank_system, q1):
    # 1 and 1e-6 pass, 1e-14 (below the 1e3 eps threshold) and 0 are rank deficient: same outcome,
    # same message, and the same reciprocal condition to round-off, from either evaluation of (4)
    bk, cs = Backend(None), fast._loaded(rank_system)
    q, v = np.array([q1, 0.5, 0.0]), np.zeros(3)
    S, k = fast._saddle_and_k(cs, 0.0, q, v)
    a = _verdict(lambda: rank_system.check_saddle(bk, 0.0, q, v, S=S))
    b = _verdict(lambda: rank_system.check_saddle(bk, 0.0, q, v))
    assert a[0] == b[0] == ("ok" if q1 >= 1e-6 else "SingularSaddleError")
    if a[0] == "ok":
        assert abs(a[1] - b[1]) <= 1e-12 * b[1]
    else:
        assert "rank deficient" in a[1] and "rank deficient" in b[1]
    assert np.max(np.abs(k - rank_system.constraint(bk, 0.0, q, v))) <= 1e-15


def test_fast_integrate_checks_every_new_point(rank_system, monkeypatch):
    with pytest.raises(SingularSaddleError, match="rank deficient"):
        fast.fast_integrate(rank_system, "gauss-2", 0.0, [0.0, 0.5, 0.0], [0.0, 0.0, 0.0], 0.1, 2)
    with pytest.raises(InconsistentInitialDataError):      # k2 = q1 v2 = 1e-9
        fast.fast_integrate(rank_system, "gauss-2", 0.0, [1.0, 0.5, 0.0], [0.0, 1e-9, 0.0], 0.1, 2)
    # the point of the fixture passed once and is remembered; any other point is checked again
    calls = []
    orig = LagrangianSystem.check_saddle
    monkeypatch.setattr(LagrangianSystem, "check_saddle", lambda self, *a, **k: calls.append(1) or orig(self, *a, **k))
    fast.fast_integrate(rank_system, "gauss-2", 0.0, [1.0, 0.5, 0.0], [0.0, 0.0, 0.0], 0.1, 2)
    assert calls == []
    fast.fast_integrate(rank_system, "gauss-2", 0.0, [1.0, 0.25, 0.0], [0.0, 0.0, 0.0], 0.1, 2)
    assert calls == [1]
    # negative control: a failed point is never remembered
    for _ in range(2):
        with pytest.raises(SingularSaddleError):
            fast.fast_integrate(rank_system, "gauss-2", 0.0, [0.0, 0.5, 0.0], [0.0, 0.0, 0.0], 0.1, 2)
    assert calls == [1, 1, 1]


def test_entry_points_give_the_dispatchers_numbers(rank_system):
    cs = fast._loaded(rank_system)
    args = (cs, "gauss-2", 0.0, [1.0, 0.5, 0.0], [0.3, 0.0, 0.15], 0.1, 20)
    via_entry = fast.run_compiled(*args)
    kernels = fast._kernels()
    saved = dict(fast._ENTRIES)
    try:
        fast._ENTRIES["spark_run"] = kernels.spark_run
        via_dispatcher = fast.run_compiled(*args)
    finally:
        fast._ENTRIES.clear()
        fast._ENTRIES.update(saved)
    assert fast._entry("spark_run") is not kernels.spark_run
    assert np.array_equal(via_entry.q, via_dispatcher.q) and np.array_equal(via_entry.v, via_dispatcher.v)
    assert np.max(np.abs(via_entry.q[-1] - np.array([1.0, 0.5, 0.0]))) > 0.01   # the run moved
