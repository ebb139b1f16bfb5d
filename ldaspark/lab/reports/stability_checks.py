"""Measurements of the stability report, sections 1-3 (plain data, reused by the report in
``ldaspark.lab.reports.stability`` and by tests/lab/reports/test_extremes.py).

* ``step_size_sweep``: one step of (21) from a point of the skate's closed-form solution,
  error against h from 1e-6 up, in float64 and mpmath (30, 50 digits); ``float64_floor_h`` names
  the h below which float64 stops improving; ``newton_limit`` doubles h until Newton fails.
* ``stage_sweep``: coefficient accuracy of the built-in families up to s = 10, residuals of
  B(p), C(q), D(r) and (22b) for the float64 and 50-digit coefficients; ``order_at_precision``
  measures whether the step still reaches its order.
* ``long_run``: 1e6 steps with ``ldaspark.compiled.fast`` (Kahan on / off): constraint residual and
  energy drift; ``roundoff_growth`` fits the round-off growth exponent (sqrt(N) law: 1/2).
"""
from __future__ import annotations

import math
import time

import mpmath
import numpy as np

from ...core.errors import LdasparkError
from ...core.families import get_method
from ...models.scenes import get_scene
from ...core.spark import SparkMethod, integrate

SWEEP_METHODS = ("euler-i", "gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3",
                 "lobatto-iiia-iiib-iiid-3")

# --- 1. step size: error against h, round-off floor, Newton limit ------------------------------
def one_step_error(method, h, dps=None, t0="0.5", scene="skate"):
    """Error max(|q1 - q(t0+h)|, |v1 - v(t0+h)|) of one step from the exact solution at t0.

    The reference is the closed form at max(dps, 15) + 20 digits, so that float64 is measured
    against a reference free of its own round-off."""
    sc = get_scene(scene)
    tab = get_method(method)
    ref_dps = (dps or 15) + 20
    with mpmath.workdps(ref_dps):
        t0m, hm = mpmath.mpf(t0), mpmath.mpf(h)
        qa, va, _ = sc.exact_solution(t0m, ref_dps)
        qb, vb, _ = sc.exact_solution(t0m + hm, ref_dps)
    # at mpmath precision the Newton matrix in float64 ("mixed"): the same fixed point, 3-9x cheaper
    m = SparkMethod(sc.system, tab, dps=dps, newton="mixed")
    if dps is None:
        r = m.step(float(t0m), np.array([float(x) for x in qa]), np.array([float(x) for x in va]), float(hm))
        with mpmath.workdps(ref_dps):
            e = max(max(abs(mpmath.mpf(float(a)) - b) for a, b in zip(r.q1, qb)),
                    max(abs(mpmath.mpf(float(a)) - b) for a, b in zip(r.v1, vb)))
        return float(e), r.iterations
    with mpmath.workdps(dps):
        q0 = np.array([+x for x in qa], dtype=object)
        v0 = np.array([+x for x in va], dtype=object)
        r = m.step(+t0m, q0, v0, +hm)
    with mpmath.workdps(ref_dps):
        e = max(max(abs(a - b) for a, b in zip(r.q1, qb)), max(abs(a - b) for a, b in zip(r.v1, vb)))
    return float(e), r.iterations


def step_size_sweep(methods=SWEEP_METHODS, hs=None, precisions=(None, 30, 50)):
    """Rows {method, order, h, err: {prec: error}} of ``one_step_error``."""
    hs = hs or [f"{10 ** k:.3g}" for k in np.arange(-6, 0.01, 0.5)]   # decimal strings: exact in mpmath
    rows = []
    for name in methods:
        row = {"method": name, "order": get_method(name).claimed_order, "h": [float(h) for h in hs], "err": {}}
        for p in precisions:
            row["err"][str(p or "float64")] = [one_step_error(name, h, p)[0] for h in hs]
        rows.append(row)
    return rows


def float64_floor_h(h, err64, err_ref, factor=4.0):
    """Largest h at which the float64 error exceeds ``factor`` x the reference (round-off-free)
    error: below it float64 has stopped improving (round-off floor)."""
    bad = [hh for hh, a, b in zip(h, err64, err_ref) if a > factor * max(b, 1e-300)]
    return max(bad) if bad else None


def local_order(h, err, lo, hi):
    """Least-squares slope of log err against log h over lo <= h <= hi (local error ~ h^(p+1))."""
    pts = [(math.log(a), math.log(b)) for a, b in zip(h, err) if lo <= a <= hi and b > 0]
    if len(pts) < 2:
        return float("nan")
    x, y = np.array(pts).T
    return float(np.polyfit(x, y, 1)[0])


