"""Checks shared by ``verification/test_systems_*.py`` (the classic systems,
``ldaspark.models.systems_classic``).

* ``ode_residual``: a closed-form solution against the underlying ODE (3a-b) at 30 digits: the
  acceleration by a central difference of the closed-form v (step d = 1e-10: truncation
  d^2 |v'''| / 6 ~ 1e-21, round-off 1e-30 / d = 1e-20), psi and k directly. Tolerance
  ``RESIDUAL_TOL`` = 1e-15: four orders above that error, fifteen below the residual of a
  wrong sign (O(1)).
* ``orders``: observed orders (least squares over the asymptotic window, ``theory.orders``) of
  Gauss s (claimed 2s) and Lobatto IIIA-B s (claimed 2s - 2) against a reference, two-sided
  within ``ORDER_TOL`` = 0.3 (the tolerance of the suite's other order checks: the LS slope over
  four halvings moves by < 0.1 from the leading error term's next correction at these h, and
  0.3 < 1/2 keeps order p apart from p +- 1).
* ``constraint_bound``: k at round-off along a run, max |k| <= 100 eps (1 + max|q|)(1 + max|v|):
  k is evaluated at q whose rounding error is eps |q| (the angles grow linearly) times
  derivatives of size |v|; the factor 100 covers the Newton tolerance (8 eps) and the ~10
  operations of a constraint. ``rk4_constraint_drift``: the control, classical RK4 on (3a-b),
  which does not enforce k = 0 and leaves it at its O(h^4) truncation error.
  ``check_constraint_roundoff_and_engines`` runs both, and the generic engine against the compiled one.
* ``long_run``: invariants along a compiled run, ``bounded`` when the max error over the last
  quarter / the first quarter <= 1.5 (``reports.energy.BOUNDED_RATIO``: linear drift gives ~4,
  a random walk ~2) or the error stays at round-off (<= 100 eps sqrt(N) (1 + |I0|) after N steps:
  ~100 eps per step from the Newton tolerance and the evaluation of I, accumulated as a random
  walk); ``drift``: not at round-off and the ratio >= 2.
"""
from __future__ import annotations

import math

import mpmath
import numpy as np

from ldaspark.core.backend import Backend
from ldaspark.core.families import get_method
from ldaspark.lab.reports.energy import BOUNDED_RATIO, boundedness
from ldaspark.lab.theory.orders import estimate_order, floor_for, measure_errors

EPS = 2.0 ** -52
RESIDUAL_TOL = 1e-15
ORDER_TOL = 0.3
# default order plan: (method, N list over [0, t_end]); float64, errors far above the 1e3 eps floor
ORDER_PLAN = (("gauss-1", [8, 16, 32, 64]), ("gauss-2", [4, 8, 16, 32]),
              ("lobatto-iiia-iiib-2", [8, 16, 32, 64]), ("lobatto-iiia-iiib-3", [4, 8, 16, 32]))
EXHAUSTIVE_PLAN = (("gauss-3", [4, 8, 16, 32]), ("lobatto-iiia-iiib-4", [4, 8, 16, 32]),
                   ("lobatto-iiia-iiib-iiid-3", [4, 8, 16, 32]))


def ode_residual(scene, system=None, t="0.7", dps=30):
    """(|v' - a|, |psi_exact - psi|, |k|) at t for the scene's closed form against the (3a-b) of
    ``system`` (default: the scene's own; a wrong-sign system for the controls)."""
    S = system or scene.system
    bk = Backend(dps)
    with mpmath.workdps(dps):
        tt, d = mpmath.mpf(t), mpmath.mpf("1e-10")
        q, v, p = scene.exact_solution(tt, dps=dps)
        vp = scene.exact_solution(tt + d, dps=dps)[1]
        vm = scene.exact_solution(tt - d, dps=dps)[1]
        a, psi = S.ode_rhs(bk, tt, q, v)
        k = S.constraint(bk, tt, q, v)
        return (float(max(abs(x) for x in (vp - vm) / (2 * d) - a)), float(max(abs(x) for x in psi - p)),
                float(max(abs(x) for x in k)))


def observed_orders(scene, reference, t_end=1.0, plan=ORDER_PLAN, system=None, quantity=None):
    """{method: (claimed, {variable: observed order}, errors)}. ``system`` replaces the scene's
    system (wrong-sign controls; same initial data); ``quantity(q, v) -> array`` measures the
    error of a derived quantity instead of q and v (the Suslov body angular velocity), with
    ``reference(t)`` then returning that quantity."""
    out = {}
    for meth, nl in plan:
        p = get_method(meth).claimed_order
        if quantity is None:
            sc = scene if system is None else _with_system(scene, system)
            m = measure_errors(meth, sc, reference, t_end, nl)
            obs = {}
            for var in ("q", "v"):
                est = estimate_order(m["h"], m[var], floor_for(None, m["scale"][var]))
                obs[var] = est.observed_order
            out[meth] = (p, obs, {var: m[var] for var in ("q", "v")})
        else:
            from ldaspark.core.spark import integrate
            S = system or scene.system
            t0, q0, v0 = scene.initial()
            ex = np.asarray(reference(t_end), float)
            hs, errs = [], []
            for N in nl:
                sol = integrate(S, get_method(meth), t0, q0, v0, (t_end - t0) / N, n_steps=N, newton="full")
                hs.append((t_end - t0) / N)
                errs.append(float(np.abs(np.asarray(quantity(sol.q[-1], sol.v[-1]), float) - ex).max()))
            est = estimate_order(hs, errs, floor_for(None, float(np.abs(ex).max())))
            out[meth] = (p, {"quantity": est.observed_order}, {"quantity": errs})
    return out


