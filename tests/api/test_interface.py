"""ldaspark.integrate: names, engines, one Result type, failures keep the prefix, save_every,
ensembles."""
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark import LagrangianSystem
from ldaspark.core.errors import InputError, NewtonError
from ldaspark.core.families import get_method
from ldaspark.core.result import Result
from ldaspark.models.scenes import get_scene
from ldaspark.core.spark import integrate as core_integrate


def test_top_level_names():
    from ldaspark.solve import integrate
    assert ldaspark.integrate is integrate
    assert ldaspark.Result is Result
    assert callable(ldaspark.load_result) and callable(ldaspark.plot.energy)


def test_by_name_equals_tableau_and_core_loop():
    """A name, a SparkTableau and the core loop compute the same numbers (same steps, same predictor)."""
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    ref = core_integrate(sc.system, get_method("gauss-2"), t0, q0, v0, 0.1, n_steps=8)
    a = ldaspark.integrate(sc, "gauss-2", n_steps=8, h=0.1, engine="generic")
    b = ldaspark.integrate(sc.system, get_method("gauss-2"), (0, 0.8), q0, v0, 0.1, engine="generic")
    for r in (a, b):
        assert isinstance(r, Result) and r.success and r.status == 0
        for name in ("t", "q", "v", "energy", "constraint", "psi"):
            assert np.array_equal(getattr(r, name), getattr(ref, name)), name
    assert a.nfev == ref.stats["nfev"] > 0 and a.nlu == ref.stats["nlu"] > 0 and a.newton_iterations > 0
    assert a.engine == "generic" and a.scene == "skate" and a.method == "gauss-2"


def test_comparator_by_name():
    r = ldaspark.integrate("particle", "gauss-irk-1", n_steps=4, h=0.1, engine="generic")
    assert r.success and r.q.shape == (5, 3) and r.method == "gauss-irk-1"


def test_unknown_method_and_engine():
    with pytest.raises(InputError, match="unknown method"):
        ldaspark.integrate("particle", "gauss-x", n_steps=2, h=0.1)
    with pytest.raises(InputError, match="engine"):
        ldaspark.integrate("particle", "gauss-2", n_steps=2, h=0.1, engine="fast")
    with pytest.raises(InputError, match="exactly one"):
        ldaspark.integrate("particle", "gauss-2", h=0.1)


def test_compiled_equals_generic():
    """The compiled kernels and the generic loop solve the same (21) (measured: 1.8e-13 after
    1e4 steps of gauss-2 on the particle); 200 steps here."""
    g = ldaspark.integrate("particle", "gauss-2", n_steps=200, h=0.01, engine="generic")
    c = ldaspark.integrate("particle", "gauss-2", n_steps=200, h=0.01, engine="compiled")
    assert c.engine == "compiled" and g.engine == "generic"
    assert np.abs(c.q - g.q).max() < 1e-12 and np.abs(c.v - g.v).max() < 1e-12
    assert c.psi.shape == g.psi.shape and np.abs(c.psi - g.psi).max() < 1e-10
    assert np.abs(c.energy - g.energy).max() < 1e-12
    # negative control: a different step size is not "the same numbers"
    g2 = ldaspark.integrate("particle", "gauss-2", n_steps=100, h=0.02, engine="generic")
    assert np.abs(g2.q[-1] - g.q[-1]).max() > 1e-12


def test_auto_falls_back_with_one_line(capsys, monkeypatch):
    """A system the code generator refuses runs on the generic engine with one notice line; a
    system with parameters stays compiled (tests/compiled/test_params_compiled.py)."""
    from ldaspark.compiled import runner
    from ldaspark.compiled.codegen import NotCompilableError
    m = sympy.Symbol("m")
    q, v = sympy.symbols("q1:4"), sympy.symbols("v1:4")
    sysm = LagrangianSystem(m * sum(x ** 2 for x in v) / 2 - (q[0] ** 2 + q[1] ** 2), [v[2] - q[1] * v[0]],
                            q, v, params=[m])
    r = ldaspark.integrate(sysm, "gauss-2", n_steps=3, h=0.1, q0=[1, 0, 0], v0=[0, 1, 0], params={"m": 1})
    assert r.engine == "compiled" and capsys.readouterr().err == ""

    def refuse(system, parts=None):
        raise NotCompilableError(f"{system.name}: an expression has no numba translation (refused here)")
    monkeypatch.setattr(runner, "mechanical_source", refuse)
    monkeypatch.setattr(runner, "general_source", refuse)
    fresh = LagrangianSystem(sysm.L, sysm.k, q, v, params=[m])    # the first one's model is kept with it
    r = ldaspark.integrate(fresh, "gauss-2", n_steps=3, h=0.1, q0=[1, 0, 0], v0=[0, 1, 0], params={"m": 2})
    err = capsys.readouterr().err.strip().splitlines()
    assert r.engine == "generic" and len(err) == 1 and "generic engine" in err[0]