def newton_limit(method, scene="skate", h0=0.25, h_max=4096.0):
    """Double h from h0 until one step from the scene's initial data fails (NewtonError).
    Returns (largest converged h, first failing h or None, message)."""
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    tab = get_method(method)
    h, ok = h0, None
    while h <= h_max:
        try:
            SparkMethod(sc.system, tab).step(t0, np.array(q0), np.array(v0), h)
        except LdasparkError as exc:
            return ok, h, str(exc)
        ok, h = h, 2 * h
    return ok, None, ""


# --- 2. stage counts up to s = 10 ----------------------------------------------------------------
def _residuals(ent, s, family, dps_eval=80):
    """Max residuals of B(p), C(q), D(r) and (22b) evaluated at ``dps_eval`` digits for the
    entries ``ent`` (dict of numpy arrays: float or mpf)."""
    with mpmath.workdps(dps_eval):
        mp = lambda a: [[mpmath.mpf(x) for x in r] for r in np.asarray(a).reshape(s, -1)]
        c = [mpmath.mpf(x) for x in np.asarray(ent["c"]).reshape(-1)]
        b = [mpmath.mpf(x) for x in np.asarray(ent["b"]).reshape(-1)]
        A, Ah = mp(ent["A"]), mp(ent["A_hat"])
        p = 2 * s if family == "gauss" else 2 * s - 2
        rB = max(abs(sum(b[i] * c[i] ** (k - 1) for i in range(s)) - mpmath.mpf(1) / k) for k in range(1, p + 1))
        rC = max(abs(sum(A[i][j] * c[j] ** (k - 1) for j in range(s)) - c[i] ** k / k)
                 for k in range(1, s + 1) for i in range(s))
        DA = Ah  # D(s) holds for A_hat (Gauss: A_hat = A; Lobatto: IIIB)
        rD = max(abs(sum(b[i] * c[i] ** (k - 1) * DA[i][j] for i in range(s)) - b[j] * (1 - c[j] ** k) / k)
                 for k in range(1, s + 1) for j in range(s))
        r22 = max(abs(b[i] * A[i][j] + b[j] * Ah[j][i] - b[i] * b[j]) for i in range(s) for j in range(s))
        return {"B": float(rB), "C": float(rC), "D": float(rD), "22b": float(r22)}


FAMILIES = (("gauss", "gauss-{s}", 1), ("lobatto", "lobatto-iiia-iiib-{s}", 2),
            ("lobatto", "lobatto-iiia-iiib-iiid-{s}", 2))


def stage_sweep(max_s=10):
    """Rows {method, s, float64: residuals, mp50: residuals}; B(2s) / B(2s-2), C(s) for A,
    D(s) for A_hat, (22b) for (A, A_hat)."""
    rows = []
    for fam, pat, s_min in FAMILIES:
        for s in range(s_min, max_s + 1):
            tab = get_method(pat.format(s=s))
            a64, a50 = tab.arrays(None), tab.arrays(50)
            e64 = {k: getattr(a64, k) for k in ("c", "b", "A", "A_hat")}
            e50 = {k: getattr(a50, k) for k in ("c", "b", "A", "A_hat")}
            rows.append({"method": tab.name, "s": s, "float64": _residuals(e64, s, fam),
                         "mp50": _residuals(e50, s, fam)})
    return rows


def order_at_precision(method, dps=50, t_end="1", Ns=(4, 8)):
    """Global q, v error at t_end on the skate for N steps, and the observed order between the
    N's (None dps = float64). Answers 'does the step still reach its order'."""
    sc = get_scene("skate")
    tab = get_method(method)
    errs = []
    for N in Ns:
        if dps is None:
            t0, q0, v0 = sc.initial()
            sol = integrate(sc.system, tab, t0, q0, v0, float(t_end) / N, n_steps=N)
            qe, ve, _ = sc.exact_solution(float(t_end))
            errs.append(float(max(np.max(np.abs(sol.q[-1] - qe)), np.max(np.abs(sol.v[-1] - ve)))))
        else:
            t0, q0, v0 = sc.initial(dps)
            with mpmath.workdps(dps):
                h = mpmath.mpf(t_end) / N
            sol = integrate(sc.system, tab, t0, q0, v0, h, n_steps=N, dps=dps, newton="mixed")
            qe, ve, _ = sc.exact_solution(t_end, dps + 10)
            with mpmath.workdps(dps + 10):
                errs.append(float(max(max(abs(a - b) for a, b in zip(sol.q[-1], qe)),
                                      max(abs(a - b) for a, b in zip(sol.v[-1], ve)))))
    orders = [math.log(errs[i] / errs[i + 1]) / math.log(Ns[i + 1] / Ns[i]) if min(errs[i], errs[i + 1]) > 0
              else float("nan") for i in range(len(Ns) - 1)]   # float64 can hit exactly 0 at the floor
    return {"method": method, "claimed": tab.claimed_order, "N": list(Ns), "err": errs, "order": orders}


