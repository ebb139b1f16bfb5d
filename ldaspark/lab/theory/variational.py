"""Variational order: L_d - L_d^E and f_d^{+-} - f_d^{E+-} against h.

At (t0, q0, t0 + h, q1) with (q0, v0) the scene's consistent data and q1 = q(t0 + h) of the
exact flow (so the exact boundary-value solution is the solution of (1)), compare Theorem 1's
L_d, f_d^-, f_d^+ (the SPARK boundary-value solve, pinned at the IVP step when it has a gauge)
with the exact L_d^E, f_d^{E-}, f_d^{E+} of ``exact_flow``. Variational error analysis
(Marsden-West; forced version) predicts L_d = L_d^E + O(h^{r+1}) for a method of order r:
local order 2s+1 for Gauss (r = 2s), 2s-1 for Lobatto (r = 2s-2), 2 for Euler.

The forces are compared in full and restricted to variations tangent to the constraint
(f_d^- projected onto ker K(t0, q0, v0), f_d^+ onto ker K(t1, q1, v1)): the SPARK solve imposes
(21e-f) on any endpoints while the exact boundary-value solution carries k(t0, q0, v0) as a first
integral, so the responses to variations normal to the constraint differ at O(1) and only the
tangential parts can converge.
"""
from __future__ import annotations

import functools
import math

import mpmath
import numpy as np

from ...core.backend import Backend
from ...core.families import get_method
from ...models.scenes import get_scene
from ...analysis.discrete import base_point, discrete_lagrangian
from .exact_flow import ExactFlow
from .orders import estimate_order

PREDICTED = {"gauss": lambda s: 2 * s + 1, "lobatto-iiia-iiib": lambda s: 2 * s - 1,
             "lobatto-iiia-iiib-iiid": lambda s: 2 * s - 1}


def predicted_local_order(tab):
    """What variational error analysis predicts for |L_d - L_d^E|: r + 1 with r the global order
    (Marsden-West [6], Theorem 2.3.1, forced version; r from section 7 / [26, 27]: Gauss 2s,
    Lobatto IIIA-B and IIIA-B-D 2s-2; Euler I, II: 1). Pinned per family and s in
    ``verification/test_variational_order.py``; checked two-sided in ``claims_paper``."""
    if tab.family in PREDICTED:
        return PREDICTED[tab.family](tab.s)
    return (tab.claimed_order or 1) + 1


def _nrm(x):
    return float(max((abs(v) for v in np.asarray(x).reshape(-1)), default=0))


def _tangent(system, bk, t, q, v):
    K = np.array(system.saddle_matrix(bk, t, q, v)[system.n:, :system.n], dtype=object)
    KK = mpmath.matrix(K.dot(K.T).tolist())
    return np.eye(system.n, dtype=object) - K.T.dot(np.array(mpmath.inverse(KK).tolist(), dtype=object)).dot(K)


def initial_point(scene_name, point, dps):
    """'base': the scene's data; 'perturbed': the generic consistent point of the ledger."""
    sc = get_scene(scene_name)
    if point == "base":
        return sc.initial(dps)
    from ...analysis.discrete import perturbed_initial
    return perturbed_initial(sc, dps)


@functools.lru_cache(maxsize=None)
def _exact(scene_name, h, dps, stages, point):
    sc = get_scene(scene_name)
    fl = ExactFlow(sc.system, dps=dps, stages=stages)
    with mpmath.workdps(dps):
        t0, q0, v0 = initial_point(scene_name, point, dps)
        q1, _, _ = fl.ivp(t0, q0, v0, mpmath.mpf(h))
        return q1, fl.bvp(t0, q0, t0 + mpmath.mpf(h), q1)


def variational_errors(method, scene_name, hs=("0.2", "0.1", "0.05"), dps=32, stages=10, point="perturbed"):
    """Errors and observed orders (least squares over the h values) of L_d, f_d^-, f_d^+ (full
    and tangential) and of the gauge-invariant p0 + f_d^-, p1 - f_d^+."""
    tab = get_method(method, exact=True) if isinstance(method, str) else method
    sc = get_scene(scene_name)
    S = sc.system
    bk = Backend(dps)
    keys = ("L_d", "f_minus", "f_plus", "f_minus_tangential", "f_plus_tangential", "p0+f_minus", "p1-f_plus")
    err = {k: [] for k in keys}
    with bk.context():
        t0, q0, v0 = initial_point(scene_name, point, dps)
        for h in hs:
            q1, ex = _exact(scene_name, h, dps, stages, point)
            t1 = bk.scalar(t0) + bk.scalar(h)
            _, _, xg = base_point(S, tab, t0, q0, v0, h, dps)
            r = discrete_lagrangian(S, tab, bk.scalar(t0), bk.array(q0), t1, q1, dps=dps, x_guess=xg)
            P0 = _tangent(S, bk, bk.scalar(t0), bk.array(q0), ex.v0)
            P1 = _tangent(S, bk, t1, q1, ex.v1)
            err["L_d"].append(float(abs(r.L_d - ex.L_d)))
            err["f_minus"].append(_nrm(r.f_d_minus - ex.f_d_minus))
            err["f_plus"].append(_nrm(r.f_d_plus - ex.f_d_plus))
            err["f_minus_tangential"].append(_nrm(P0.dot(r.f_d_minus - ex.f_d_minus)))
            err["f_plus_tangential"].append(_nrm(P1.dot(r.f_d_plus - ex.f_d_plus)))
            err["p0+f_minus"].append(_nrm(r.p0 + r.f_d_minus - ex.p0 - ex.f_d_minus))
            err["p1-f_plus"].append(_nrm(r.p1 - r.f_d_plus - ex.p1 + ex.f_d_plus))
    floor = 1e3 * bk.eps
    out = {"method": tab.name, "scene": scene_name, "point": point, "h": [float(x) for x in hs], "errors": err,
           "global_order": tab.claimed_order, "predicted_local_order": predicted_local_order(tab),
           "orders": {}}
    for k in keys:
        if max(err[k]) <= floor:
            out["orders"][k] = math.inf       # zero to working precision at every h
            continue
        est = estimate_order(out["h"], err[k], floor)
        out["orders"][k] = est.observed_order
    return out