def _wall():
    """A particle pulled into the domain boundary q1 = 2 of its Lagrangian (math domain error)."""
    q, v = sympy.symbols("q1:4"), sympy.symbols("v1:4")
    L = sum(x ** 2 for x in v) / 2 - sympy.sqrt(2 - q[0])
    return LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="wall")


def test_generic_failure_keeps_prefix():
    sysm = _wall()
    r = ldaspark.integrate(sysm, "gauss-2", t_span=(0, 3), q0=[0, 0, 0], v0=[1, 0, 0], h=0.05, engine="generic")
    assert r.status == -3 and not r.success and "step 29" in r.message
    assert len(r.t) == 30 and len(r.psi) == 29 and np.all(np.isfinite(r.q))
    ok = ldaspark.integrate(sysm, "gauss-2", n_steps=29, q0=[0, 0, 0], v0=[1, 0, 0], h=0.05, engine="generic")
    assert ok.success and np.array_equal(ok.q, r.q) and np.array_equal(ok.psi, r.psi)
    with pytest.raises(NewtonError):
        ldaspark.integrate(sysm, "gauss-2", t_span=(0, 3), q0=[0, 0, 0], v0=[1, 0, 0], h=0.05, engine="generic",
                           raise_on_failure=True)
    with pytest.raises(NewtonError):
        r.raise_for_status()


# the same walk into the domain boundary of L on every engine and comparator: the generic SPARK
# step called it a Newton failure (status -1: "residual nan ... math domain error"), the compiled
# kernels a non-finite value (status -3), and the semi-implicit comparators on the generic engine
# let the raw ValueError "math domain error" of grad U out of integrate. Now every path ends at
# the same step with status -3 (STATUS_OTHER: NaN, infinity or complex values, NonFiniteError)
# and the trajectory up to the last good step.
WALL_PATHS = [("gauss-2", "generic", {}), ("gauss-2", "generic", {"dps": 20}), ("gauss-2", "compiled", {}),
              ("lobatto-iiia-iiib-2", "generic", {}), ("lobatto-iiia-iiib-2", "compiled", {}),
              ("gauss-irk-2", "generic", {}), ("lobatto-iiia-iiib-2-modified", "generic", {}),
              ("lobatto-iiia-iiib-2-modified", "compiled", {}), ("lobatto-iiia-iiib-2-leapfrog", "generic", {}),
              ("lobatto-iiia-iiib-2-leapfrog", "generic", {"dps": 20}),
              ("lobatto-iiia-iiib-2-leapfrog", "compiled", {}), ("lobatto-iiia-iiib-2-modified-leapfrog", "generic", {}),
              ("mp-lobatto-iiib-a-2", "generic", {}), ("mp-lobatto-iiib-a-2", "compiled", {}),
              ("euler-i-ii-composition", "generic", {})]


@pytest.mark.parametrize("method, engine, kw", WALL_PATHS)
def test_a_domain_failure_is_the_same_status_on_every_engine(method, engine, kw):
    from ldaspark.core.errors import NonFiniteError
    sysm = _wall()
    run = dict(t_span=(0, 3), q0=[0, 0, 0], v0=[1, 0, 0], h=0.05, engine=engine, **kw)
    r = ldaspark.integrate(sysm, method, **run)
    assert r.status == -3 and "step 29" in r.message and len(r.t) == 30, (r.status, r.message)
    assert isinstance(r.error, NonFiniteError) and np.all(np.isfinite(np.asarray(r.q, float)))
    ok = ldaspark.integrate(sysm, method, **dict(run, t_span=None, n_steps=29))
    assert ok.success and np.array_equal(np.asarray(ok.q, float), np.asarray(r.q, float))