# --- 3. long runs ----------------------------------------------------------------------------------
def long_run(method="gauss-2", scene="particle", h=0.05, n_steps=10 ** 6, every=1000):
    """Float64 long run (fast path if available) with and without Kahan summation.
    Returns max |k|, energy error max over windows [0, 10^j], and the plain-compensated energy gap."""
    sc = get_scene(scene)
    out = {"method": method, "scene": scene, "h": h, "N": n_steps, "every": every}
    try:
        from ...compiled.fast import fast_integrate
    except ImportError:  # pragma: no cover - fast path not installed
        fast_integrate = None
    runs = {}
    for comp in (True, False):
        t = time.perf_counter()
        if fast_integrate is not None:
            r = fast_integrate(sc, method, h=h, n_steps=n_steps, every=every, compensated=comp)
            E, K, path = np.asarray(r.energy), np.asarray(r.constraint), r.stats.get("path", "fast")
        else:
            t0, q0, v0 = sc.initial()
            s = integrate(sc.system, get_method(method), t0, q0, v0, h, n_steps=n_steps)
            E, K, path = np.asarray(s.energy)[::every], np.asarray(s.constraint)[::every], "generic"
        runs[comp] = (E, K)
        out[f"seconds_{'kahan' if comp else 'plain'}"] = time.perf_counter() - t
        out["path"] = path
    E, K = runs[True]
    Ep, Kp = runs[False]
    steps = np.arange(len(E)) * every
    out["max_k"] = {"kahan": float(np.max(np.abs(K))), "plain": float(np.max(np.abs(Kp)))}
    out["E0"] = float(E[0])
    wins = [10 ** j for j in range(3, int(round(math.log10(n_steps))) + 1)]
    out["windows"] = wins
    out["dE_window"] = {"kahan": [float(np.max(np.abs(E[steps <= w] - E[0]))) for w in wins],
                        "plain": [float(np.max(np.abs(Ep[steps <= w] - Ep[0]))) for w in wins]}
    out["plain_minus_kahan"] = [float(np.max(np.abs((Ep - E)[steps <= w]))) for w in wins]
    gap = np.abs(Ep - E)
    sel = (steps >= 10 * every) & (gap > 0)
    # growth exponent of the plain-summation round-off in the energy (random walk: 1/2)
    out["gap_exponent"] = float(np.polyfit(np.log(steps[sel]), np.log(gap[sel]), 1)[0]) if sel.sum() > 2 else float("nan")
    # drift: slope of a straight line through E_n - E_0 (per unit time), second half vs first half means
    half = len(E) // 2
    out["drift_halves"] = {"kahan": float(np.mean(E[half:]) - np.mean(E[:half])),
                           "plain": float(np.mean(Ep[half:]) - np.mean(Ep[:half]))}
    out["series"] = {"steps": steps.tolist(), "dE_kahan": (E - E[0]).tolist(), "dE_plain": (Ep - Ep[0]).tolist(),
                     "k_kahan": np.max(np.abs(K), axis=1).tolist()}
    return out


def roundoff_growth(n_steps=10 ** 6, every=1000, n_ics=8):
    """Round-off error against an exact-arithmetic reference of the same discrete map (linear
    test system of ldaspark.compiled.fast), with and without Kahan; fitted exponent of N."""
    from ...compiled.fast import roundoff_errors
    r = roundoff_errors(n_steps=n_steps, every=every, n_ics=n_ics)
    N = np.array(r["N"], dtype=float)
    fit = {}
    for k, e in r["rms"].items():
        e = np.array(e)
        sel = (N >= 10 * every) & (e > 0)
        fit[k] = float(np.polyfit(np.log(N[sel]), np.log(e[sel]), 1)[0]) if sel.sum() > 2 else float("nan")
    r["exponent"] = fit
    return r