def orders_hold(obs, tol=ORDER_TOL):
    """True when every observed order is within ``tol`` of the claim (None: no window: fails)."""
    return all(o is not None and abs(o - p) <= tol for p, d, _ in obs.values() for o in d.values())


def _with_system(scene, system):
    import copy
    sc = copy.copy(scene)
    sc.system = system
    return sc


def constraint_bound(res):
    """100 eps (1 + max|q|)(1 + max|v|) (module docstring)."""
    q, v = np.asarray(res.q, float), np.asarray(res.v, float)
    return 100 * EPS * (1 + np.abs(q).max()) * (1 + np.abs(v).max())


def check_constraint_roundoff_and_engines(name):
    """Asserts, for the scene ``name``: Gauss-2 (h = 0.1, [0, 200], compiled engine) succeeds with
    max |k| <= ``constraint_bound`` (100 eps (1 + max|q|)(1 + max|v|), module docstring); the
    generic engine's q at t = 2 agrees with the compiled run's to 1e-12 (max abs); control: classical
    RK4 on (3a-b) over the same 20 steps leaves max |k| > 10 ``constraint_bound`` (k above the
    bound by a factor 10, not at round-off)."""
    import ldaspark
    from ldaspark.models.scenes import get_scene
    sc = get_scene(name)
    res = ldaspark.integrate(name, "gauss-2", t_span=(0, 200), h=0.1)
    assert res.engine == "compiled" and res.success, (res.engine, res.success)
    assert np.abs(res.constraint).max() <= constraint_bound(res), (np.abs(res.constraint).max(), constraint_bound(res))
    gen = ldaspark.integrate(name, "gauss-2", t_span=(0, 2), h=0.1, engine="generic")
    assert np.abs(gen.q[-1] - res.q[20]).max() < 1e-12, np.abs(gen.q[-1] - res.q[20]).max()
    drift = rk4_constraint_drift(sc, 0.1, 20)
    assert drift > 10 * constraint_bound(res), (drift, constraint_bound(res))


def rk4_constraint_drift(scene, h, n_steps, q0=None, v0=None):
    """max |k| along classical RK4 on (3a-b) (float64): the control of the round-off claim."""
    S = scene.system
    bk = Backend(None)
    t0, sq, sv = scene.initial()
    q = np.array(sq if q0 is None else q0, float)
    v = np.array(sv if v0 is None else v0, float)
    n = S.n
    t = float(t0)

    def f(t, y):
        a, _ = S.ode_rhs(bk, t, y[:n], y[n:])
        return np.concatenate([y[n:], a])
    y = np.concatenate([q, v])
    worst = 0.0
    for _ in range(n_steps):
        k1 = f(t, y)
        k2 = f(t + h / 2, y + h / 2 * k1)
        k3 = f(t + h / 2, y + h / 2 * k2)
        k4 = f(t + h, y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        t += h
        worst = max(worst, float(np.abs(S.constraint(bk, t, y[:n], y[n:])).max()))
    return worst


def long_run(scene, method, T, h, q0=None, v0=None, engine="compiled", observables=None):
    """(Result, {name: boundedness record + 'bounded'}) of the scene's invariants (or of
    ``observables``: {name: f(t, q, v) -> array of errors}) along a run of ``method``."""
    import ldaspark
    res = ldaspark.integrate(scene, method, t_span=(0, T), h=h, q0=q0, v0=v0, engine=engine)
    series, I0 = {}, {}
    if observables is None:
        for k, x in scene.invariant_values(res.t, res.q, res.v).items():
            series[k] = x - x[0]
            I0[k] = x[0]
    else:
        for k, f in observables.items():
            series[k] = np.asarray(f(res.t, res.q, res.v), float)
    out = {}
    for k, e in series.items():
        b = boundedness(res.t, e)
        scale = 1 + abs(float(I0.get(k, 0.0)))
        b["roundoff"] = bool(b["max_abs_dE"] <= 100 * EPS * math.sqrt(len(res.t)) * scale)
        b["bounded"] = bool(b["roundoff"] or b["last_over_first_quarter"] <= BOUNDED_RATIO)
        b["drift"] = bool(not b["roundoff"] and b["last_over_first_quarter"] >= 2.0)
        out[k] = b
    return res, out


def wrong_sign(system, where, symbol_name, name=None):
    """The system with ``symbol_name`` -> -``symbol_name`` in L (``where="L"``) or in k only:
    a sign error a user could make (the control of each check)."""
    import sympy
    from ldaspark.core.system import LagrangianSystem
    sym = next(s for s in list(system.q) + list(system.v) if str(s) == symbol_name)
    L = system.L.subs(sym, -sym) if where == "L" else system.L
    k = [e.subs(sym, -sym) for e in system.k] if where == "k" else list(system.k)
    assert (L != system.L) or any(sympy.simplify(a - b) != 0 for a, b in zip(k, system.k)), "sign flip changed nothing"
    return LagrangianSystem(L, k, system.q, system.v, t=system.t, name=name or f"{system.name}-wrong-{where}")


def finite(x):
    return x is not None and math.isfinite(x)