def test_compiled_failure_keeps_prefix():
    # h = 6 (measured: stops at step 9): at h = 2 the compiled engine used to fail where the generic
    # full Newton converges; its fallback chain now finishes that run, as the generic one
    r = ldaspark.integrate("robot", "gauss-2", n_steps=40, h=6.0, engine="compiled")
    assert r.status == -1 and r.engine == "compiled" and 1 < len(r.t) < 41
    ok = ldaspark.integrate("robot", "gauss-2", n_steps=len(r.t) - 1, h=6.0, engine="compiled")
    assert ok.success and np.array_equal(ok.q, r.q)


@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_save_every_is_slicing(engine):
    full = ldaspark.integrate("skate", "gauss-2", n_steps=23, h=0.05, engine=engine)
    part = ldaspark.integrate("skate", "gauss-2", n_steps=23, h=0.05, engine=engine, save_every=5)
    idx = [0, 5, 10, 15, 20, 23]
    assert np.array_equal(part.t, full.t[idx])
    for name in ("q", "v", "energy", "constraint"):
        assert np.array_equal(getattr(part, name), getattr(full, name)[idx]), name
    if engine == "generic":
        assert np.array_equal(part.psi, full.psi[idx[:-1]])
    with pytest.raises(InputError):
        ldaspark.integrate("skate", "gauss-2", n_steps=3, h=0.05, save_every=0)


def test_mpmath_engine():
    r = ldaspark.integrate("skate", "gauss-2", n_steps=3, h="0.1", dps=30)
    assert r.dps == 30 and r.engine == "generic" and r.q.dtype == object
    assert abs(float(r.constraint[-1, 0])) < 1e-28


def test_ensemble_over_initial_data():
    sc = get_scene("particle")
    Q0 = [[1, 0, 0], [0.5, 0, 0]]
    V0 = [[0, 1, 0], [0, 0.5, 0]]
    r = ldaspark.integrate(sc.system, "gauss-2", n_steps=5, h=0.1, q0=Q0, v0=V0, engine="generic")
    assert r.batch == 2 and r.q.shape == (2, 6, 3) and r.status.tolist() == [0, 0] and r.success
    one = ldaspark.integrate(sc.system, "gauss-2", n_steps=5, h=0.1, q0=Q0[1], v0=V0[1], engine="generic")
    assert np.array_equal(r.q[1], one.q) and r.nfev.shape == (2,)


def test_compiled_ensemble_through_an_executor_equals_the_loop():
    from concurrent.futures import ThreadPoolExecutor
    Q0 = [[1, 0, 0], [0.5, 0, 0], [0.2, 0, 0]]
    V0 = [[0, 1, 0], [0, 0.5, 0], [0, 0.3, 0]]
    kw = dict(n_steps=20, h=0.05, q0=Q0, v0=V0, engine="compiled", save_every=4)
    loop = ldaspark.integrate("particle", "gauss-2", **kw)
    with ThreadPoolExecutor(1) as ex:
        par = ldaspark.integrate("particle", "gauss-2", executor=ex, **kw)
    assert par.batch == loop.batch == 3 and par.q.shape == (3, 6, 3) and par.success
    assert np.array_equal(par.q, loop.q) and np.array_equal(par.t, loop.t) and par.method == "gauss-2"
    assert list(par.nfev) == list(loop.nfev)


@pytest.mark.parametrize("tol", [None, 1e-6])
def test_compiled_ensemble_kernel_tasks_honour_tol(tol):
    # guard=False sends an ensemble through an executor to the kernel tasks of run_many: each
    # member equals its single run with the same tol (a loose tol takes fewer Newton iterations)
    from concurrent.futures import ThreadPoolExecutor
    Q0 = [[1, 0, 0], [0.5, 0, 0]]
    V0 = [[0, 1, 0], [0, 0.5, 0]]
    kw = dict(n_steps=20, h=0.2, engine="compiled", guard=False, tol=tol)
    with ThreadPoolExecutor(1) as ex:
        par = ldaspark.integrate("particle", "gauss-2", q0=Q0, v0=V0, executor=ex, **kw)
    assert [m["guard"] for m in par.stats["members"]] == [False, False]     # the kernel tasks ran
    for r, (q0, v0) in enumerate(zip(Q0, V0)):
        one = ldaspark.integrate("particle", "gauss-2", q0=q0, v0=v0, **kw)
        assert np.array_equal(par.q[r], one.q) and par.newton_iterations[r] == one.newton_iterations
    loose = ldaspark.integrate("particle", "gauss-2", q0=Q0[0], v0=V0[0], **dict(kw, tol=1e-6))
    tight = ldaspark.integrate("particle", "gauss-2", q0=Q0[0], v0=V0[0], **dict(kw, tol=None))
    assert loose.newton_iterations < tight.newton_iterations     # the option is observable here


