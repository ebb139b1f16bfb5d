"""Section 2.2: the energy balance dE/dt = -psi^T K(t, q, v) v - L_t(t, q, v), E = L_v v - L (8).

Test systems where energy is not conserved (built here, variations of the nonholonomic
particle of 8.1, L = |v|^2/2 - U, U = q1^2 + q2^2, k = v3 - q2 v1):

* ``time-L``: L = |v|^2/2 - (1 + t/2) U(q) (time-dependent Lagrangian, -L_t = U/2);
* ``affine-b``: k = v3 - q2 v1 + (q1 + sin t)/4 (affine, rheonomic b(t, q): -psi^T K v = psi b);
* ``nonlinear-k``: k = v3 - q2 v1 + v1^2/4 (nonlinear in v: K v = k_v v != k);
* ``rheonomic-linear``: k = v3 - (1 + t/2) q2 v1 (rheonomic but linear in v: K v = k = 0, E is
  conserved although the paper's sufficient condition (scleronomic) does not hold);
* ``particle``: the paper's conservative case (scleronomic, linear, autonomous L).

Exact side: along the exact flow (``exact_flow``) the balance holds pointwise (E_t + E_q v + E_v a
against the right side at the collocation nodes) and integrated (E(t1) - E(t0) against Gauss
quadrature of the right side). Discrete side: along one SPARK step, Delta E = E(t1, q1, v1) -
E(t0, q0, v0) against the stage quadrature h sum_i b_i (-Psi_i^T K_i V_i - L_t(T_i, Q_i, V_i)); the
mismatch is O(h^{p+1}) for a method of order p while Delta E itself is O(h) (not conserved).
"""
from __future__ import annotations

import functools
import math

import mpmath
import numpy as np
import sympy

from ...core.backend import Backend
from ...core.errors import InputError
from ...core.spark import SparkMethod
from ...core.system import LagrangianSystem
from .exact_flow import ExactFlow
from .orders import floor_for

SYSTEMS = ("time-L", "affine-b", "nonlinear-k", "rheonomic-linear", "particle")


@functools.lru_cache(maxsize=None)
def energy_system(name: str):
    """(system, t0, q0, v0 strings) of one of SYSTEMS; v0 is made consistent by projection."""
    if name not in SYSTEMS:
        raise InputError(f"unknown energy test system {name!r}; choose from {', '.join(SYSTEMS)}")
    t = sympy.Symbol("t")
    q = list(sympy.symbols("q1:4"))
    v = list(sympy.symbols("v1:4"))
    U = q[0] ** 2 + q[1] ** 2
    T = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2
    L = T - (1 + t / 2) * U if name == "time-L" else T - U
    k = {"time-L": v[2] - q[1] * v[0], "particle": v[2] - q[1] * v[0],
         "affine-b": v[2] - q[1] * v[0] + (q[0] + sympy.sin(t)) / 4,
         "nonlinear-k": v[2] - q[1] * v[0] + v[0] ** 2 / 4,
         "rheonomic-linear": v[2] - (1 + t / 2) * q[1] * v[0]}[name]
    sysm = LagrangianSystem(L, [k], q, v, t=t, name=name)
    bk = Backend(50)
    with bk.context():
        q0 = [mpmath.mpf(1), mpmath.mpf(1) / 5, mpmath.mpf(0)]
        v0 = sysm.project_velocity(bk, mpmath.mpf(0), q0, [mpmath.mpf(1) / 2, mpmath.mpf(1), mpmath.mpf(0)])
        return sysm, [str(x) for x in q0], [mpmath.nstr(x, 50) for x in v0]


def _fns(sysm):
    """Lambdified E, dE/dt pieces (E_t, E_q, E_v), L_t and K."""
    E = sysm.energy_expr
    args = [sysm.t] + sysm.q + sysm.v
    pieces = [E, sympy.diff(E, sysm.t), [sympy.diff(E, x) for x in sysm.q], [sympy.diff(E, x) for x in sysm.v],
              sysm.L_t, sysm.k_v.tolist()]
    return sympy.lambdify(args, pieces, modules="mpmath")


def rhs_terms(f, t, q, v, psi):
    """(-psi^T K v, -L_t) at one point."""
    _, _, _, _, Lt, K = f(t, *q, *v)
    K = np.array(mpmath.matrix(K).tolist(), dtype=object)
    return -np.asarray(psi).dot(K.dot(np.asarray(v))), -Lt


