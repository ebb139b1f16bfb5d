"""Observed orders of convergence for q, v and Psi, against an independent reference.

Order estimation (``estimate_order``): from steps h_1 > h_2 > ... and global errors e_j,

* pairwise orders  p_j = log(e_j / e_{j+1}) / log(h_j / h_{j+1});
* the asymptotic window: the longest run of consecutive points that lie above the round-off
  plateau (e > floor) and whose errors strictly decrease with h;
* the observed order: least-squares slope of log e against log h over that window.

References (never the method being measured):

* ``ExactReference``: a scene's closed-form solution (the skate, 8.2);
* ``ODEReference``: the underlying ODE (3a-b) y = (q, v), y' = (v, dv/dt), integrated by
  mpmath's Taylor-series ODE solver (``mpmath.odefun``) at ``dps`` digits, with dense output;
  psi(t) is then the multiplier of (3a-b) at the reference state.

Psi is a stage quantity. What is compared (``psi`` records): the stage multipliers Psi_i of the
LAST step [T - h, T] against the reference psi at the stage times T_i = T - h + c_i h,
error = max_i |Psi_i - psi(T_i)|_inf.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import mpmath
import numpy as np

from ...core.backend import Backend
from ...core.errors import InputError
from ...models.scenes import get_scene
from ...core.spark import integrate
from ...core.families import get_method

VARIABLES = ("q", "v", "psi")


# --- order estimation -------------------------------------------------------------------------
def pairwise_orders(hs, errors):
    """log(e_j / e_{j+1}) / log(h_j / h_{j+1}); None where an error is zero or not finite."""
    out = []
    for j in range(len(hs) - 1):
        e0, e1 = float(errors[j]), float(errors[j + 1])
        if e0 > 0 and e1 > 0 and math.isfinite(e0) and math.isfinite(e1):
            out.append(math.log(e0 / e1) / math.log(float(hs[j]) / float(hs[j + 1])))
        else:
            out.append(None)
    return out


def asymptotic_window(hs, errors, floor):
    """Indices (i0, i1) inclusive of the longest run of consecutive points with e > floor and
    e strictly decreasing as h decreases (hs sorted decreasing); ties go to the smaller h.
    None when no run has two points."""
    ok = [float(e) > floor and math.isfinite(float(e)) for e in errors]
    best = None
    i = 0
    n = len(errors)
    while i < n:
        if not ok[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and ok[j + 1] and float(errors[j + 1]) < float(errors[j]):
            j += 1
        if j > i and (best is None or j - i >= best[1] - best[0]):
            best = (i, j)
        i = j + 1
    return best


@dataclass
class OrderEstimate:
    h: list
    errors: list
    floor: float
    window: tuple | None
    observed_order: float | None
    pairwise_orders: list = field(default_factory=list)


def estimate_order(hs, errors, floor) -> OrderEstimate:
    """LS slope over the asymptotic window plus pairwise orders (hs decreasing)."""
    hs = [float(h) for h in hs]
    if any(hs[j + 1] >= hs[j] for j in range(len(hs) - 1)):
        raise InputError("step sizes must be strictly decreasing")
    errs = [float(e) for e in errors]
    win = asymptotic_window(hs, errs, floor)
    slope = None
    if win is not None:
        x = np.log(hs[win[0]:win[1] + 1])
        y = np.log(errs[win[0]:win[1] + 1])
        slope = float(np.polyfit(x, y, 1)[0])
    return OrderEstimate(hs, errs, floor, win, slope, pairwise_orders(hs, errs))


# --- references -------------------------------------------------------------------------------
class ExactReference:
    """A scene's closed-form solution (q, v, psi)(t)."""

    kind = "exact"

    def __init__(self, scene, dps=40):
        self.scene, self.dps = scene, dps

    def __call__(self, t):
        with mpmath.workdps(self.dps):
            return self.scene.exact_solution(mpmath.mpf(t), dps=self.dps)


class ODEReference:
    """Underlying ODE (3a-b) in mpmath's Taylor solver at ``dps`` digits, dense in t >= t0.
    ``n_rhs`` counts evaluations of (3a-b)."""

    kind = "ode-3ab-taylor"

    def __init__(self, system, t0, q0, v0, dps=40):
        self.system, self.dps = system, dps
        self.bk = Backend(dps)
        self.n = system.n
        self.n_rhs = 0
        with mpmath.workdps(dps):
            y0 = [mpmath.mpf(x) for x in list(q0) + list(v0)]
            self._f = mpmath.odefun(self._rhs, mpmath.mpf(t0), y0)

    def _rhs(self, t, y):
        self.n_rhs += 1
        n = self.n
        q = np.array(y[:n], dtype=object)
        v = np.array(y[n:], dtype=object)
        a, _ = self.system.ode_rhs(self.bk, t, q, v)
        return list(v) + list(a)

    def __call__(self, t):
        n = self.n
        with mpmath.workdps(self.dps):
            y = self._f(mpmath.mpf(t))
            q = np.array(y[:n], dtype=object)
            v = np.array(y[n:], dtype=object)
            _, psi = self.system.ode_rhs(self.bk, mpmath.mpf(t), q, v)
        return q, v, psi


def make_reference(scene, dps=40):
    """Exact solution when the scene has one, else the ODE (3a-b) Taylor reference."""
    if scene.exact is not None:
        return ExactReference(scene, dps)
    t0, q0, v0 = scene.initial(dps)
    return ODEReference(scene.system, t0, q0, v0, dps)


# --- running a method -------------------------------------------------------------------------
def stage_nodes(method_name, dps=None):
    """c of the method whose Psi are compared, or None (no stage times known)."""
    from ...core.comparators import is_comparator
    if method_name.startswith("gauss-irk-"):
        return get_method("gauss-" + method_name.split("-")[-1]).arrays(dps).c
    if is_comparator(method_name):
        return None
    return get_method(method_name).arrays(dps).c


