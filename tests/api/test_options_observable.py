"""Every option of ``ldaspark.integrate`` is observable on every engine: changing it changes the
counters or the numbers as documented, or it is refused (docs/verification.md, "The
differential harness"). A discrepancy is a strict xfail naming it, so that it flips when fixed.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark import LdasparkError
from ldaspark.core.errors import InputError

ENGINES = ("generic", "compiled")
KW = dict(t_span=(0.0, 0.5), h=0.05)


def run(engine, **kw):
    return ldaspark.integrate("skate", "gauss-2", engine=engine, **{**KW, **kw})


@pytest.mark.parametrize("engine", ENGINES)
def test_tol_changes_the_iterations(engine):
    """A loose Newton tolerance stops earlier: fewer iterations, other numbers (at ~tol); on a
    system where Newton needs several iterations (L quartic in v, k quadratic in v)."""
    from verification.general_fixtures import rheonomic_initial, rheonomic_system
    t0, q0, v0 = rheonomic_initial()
    sysm = rheonomic_system()

    def go(**kw):
        return ldaspark.integrate(sysm, "gauss-2", t_span=(t0, t0 + 0.5), q0=q0, v0=v0, h=0.1, engine=engine, **kw)
    tight, loose = go(), go(tol=1e-3)
    assert loose.newton_iterations < tight.newton_iterations, (loose.newton_iterations, tight.newton_iterations)
    assert 0 < np.max(np.abs(loose.q - tight.q)) < 1e-2


@pytest.mark.parametrize("engine", [
    "generic",
    "compiled",                     # honoured since the root finder became an option object (#46)
])
def test_newton_variant_changes_the_counters(engine):
    """Full Newton evaluates and factors the Jacobian at every iteration, simplified Newton once
    a step: the counters njev/nlu differ (same numbers to the tolerance)."""
    full, simp = run(engine, newton="full"), run(engine, newton="simplified")
    assert (full.njev, full.nlu) != (simp.njev, simp.nlu), (full.njev, full.nlu, simp.njev, simp.nlu)
    assert full.njev > simp.njev
    assert np.max(np.abs(full.q - simp.q)) < 1e-12


@pytest.mark.parametrize("engine", ENGINES)
def test_save_every_keeps_fewer_rows_and_the_same_work(engine):
    a, b = run(engine), run(engine, save_every=3)
    assert len(a.t) == 11 and len(b.t) == 5 and b.nfev == a.nfev     # 0, 3, 6, 9 and the last (10)
    assert np.array_equal(np.asarray(b.t, float), np.asarray(a.t, float)[[0, 3, 6, 9, 10]])


@pytest.mark.parametrize("engine", ENGINES)
def test_dense_output_attaches_sol(engine):
    a, b = run(engine), run(engine, dense_output=True)
    assert getattr(a, "sol", None) is None and callable(b.sol)
    q, _ = b.sol(0.125)
    assert np.all(np.isfinite(q)) and not np.allclose(q, b.q[2]) and not np.allclose(q, b.q[3])


@pytest.mark.parametrize("engine", ENGINES)
def test_events_are_located_and_terminal_stops(engine):
    ref = run(engine)
    level = float((ref.q[0][0] + ref.q[-1][0]) / 2)

    def g(t, q, v):
        return q[0] - level
    a = run(engine, events=g)
    assert len(a.t_events[0]) >= 1 and a.status == 0 and len(a.t) == 11
    g.terminal = True
    b = run(engine, events=g)
    assert b.status == 1 and len(b.t) < 11


@pytest.mark.parametrize("engine", ENGINES)
def test_energy_jump_stops_the_run_and_raise_on_failure_raises(engine):
    """A threshold below the per-step energy change (round-off of a conserved energy: ~1e-16):
    status -3; with raise_on_failure the same failure is raised."""
    ok = run(engine, energy_jump=1e-3)
    assert ok.status == 0
    bad = run(engine, energy_jump=1e-300)
    assert bad.status == -3 and len(bad.t) < 11
    with pytest.raises(LdasparkError):
        run(engine, energy_jump=1e-300, raise_on_failure=True)


@pytest.mark.parametrize("method, h", [("gauss-2", "1e-3"), ("lobatto-iiia-iiib-2-leapfrog", "1e-5")])
def test_energy_jump_at_dps_is_judged_at_the_runs_digits(method, h):
    """At 30 digits the energy monitor compared float64 energies: a change of the energy below
    float64's resolution of E (ulp(1.5) = 2.2e-16) was 0 whatever energy_jump said. The particle's
    energy changes by 2.2e-19 .. 1.1e-18 a step with gauss-2 at h = 1e-3 (the stepping engine) and
    by 1.5e-20 .. 7.5e-20 with the leapfrog comparator at h = 1e-5 (a block engine): thresholds
    1e-21 (x 2.5 = 2.5e-21, 6x below the smallest change) stop at step 0; 1e-16 (2.5e-16, 2000x
    above the largest) does not (control)."""
    kw = dict(h=h, n_steps=3, dps=30)
    free = ldaspark.integrate("particle", method, **kw)
    E = np.asarray(free.energy, float)
    assert free.status == 0 and np.all(E == E[0])            # the changes are below float64's resolution
    r = ldaspark.integrate("particle", method, energy_jump=1e-21, **kw)
    assert r.status == -3 and len(r.t) == 1 and "step 0" in r.message
    assert ldaspark.integrate("particle", method, energy_jump=1e-16, **kw).status == 0


@pytest.mark.parametrize("engine", ENGINES)
def test_project_makes_inconsistent_data_consistent(engine):
    scene = ldaspark.get_scene("skate")
    t0, q0, v0 = scene.initial(None)
    v0 = [float(x) + 0.1 for x in v0]
    q0 = [float(x) for x in q0]
    with pytest.raises(LdasparkError, match="inconsistent"):
        run(engine, q0=q0, v0=v0)
    r = run(engine, q0=q0, v0=v0, project=True)
    assert r.status == 0 and r.stats["projected_v0_change"] > 1e-3


def test_dps_runs_mpmath_on_generic_and_is_refused_by_compiled():
    r = run("generic", dps=30)
    assert type(r.q[-1][0]).__name__ == "mpf"
    with pytest.raises(InputError, match="float64 only"):
        run("compiled", dps=30)


@pytest.mark.parametrize("engine", ENGINES)
def test_params_change_the_numbers(engine):
    x, y, vx, vy = sympy.symbols("x y vx vy")
    w = sympy.Symbol("w")
    sysm = ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - w * x ** 2 / 2, [vy - x * vx], [x, y], [vx, vy],
                                     params=[w])
    kw = dict(q0=[0.3, 0.0], v0=[0.2, 0.06], t_span=(0.0, 0.5), h=0.05, engine=engine)
    a = ldaspark.integrate(sysm, "gauss-2", params={"w": 1.0}, **kw)
    b = ldaspark.integrate(sysm, "gauss-2", params={"w": 2.0}, **kw)
    assert np.max(np.abs(a.q - b.q)) > 1e-3
    with pytest.raises(LdasparkError):
        ldaspark.integrate(sysm, "gauss-2", **kw)        # no value for w: refused


class _CountingExecutor(ThreadPoolExecutor):
    calls = 0

    def map(self, *a, **k):
        type(self).calls += 1
        return super().map(*a, **k)

    def submit(self, *a, **k):
        type(self).calls += 1
        return super().submit(*a, **k)


@pytest.mark.parametrize("engine", ENGINES)
def test_executor_runs_the_members(engine):
    scene = ldaspark.get_scene("skate")
    _, q0, v0 = scene.initial(None)
    q0, v0 = [float(x) for x in q0], [float(x) for x in v0]
    q1 = [q0[0] + 0.1] + q0[1:]
    _CountingExecutor.calls = 0
    with _CountingExecutor(max_workers=2) as ex:
        r = run(engine, q0=[q0, q1], v0=[v0, v0], executor=ex)
    assert _CountingExecutor.calls >= 1 and r.q.shape[0] == 2
    with pytest.raises(InputError):
        run(engine, executor="threads")


@pytest.mark.parametrize("engine", ENGINES)
def test_executor_runs_a_single_run(engine):
    # executor= with one run (q0 of shape (n,), params a dict or None) was accepted and the run
    # made in this process (the executor never called). A single run is an ensemble of one member:
    # it runs on the executor, its Result that of the run without one, bit for bit (the same
    # float64 operations in another thread). Control: without an executor nothing is submitted.
    _CountingExecutor.calls = 0
    ref = run(engine, dense_output=True)
    assert _CountingExecutor.calls == 0
    with _CountingExecutor(max_workers=1) as ex:
        r = run(engine, executor=ex, dense_output=True)
    assert _CountingExecutor.calls >= 1
    assert np.array_equal(np.asarray(r.q, float), np.asarray(ref.q, float)) and r.engine == ref.engine
    assert np.array_equal(r.sol(0.125)[0], ref.sol(0.125)[0])


def test_max_stages_raises_the_stage_limit():
    with pytest.raises(LdasparkError, match="more than the limit"):
        ldaspark.integrate("skate", "gauss-21", h=0.1, n_steps=1, engine="generic")
    r = ldaspark.integrate("skate", "gauss-21", h=0.1, n_steps=1, engine="generic", max_stages=21)
    assert r.status == 0 and r.psi.shape[1] == 21


@pytest.mark.parametrize("engine", ENGINES)
def test_an_unknown_option_is_refused(engine):
    with pytest.raises(InputError, match="did you mean tol"):
        run(engine, tool=1e-3)