def exact_balance(name, h="0.1", dps=32, stages=10):
    """Exact side: pointwise max |dE/dt - rhs| at the nodes and |E(t1) - E(t0) - int rhs| (both
    relative to max |dE/dt|, with 1 as floor), the controls without -L_t / without the psi term,
    and |E(t1) - E(t0)| (zero only when energy is conserved)."""
    sysm, q0, v0 = energy_system(name)
    f = _fns(sysm)
    fl = ExactFlow(sysm, dps=dps, stages=stages)
    with mpmath.workdps(dps):
        hh = mpmath.mpf(h)
        q0 = np.array([mpmath.mpf(x) for x in q0], dtype=object)
        v0 = np.array([mpmath.mpf(x) for x in v0], dtype=object)
        q1, v1, nd = fl.ivp(0, q0, v0, hh)
        pw, no_lt, no_psi, rhs_vals, scale = [], [], [], [], mpmath.mpf(1)
        for i in range(fl.s):
            T, Q, V, a, Psi = nd["T"][i], nd["Q"][i], nd["V"][i], nd["a"][i], nd["Psi"][i]
            _, Et, Eq, Ev, _, _ = f(T, *Q, *V)
            dEdt = Et + np.array(Eq, dtype=object).dot(V) + np.array(Ev, dtype=object).dot(a)
            ps, lt = rhs_terms(f, T, Q, V, Psi)
            rhs_vals.append(ps + lt)
            scale = max(scale, abs(dEdt))
            pw.append(abs(dEdt - ps - lt))
            no_lt.append(abs(dEdt - ps))
            no_psi.append(abs(dEdt - lt))
        E0 = f(mpmath.mpf(0), *q0, *v0)[0]
        E1 = f(hh, *q1, *v1)[0]
        integral = abs(E1 - E0 - fl.quad(rhs_vals, hh))
        return {"pointwise": float(max(pw) / scale), "integral": float(integral / scale),
                "without_L_t": float(max(no_lt) / scale), "without_psi_term": float(max(no_psi) / scale),
                "delta_E": float(abs(E1 - E0)), "max_dEdt": float(scale)}


def predicted_mismatch_order(tab) -> int:
    """The order of |Delta E - h sum_i b_i rhs_i| over one step that section 2.2 with the global
    order p of the method predicts: the exact flow satisfies the balance (8) exactly, and one step
    of a method of order p (section 7: Gauss 2s, Lobatto 2s-2, Euler 1) has local error
    O(h^{p+1}) in (q, v) and in the stage quadrature, hence p + 1. A two-sided prediction for the
    tested systems (time-L: L_t != 0, so no cancellation): ``claims_paper.energy_records``."""
    return int(tab.claimed_order) + 1


def discrete_balance(name, tab, hs=("0.2", "0.1", "0.05"), dps=30):
    """One SPARK step from the system's data for each h: |Delta E|, the mismatch
    |Delta E - h sum b_i rhs_i| with stage values, and the control without -L_t; with the
    observed orders (log-log slopes over the last two h). ``floor`` is the round-off plateau of
    these differences of energies, 1e3 eps max(1, |E|) at ``dps`` digits (``orders.floor_for``):
    an order needs both errors of the pair above it, else it is None (a slope of round-off, e.g.
    Gauss on a quadratic E with L_t = 0, is no order)."""
    sysm, q0s, v0s = energy_system(name)
    f = _fns(sysm)
    meth = SparkMethod(sysm, tab, dps=dps)
    bk = meth.backend
    out = {"h": [float(x) for x in hs], "delta_E": [], "mismatch": [], "mismatch_without_L_t": []}
    with bk.context():
        q0, v0 = bk.array(q0s), bk.array(v0s)
        t0 = mpmath.mpf(0)
        E0 = f(t0, *q0, *v0)[0]
        E_scale = abs(E0)
        for hs_ in hs:
            h = mpmath.mpf(hs_)
            r = meth.step(t0, q0, v0, h)
            E1 = f(t0 + h, *r.q1, *r.v1)[0]
            E_scale = max(E_scale, abs(E1))
            quad, quad_nolt = 0, 0
            for i in range(tab.s):
                ps, lt = rhs_terms(f, t0 + meth.tab.c[i] * h, r.Q[i], r.V[i], r.Psi[i])
                quad += meth.tab.b[i] * (ps + lt) * h
                quad_nolt += meth.tab.b[i] * ps * h
            out["delta_E"].append(float(abs(E1 - E0)))
            out["mismatch"].append(float(abs(E1 - E0 - quad)))
            out["mismatch_without_L_t"].append(float(abs(E1 - E0 - quad_nolt)))
    floor = out["floor"] = floor_for(dps, float(E_scale))
    for key in ("delta_E", "mismatch", "mismatch_without_L_t"):
        e = out[key]
        out["order_" + key] = (math.log(e[-2] / e[-1]) / math.log(out["h"][-2] / out["h"][-1])
                               if e[-1] > floor and e[-2] > floor else None)
    return out
