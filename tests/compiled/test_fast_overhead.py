"""The compiled path's per-call savings keep every check: the set-up checks of (4) and of
consistency through the model's own compiled functions give the verdicts (and the reciprocal
condition) of the lambdified ones; a remembered initial point is the only one skipped; the
kernels called through their compiled entry points give the dispatchers' numbers bit for bit."""
import numpy as np
import pytest
import sympy

from ldaspark.compiled import fast, runner
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


# --- ldaspark.integrate's repeated call: the tableau of a name and validated options are
# remembered per process (solve._METHODS, fast._OPTIONS_OK); nothing else changes
def test_repeated_call_reuses_the_tableau_and_gives_the_same_numbers(monkeypatch):
    import ldaspark
    from ldaspark import solve
    from ldaspark.core.families import gauss
    made = []
    orig = fast._make_spec
    monkeypatch.setattr(runner, "_make_spec", lambda *a: made.append(a[0]) or orig(*a))
    solve._METHODS.clear()
    fast._SPECS.clear()
    run = lambda m: ldaspark.integrate("skate", m, t_span=(0, 0.5), h=0.05)       # noqa: E731
    a, b = run("gauss-2"), run("gauss-2")
    assert len(made) == 1 and solve.resolve_method("gauss-2")[1] is solve.resolve_method("gauss-2")[1]
    assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v) and a.status == b.status == 0
    # control: a tableau object given by the caller is its own (a new object: a new spec), and
    # the same numbers as the remembered one of the same name
    c = run(gauss(2))
    assert len(made) == 2 and np.array_equal(c.q, a.q)
    # a comparator name is never taken for a SPARK name
    assert solve.resolve_method("lobatto-iiia-iiib-2-leapfrog")[0] == "comparator"
    assert "lobatto-iiia-iiib-2-leapfrog" not in solve._METHODS


def test_remembered_options_still_refuse_bad_ones():
    from ldaspark.core.errors import InputError
    fast._check_options(10, 1, 1, None, 50, 3, 1)
    fast._check_options(10, 1, 1, None, 50, 3, 1)           # remembered
    assert (int, 10, int, 1, int, 1, type(None), None, int, 50, 3, 1) in fast._OPTIONS_OK
    # True == 1 and hash(True) == hash(1): without the types in the key predictor=True would pass
    for bad in [dict(predictor=True), dict(n_steps=True), dict(n_steps=0), dict(every=1.0), dict(tol=-1.0)]:
        args = dict(n_steps=10, every=1, predictor=1, tol=None, max_iter=50)
        args.update(bad)
        with pytest.raises(InputError):
            fast._check_options(args["n_steps"], args["every"], args["predictor"], args["tol"],
                                args["max_iter"], 3, 1)
    with pytest.raises(InputError):                          # unhashable: checked, not remembered
        fast._check_options([10], 1, 1, None, 50, 3, 1)
