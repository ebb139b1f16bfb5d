"""Ill-conditioned scenes and time reversal, sections 4-5 of the stability report (plain data,
reused by ``ldaspark.lab.reports.stability`` and tests/lab/reports/test_extremes.py).

* ``mass_ratio_scene``, ``rank_loss_scene``, ``soft_scene``: ill-conditioned scenes built here,
  with what the user gets (error class and message, or silence); ``saddle_crossings`` is a
  post-run monitor for trajectories that cross the singular set of assumption (4).
* ``time_reversal``: forward N steps, then N steps with -h; return error.
"""
from __future__ import annotations

import mpmath
import numpy as np
import sympy

from ...core.backend import Backend
from ...core.errors import LdasparkError, SingularSaddleError
from ...core.families import get_method
from ...models.scenes import get_scene
from ...core.spark import integrate
from ...core.system import LagrangianSystem

# --- 4. ill-conditioned scenes ------------------------------------------------------------------
def _qv(n):
    return list(sympy.symbols(f"q1:{n + 1}")), list(sympy.symbols(f"v1:{n + 1}"))


def mass_ratio_system(mu):
    """Nonholonomic particle (8.1) with M = diag(1, mu, 1): mass ratio mu."""
    q, v = _qv(3)
    return LagrangianSystem.mechanical_form(sympy.diag(1, sympy.nsimplify(mu), 1), q[0] ** 2 + q[1] ** 2,
                                            [[-q[1], 0, 1]], q=q, v=v, name=f"particle-mu{mu:g}")


def rank_loss_system(eps):
    """k = (v3 - q2 v1, v3 - q2 v1 + eps v2): for every eps != 0 the constraint set is the same
    ({v2 = 0, v3 = q2 v1}), so (q, v) do not depend on eps; K loses rank as eps -> 0."""
    q, v = _qv(3)
    L = sum(x ** 2 for x in v) / 2 - (q[0] ** 2 + q[1] ** 2)
    e = sympy.nsimplify(eps)
    return LagrangianSystem(L, [v[2] - q[1] * v[0], v[2] - q[1] * v[0] + e * v[1]], q, v, name=f"rankK-{eps:g}")


def soft_system():
    """Non-quadratic L = v1^2/2 - v1^4/12 + (v2^2 + v3^2)/2 - (q1^2 + q2^2), k = v3 - q2 v1.
    L_vv = diag(1 - v1^2, 1, 1); (4) fails where 1 - v1^2 + q2^2 = 0 (v1 = +-1 at q2 = 0)."""
    q, v = _qv(3)
    L = v[0] ** 2 / 2 - v[0] ** 4 / 12 + (v[1] ** 2 + v[2] ** 2) / 2 - (q[0] ** 2 + q[1] ** 2)
    return LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="soft")


def _outcome(fn):
    try:
        return "ok", fn()
    except LdasparkError as exc:
        return type(exc).__name__, str(exc)


def _rcond(system, t, q, v):
    bk = Backend()
    S = system.saddle_matrix(bk, t, np.array(q, float), np.array(v, float))
    sv = bk.singular_values(S)
    return float(sv[-1] / sv[0])


def mass_ratio_scene(mus=(1.0, 1e4, 1e8, 1e12, 1e13, 1e16), method="gauss-2", h=0.05, n_steps=40, dps=40):
    """Float64 against the same method in mpmath (same discrete map): error from conditioning.
    v0 = (0, mu^(-1/2), 0) keeps the kinetic energy O(1)."""
    rows = []
    tab = get_method(method)
    for mu in mus:
        sysm = mass_ratio_system(mu)
        q0, v0 = [1.0, 0.0, 0.0], [0.0, float(mu) ** -0.5, 0.0]
        row = {"mu": mu, "rcond": _rcond(sysm, 0.0, q0, v0)}
        st, res = _outcome(lambda: integrate(sysm, tab, 0.0, q0, v0, h, n_steps=n_steps))
        row["outcome"] = st
        if st == "ok":
            ref = integrate(sysm, tab, 0, [mpmath.mpf(x) for x in q0], [mpmath.mpf(x) for x in v0],
                            mpmath.mpf(h), n_steps=n_steps, dps=dps)
            dq = np.abs(res.q.astype(float) - ref.q.astype(float))
            dv = np.abs(res.v.astype(float) - ref.v.astype(float))
            # relative to each component's scale (q2, v2 are O(mu^-1/2))
            sq = np.max(np.abs(ref.q.astype(float)), axis=0) + 1e-300
            sv = np.max(np.abs(ref.v.astype(float)), axis=0) + 1e-300
            row["rel_err"] = float(max(np.max(dq / sq), np.max(dv / sv)))
            row["iterations"] = res.stats["mean_iterations"]
        else:
            row["message"] = res
        rows.append(row)
    return rows