@pytest.mark.parametrize("how", ["loop", "executor", "params"])
def test_an_ensemble_whose_samples_cannot_fit_is_refused_before_any_member_runs(monkeypatch, how):
    """The storage bound holds for the ensemble as a whole on every path (the kernel tasks of
    run_many bounded it, the loop of single runs bounded each member alone): a memory limit that
    fits one member of 101 samples but not 100 of them refuses the ensemble before any step."""
    from concurrent.futures import ThreadPoolExecutor
    from ldaspark import solve
    from ldaspark.core import validate
    sc = get_scene("skate")
    # gauss-2 on the skate: 2 + 2n + m + s m = 11 numbers a sample, 40 bytes each (float64)
    one = 101 * 11 * 40
    monkeypatch.setattr(validate, "physical_memory", lambda: int(4 * one / validate.MEMORY_FRACTION))
    B = 100
    kw = dict(q0=np.tile(sc.q0, (B, 1)), v0=np.tile(np.asarray(sc.v0, dtype=float), (B, 1)))
    if how == "executor":
        kw["executor"] = ThreadPoolExecutor(1)
    elif how == "params":
        kw = dict(params=[{}] * B)
    ran = []
    monkeypatch.setattr(solve, "_member", lambda *a: ran.append(a) or pytest.fail("a member ran"))
    with pytest.raises(InputError, match=r"storing the ensemble samples \(1\.01e\+04 points x 11 numbers\)"):
        ldaspark.integrate("skate", "gauss-2", h=0.01, n_steps=100, **kw)
    assert ran == []
    # one member alone fits
    assert ldaspark.integrate("skate", "gauss-2", h=0.01, n_steps=100).status == 0


def _raises_in_member_1(t, q, v):
    """An event function that raises in the member started at q[0] = 0.5 (module level: pickles)."""
    if abs(q[0] - 0.5) < 0.05:
        raise ZeroDivisionError("boom")
    return 1.0


@pytest.mark.parametrize("where", ["loop", "threads"])
@pytest.mark.parametrize("fault", ["inconsistent v0", "parameter", "event"])
def test_an_ensemble_error_names_the_member_on_every_path(where, fault):
    """A member whose set-up or event function fails ends the call with an error naming the member
    (the executor path's initial-point check said "ensemble member 1:", the loop did not, and no
    path named a member with a bad parameter value or a raising event function)."""
    from concurrent.futures import ThreadPoolExecutor
    sc = get_scene("particle")
    Q0 = [[1, 0, 0], [0.5, 0, 0], [0.2, 0, 0]]
    V0 = [[0, 1, 0], [0, 0.5, 0], [0, 0.3, 0]]
    kw = dict(n_steps=5, h=0.1, q0=Q0, v0=V0)
    if fault == "inconsistent v0":
        kw["v0"] = [V0[0], [1, 1, 1], V0[2]]
    elif fault == "event":
        kw["events"] = _raises_in_member_1
    system = sc.system
    if fault == "parameter":
        system = LagrangianSystem("(vx**2 + vy**2 + vz**2)/2 - g*z", ["vz - x*vy"], ["x", "y", "z"],
                                  ["vx", "vy", "vz"], params=["g"], name="knife")
        kw = dict(n_steps=5, h=0.1, q0=[0, 0, 0], v0=[1, 0, 0], params=[{"g": 1}, {"g": "foo"}, {"g": 2}])
    ex = ThreadPoolExecutor(1) if where == "threads" else None
    with pytest.raises(ldaspark.LdasparkError, match=r"^ensemble member 1: "):
        ldaspark.integrate(system, "gauss-2", executor=ex, **kw)