def run_method(method_name, system, t0, q0, v0, h, n_steps, dps=None, newton="full"):
    """A SPARK method by name (``newton`` as in ``integrate``), or a comparator of
    ``ldaspark.core.comparators``."""
    from ...core.comparators import integrate_comparator, is_comparator
    if is_comparator(method_name):
        return integrate_comparator(method_name, system, t0, q0, v0, h, n_steps, dps=dps)
    return integrate(system, get_method(method_name), t0, q0, v0, h, n_steps=n_steps, dps=dps,
                     newton=newton)


def _err(a, b):
    return float(max(abs(x - y) for x, y in zip(list(a), list(b))))


def measure_errors(method_name, scene, reference, t_end, n_list, dps=None, newton="full"):
    """Global errors at t_end for steps h = (t_end - t0)/N, N in n_list (increasing).

    Returns dict with h (strings), errors {q, v, psi}, scales {q, v, psi} (|reference|)."""
    t0, q0, v0 = scene.initial(dps)
    qr, vr, _ = reference(t_end)
    c = stage_nodes(method_name, dps)
    out = {"h": [], "q": [], "v": [], "psi": [], "scale": {}, "stats": []}
    bk = Backend(dps)
    psi_scale = 0.0
    for N in n_list:
        with bk.context():
            h = (bk.scalar(t_end) - bk.scalar(t0)) / N
        sol = run_method(method_name, scene.system, t0, q0, v0, h, N, dps=dps, newton=newton)
        out["h"].append(float(h))
        out["q"].append(_err(sol.q[-1], qr))
        out["v"].append(_err(sol.v[-1], vr))
        if c is not None:
            e = 0.0
            with bk.context():
                t_last = bk.scalar(t_end) - h
                for i in range(len(c)):
                    _, _, pr = reference(t_last + c[i] * h)
                    e = max(e, _err(sol.psi[-1][i], pr))
                    psi_scale = max(psi_scale, float(max(abs(x) for x in pr)))
            out["psi"].append(e)
        out["stats"].append(sol.stats)
    out["scale"] = {"q": float(max(abs(x) for x in qr)), "v": float(max(abs(x) for x in vr)),
                    "psi": psi_scale}
    return out


def floor_for(dps, scale, factor=1e3):
    """Round-off plateau threshold: factor * unit round-off * max(1, |reference|)."""
    return factor * Backend(dps).eps * max(1.0, scale)


def claim_scope(method_name):
    """SPARK claims (7) are per variable (q and v each of order p); the order-reduction claims of
    7.3-7.4 are about the method's order, i.e. min over q and v (a component may do better)."""
    return "method" if method_name.startswith("gauss-irk-") else "variable"


def order_records(method_name, scene_name, claimed, measured, dps, t_end, reference_kind,
                  psi_claimed=None):
    """JSON records (one per variable) from ``measure_errors`` output."""
    recs = []
    for var in VARIABLES:
        errs = measured[var]
        if not errs:
            continue
        est = estimate_order(measured["h"], errs, floor_for(dps, measured["scale"][var]))
        recs.append({
            "method": method_name, "scene": scene_name, "variable": var,
            "claimed_order": claimed if var != "psi" else psi_claimed,
            "claim_scope": claim_scope(method_name),
            "observed_order": est.observed_order, "pairwise_orders": est.pairwise_orders,
            "window": list(est.window) if est.window else None,
            "h": est.h, "errors": est.errors, "floor": est.floor, "dps": dps,
            "t_end": float(t_end), "reference": reference_kind,
            "compared": ("max over stages of the last step of |Psi_i - psi(T - h + c_i h)|"
                         if var == "psi" else f"|{var}_N - {var}(T)|_inf at T = t_end"),
        })
    return recs


def claimed_order_of(method_name):
    """The paper's order claim (7: Gauss 2s, Lobatto 2s-2; 7.3-7.4: standard Gauss IRK 1, 2)."""
    if method_name in ("gauss-irk-1", "gauss-irk-2"):
        return int(method_name[-1])
    from ...core.comparators import is_comparator
    if is_comparator(method_name):
        return None
    return get_method(method_name).claimed_order


def measure_orders(method_name, scene_name, t_end=1.0, n_list=(4, 8, 16, 32), dps=None,
                   reference=None, ref_dps=40, newton="full"):
    """Records for q, v, psi of one method on one scene (see module docstring)."""
    scene = get_scene(scene_name)
    ref = reference if reference is not None else make_reference(scene, ref_dps)
    m = measure_errors(method_name, scene, ref, t_end, list(n_list), dps=dps, newton=newton)
    return order_records(method_name, scene_name, claimed_order_of(method_name), m, dps, t_end, ref.kind)


def verdict(rec, records=None, tol=0.3):
    """'holds' / 'FAILS' / 'NO WINDOW' / 'no claim'; for method-scope claims (7.3-7.4) the
    method order min(q, v) of the same (method, scene) in ``records`` is compared, and an
    order above the claim is 'HIGHER than claimed'."""
    c = rec["claimed_order"]
    if c is None:
        return "no claim"
    o = rec["observed_order"]
    if rec.get("claim_scope") == "method" and records is not None:
        os_ = [r["observed_order"] for r in records if r["method"] == rec["method"]
               and r["scene"] == rec["scene"] and r["variable"] in ("q", "v")]
        o = None if any(x is None for x in os_) else min(os_)
        if o is not None and o > c + tol:
            return "HIGHER than claimed"
    if o is None:
        return "NO WINDOW"
    return "holds" if abs(o - c) <= tol else "FAILS"