def rank_loss_scene(epss=(1.0, 1e-2, 1e-4, 1e-6, 1e-7, 1e-8), method="gauss-2", h=0.1, n_steps=20):
    """Error in (q, v) against eps = 1 (exact solutions coincide), |psi|, Newton iterations."""
    tab = get_method(method)
    q0, v0 = [1.0, 0.5, 0.0], [0.0, 0.0, 0.0]
    ref = integrate(rank_loss_system(1.0), tab, 0.0, q0, v0, h, n_steps=n_steps)
    rows = []
    for eps in epss:
        sysm = rank_loss_system(eps)
        row = {"eps": eps, "rcond": _rcond(sysm, 0.0, q0, v0)}
        st, res = _outcome(lambda: integrate(sysm, tab, 0.0, q0, v0, h, n_steps=n_steps))
        row["outcome"] = st
        if st == "ok":
            row["err"] = float(max(np.max(np.abs(res.q - ref.q)), np.max(np.abs(res.v - ref.v))))
            row["max_psi"] = float(np.max(np.abs(res.psi)))
            row["iterations"] = res.stats["mean_iterations"]
        else:
            row["message"] = res
        rows.append(row)
    return rows


def saddle_crossings(system, sol):
    """Steps n where det of the saddle matrix (4) changes sign between t_n and t_{n+1}: the
    discrete trajectory jumped across the set where (4) fails (for a scalar m this is exactly
    where the restricted L_vv becomes singular). Empty list = no crossing detected."""
    bk = Backend()
    signs = []
    for t, q, v in zip(sol.t, sol.q, sol.v):
        S = system.saddle_matrix(bk, float(t), np.asarray(q, float), np.asarray(v, float))
        signs.append(np.sign(np.linalg.det(S)))
    return [i for i in range(len(signs) - 1) if signs[i] * signs[i + 1] < 0]


def check_saddle_along(system, sol):
    """Raise SingularSaddleError naming the first step whose trajectory crosses the singular
    set of (4) (a wrong-branch solution of (21) near the limit of assumption (4))."""
    cr = saddle_crossings(system, sol)
    if cr:
        n = cr[0]
        raise SingularSaddleError(
            f"trajectory crosses the singular set of (4) between step {n} (t = {float(sol.t[n]):.6g}) and "
            f"step {n + 1}: the step solved (21) on the wrong branch")
    return None


def soft_scene(deltas=(1e-1, 1e-2, 1e-4, 1e-6, 1e-9, 1e-12, 1e-15, 0.0), method="gauss-2", h=0.01, n_steps=300):
    """Start at v1 = 1 - delta (q2 = 0): the limit of (4) is v1 = 1. Reports the set-up
    reciprocal condition, the outcome, max v1 reached and the first sign change of det(4)."""
    sysm = soft_system()
    tab = get_method(method)
    rows = []
    for d in deltas:
        q0, v0 = [0.0, 0.0, 0.0], [1.0 - d, 0.0, 0.0]
        row = {"delta": d, "rcond": _rcond(sysm, 0.0, q0, v0)}
        st, res = _outcome(lambda: integrate(sysm, tab, 0.0, q0, v0, h, n_steps=n_steps))
        row["outcome"] = st
        if st == "ok":
            row["max_v1"] = float(np.max(res.v[:, 0]))
            row["min_v1"] = float(np.min(res.v[:, 0]))
            cr = saddle_crossings(sysm, res)
            row["crossing_step"] = cr[0] if cr else None
            row["dE"] = float(np.max(np.abs(res.energy - res.energy[0])))
        else:
            row["message"] = res
        rows.append(row)
    return rows


# --- 5. time reversal ------------------------------------------------------------------------
def time_reversal(method, scene="particle", h=0.05, n_steps=100, dps=None):
    """Integrate N steps with h, then N steps with -h from the end; return max error in (q, v)
    against the initial data (and the forward excursion, for scale)."""
    sc = get_scene(scene)
    tab = get_method(method)
    t0, q0, v0 = sc.initial(dps)
    hh = h if dps is None else mpmath.mpf(str(h))
    nw = "full" if dps is None else "mixed"     # mpmath: float64 Newton matrix, same fixed point
    fw = integrate(sc.system, tab, t0, q0, v0, hh, n_steps=n_steps, dps=dps, newton=nw)
    bw = integrate(sc.system, tab, fw.t[-1], fw.q[-1], fw.v[-1], -hh, n_steps=n_steps, dps=dps,
                   check_initial=False, newton=nw)
    with mpmath.workdps(dps or 15):
        err = max(max(abs(a - b) for a, b in zip(bw.q[-1], fw.q[0])), max(abs(a - b) for a, b in zip(bw.v[-1], fw.v[0])))
        excursion = max(abs(a - b) for a, b in zip(fw.q[-1], fw.q[0]))
    return {"method": method, "scene": scene, "h": h, "N": n_steps, "dps": dps, "return_error": float(err),
            "excursion": float(excursion)}
