"""The step-acceptance guard (``ldaspark.core.guard``): a step whose Newton converged to another
root of the stage equations (21) stops the run on every engine; without the guard the same run
returns the wrong root silently (the negative control)."""
import warnings

import numpy as np
import pytest
import sympy as sp

import ldaspark
from ldaspark import LagrangianSystem, Newton
from ldaspark.core import guard

x, y, vx, vy = sp.symbols("x y vx vy")
# a double well: for gauss-1 the stage equation is a cubic in the midpoint position with three
# real roots once h > 2 (w^3 + (4/h^2 - 1) w = b); at h = 2.5 from (1.2, 1.5) a Newton started
# from zero increments (predictor="zero") lands on another root at a later step than the one
# the previous step's collocation polynomial leads to (found by a scan of h, x0, vx0)
WELL = LagrangianSystem((vx ** 2 + vy ** 2) / 2 - (x ** 4 / 4 - x ** 2 / 2), [vy], [x, y], [vx, vy],
                        name="double-well")
START = dict(t0=0.0, q0=[1.2, 0.0], v0=[1.5, 0.0], h=2.5, n_steps=30)


def run(method, engine, newton="auto", **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ldaspark.integrate(WELL, method, engine=engine, newton=newton, **dict(START, **kw))


CASES = [("gauss-1", "generic", Newton(predictor="zero"), {}),
         ("gauss-1", "generic", Newton(predictor="zero"), {"dps": 20}),
         ("gauss-1", "compiled", Newton(predictor="zero"), {}),
         ("gauss-irk-1", "generic", "auto", {})]       # a comparator: its warm start vs a fresh one


@pytest.mark.parametrize("method, engine, newton, kw", CASES, ids=["generic", "mpmath", "compiled", "comparator"])
def test_a_second_root_stops_the_run_on_every_engine(method, engine, newton, kw):
    res = run(method, engine, newton, **kw)
    assert res.status == guard.STATUS_GUARD, res.message
    k = res.error.step
    assert "two roots" in res.message and f"step {k} " in res.message
    assert res.message.count("q1 = ") == 2 and res.message.count("with energy") + res.message.count("with E =") == 2
    assert len(res.t) == k + 1 and res.stats["guard_flagged"] >= 1    # ends at the state before the step
    with pytest.raises(guard.RootMismatchError):
        res.raise_for_status()
    # negative control: without the guard the run goes through that step on the other root (as
    # the rattleback did: it may fail with a Newton message only steps later), and the energy (8)
    # jumps there far beyond the previous steps' changes (the guard's own test, flagged)
    off = run(method, engine, newton, guard=False, **kw)
    assert len(off.t) > k + 1 and off.stats["guard"] is False
    E = np.asarray(off.energy, dtype=float)
    assert k in guard.flagged(E)
    assert np.allclose(np.asarray(off.q[:k + 1], float), np.asarray(res.q, float), rtol=0, atol=1e-12)


def test_a_flagged_step_with_the_same_root_stands():
    # the default predictor finds the continuing root: its flagged steps are confirmed
    res = run("gauss-1", "generic")
    assert res.status == 0 and res.stats["guard_flagged"] >= 1
    assert res.stats["guard_confirmed"] == res.stats["guard_flagged"]


def test_threshold_is_relative_to_the_previous_steps():
    # a smooth energy error never flags; the same series with one step 20x its neighbours
    # (beyond SAFETY = 10) flags exactly that step; step 0 has no history
    n = np.arange(200)
    E = 1.0 + 1e-6 * np.sin(0.3 * n)
    assert len(guard.flagged(E)) == 0
    J = E.copy()
    J[101:] += 20 * np.max(np.abs(np.diff(E)))
    assert list(guard.flagged(J)) == [100]
    J0 = E.copy()
    J0[1:] += 1.0
    assert len(guard.flagged(J0)) == 0
    # round-off only (an energy-preserving method): below the 1024-ulp floor
    R = 1.0 + 1e-16 * np.random.default_rng(0).standard_normal(100)
    assert len(guard.flagged(R)) == 0
    # the streaming test of the generic engine agrees with the vectorised one
    g = guard.StepGuard()
    seen = []
    for i in range(len(J) - 1):
        if g.suspect(i, J[i], J[i + 1]):
            seen.append(i)
        g.accept(J[i], J[i + 1])
    assert seen == [100]


def test_the_guard_flags_nothing_on_the_skate():
    for engine in ("generic", "compiled"):
        res = ldaspark.integrate("skate", "gauss-2", t_span=(0, 10), h=0.1, engine=engine)
        assert res.status == 0 and res.stats["guard"] is True and res.stats["guard_flagged"] == 0


def test_a_second_root_between_saved_samples_is_located():
    # save_every = 4 on the compiled engine: the guard judges the saved samples, runs the
    # flagged prefix again with every step kept, and stops at the same step as with every step
    every = run("gauss-1", "compiled", Newton(predictor="zero"))
    sampled = run("gauss-1", "compiled", Newton(predictor="zero"), save_every=4)
    assert every.status == sampled.status == guard.STATUS_GUARD
    assert sampled.error.step == every.error.step
    k = every.error.step
    assert list(sampled.t) == list(every.t[list(range(0, k + 1, 4)) + ([k] if k % 4 else [])])
    assert sampled.psi is not None and len(sampled.psi) == len(sampled.t) - 1


def test_the_guard_runs_on_every_member_of_a_compiled_ensemble_through_an_executor():
    # an ensemble over initial data with an executor once went to the kernel tasks without the
    # guard (members' stats without "guard"): with guard=True (the default) every member is
    # judged as its single run is; guard=False takes the kernel tasks and says so
    from concurrent.futures import ThreadPoolExecutor
    Q0, V0 = [[1.2, 0.0], [1.1, 0.0]], [[1.5, 0.0], [1.4, 0.0]]
    kw = dict(START, q0=Q0, v0=V0, n_steps=12)
    singles = [run("gauss-1", "compiled", **dict(kw, q0=q, v0=v)) for q, v in zip(Q0, V0)]
    assert sum(r.stats["guard_flagged"] for r in singles) >= 1       # the scene gives the guard work
    with ThreadPoolExecutor(1) as ex:
        ens = run("gauss-1", "compiled", executor=ex, **kw)
        off = run("gauss-1", "compiled", executor=ex, guard=False, **kw)
    for member, one in zip(ens.stats["members"], singles):
        assert member["guard"] is True and member["engine"] == "compiled"
        assert {k: member[k] for k in ("guard_flagged", "guard_confirmed")} == \
            {k: one.stats[k] for k in ("guard_flagged", "guard_confirmed")}
    assert [m["guard"] for m in off.stats["members"]] == [False, False]
    assert np.array_equal(np.asarray(ens.q, float), np.asarray(off.q, float))


@pytest.mark.parametrize("t0", [-40.0, 1e7])
def test_a_second_root_between_saved_samples_is_located_from_any_t0(t0):
    # the double well is autonomous: from t0 = -40 or 1e7 (t0 + k h exact in float64) the run is
    # the one from 0, and the guard runs the prefix up to the flagged sample interval (its length
    # counted from t0) again with every step kept: the same step is located
    ref = run("gauss-1", "compiled", Newton(predictor="zero"), save_every=4)
    res = run("gauss-1", "compiled", Newton(predictor="zero"), save_every=4, t0=t0)
    assert ref.status == res.status == guard.STATUS_GUARD
    assert res.error.step == ref.error.step and np.array_equal(res.q, ref.q)
    assert list(res.t) == [t0 + float(x) for x in ref.t]


@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_a_loose_newton_tolerance_is_not_a_second_root(engine):
    """tol = 1e-5 leaves each root uncertain at ~1e-5: the friction skate's flagged step 1 was
    called two roots (status -4; with guard=False the run is the same to 2e-6 of the default
    tolerance's). Roots agree within max(ROOT_AGREE, ROOT_TOL_FACTOR tol) now, and energy changes
    within ENERGY_TOL_FACTOR tol are Newton's. Control: at that tolerance the double well's second
    root (O(1) away) still stops the run."""
    kw = dict(n_steps=20, h=0.05, tol=1e-5, engine=engine)
    res = ldaspark.integrate("friction-skate", "lobatto-iiia-iiib-2", **kw)
    off = ldaspark.integrate("friction-skate", "lobatto-iiia-iiib-2", guard=False, **kw)
    assert res.status == 0 and np.array_equal(np.asarray(res.q, float), np.asarray(off.q, float))
    assert guard.same_root([1.0], [0.0], [1.0 + 1e-6], [0.0], tol=1e-5)
    assert not guard.same_root([1.0], [0.0], [1.0 + 1e-6], [0.0])
    wrong = run("gauss-1", engine, Newton(predictor="zero", tol=1e-5))
    assert wrong.status == guard.STATUS_GUARD and "two roots" in wrong.message
