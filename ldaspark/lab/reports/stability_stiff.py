"""Measurements at the extremes for ``reports/stability.md``: stiff forces, tiny steps along whole runs,
and the regimes table.

* ``linear_stability(method, z)``: the SPARK step (21) on the unconstrained oscillator
  q'' = -omega^2 q is a linear map of (omega q, v) whose 2x2 matrix M(z), z = h omega, comes from
  the tableau: (21a) Q = q0 1 + h A V, (21b) P = V = v0 1 - h omega^2 A_hat Q, (21c)
  q1 = q0 + h b^T V, (21d) v1 = v0 - h omega^2 b_hat^T Q. For A = A_hat (Gauss) its eigenvalues
  are R(i z), R(-i z) with R the stability function of the collocation method, |R(i z)| = 1
  (A-stable, no bound on z); Lobatto IIIA-B (A != A_hat) is Stormer-Verlet for s = 2, stable iff
  z < 2. Stability = spectral radius rho(M(z)) <= 1 (det M = 1 for these symplectic pairs).
* ``stiff_sweep(scene, method, hw)``: whole runs of a stiff nonholonomic oscillator
  (``stiff_scene``: the skate of 8.2 or the particle of 8.1 in the potential
  U = omega^2 |q|^2 / 2 resp. omega^2 (q1^2 + q2^2) / 2) on the compiled engine, for each
  h omega: energy error (bounded or not), Newton iterations per step, fallbacks taken, failure.
* ``tiny_step_run`` / ``error_floor``: whole runs at h = 1e-4 .. 1e-7 and the skate's global
  error against its closed form as h decreases (truncation, then the round-off floor, with and
  without Kahan's compensated summation).
"""
from __future__ import annotations

import functools
import time

import numpy as np
import sympy

from ...core.errors import LdasparkError

OMEGA = 100
HW = (1e-2, 0.1, 0.3, 1.0, 1.9, 2.1, 3.0, 10.0, 30.0, 100.0, 1e3, 1e4)
STIFF_METHODS = ("euler-i", "gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3",
                 "lobatto-iiia-iiib-iiid-2", "lobatto-iiia-iiib-iiid-3")
STIFF_SCENES = ("stiff-skate", "stiff-particle")
N_STIFF = 1000
TINY_H = (1e-4, 1e-5, 1e-6, 1e-7)
TINY_METHODS = ("euler-i", "euler-ii", "gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-2",
                "lobatto-iiia-iiib-3", "lobatto-iiia-iiib-iiid-2", "lobatto-iiia-iiib-iiid-3")
FLOOR_H = (1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6, 3e-7, 1e-7)
FLOOR_T = 0.1


def linear_stability(method, z):
    """(rho(M(z)), |R(i z)| or None): the spectral radius of the step matrix of (21) on the
    oscillator in the variables (omega q, v), and for A = A_hat the modulus of the stability
    function R(i z) = 1 + i z b^T (I - i z A)^-1 1 of the underlying Runge-Kutta method."""
    from ...core.families import get_method
    t = get_method(method).arrays(None)
    A, Ah, b, bh = (np.asarray(x, float) for x in (t.A, t.A_hat, t.b, t.b_hat))
    s = len(b)
    one = np.ones(s)
    # V = v0 1 - z Ah (w0 1 + z A V) with w = omega q, h omega^2 q = z w
    S = np.eye(s) + z * z * Ah @ A
    cols = []
    for w0, v0 in ((1.0, 0.0), (0.0, 1.0)):
        V = np.linalg.solve(S, v0 * one - z * w0 * Ah @ one)
        W = w0 * one + z * A @ V                   # omega Q
        cols.append([w0 + z * b @ V, v0 - z * bh @ W])
    M = np.array(cols).T
    rho = float(max(abs(np.linalg.eigvals(M))))
    R = None
    if np.allclose(A, Ah):
        R = float(abs(1 + 1j * z * b @ np.linalg.solve(np.eye(s) - 1j * z * A, one)))
    return rho, R


@functools.lru_cache(maxsize=None)
def stiff_scene(name, omega=OMEGA):
    """(system, t0, q0, v0): the skate (8.2) or the particle (8.1) in a stiff potential."""
    from ...core.system import LagrangianSystem
    q = list(sympy.symbols("q1:4"))
    v = list(sympy.symbols("v1:4"))
    w2 = sympy.Integer(omega) ** 2
    T = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2
    if name == "stiff-skate":
        L = T - w2 * (q[0] ** 2 + q[1] ** 2 + q[2] ** 2) / 2
        k = [sympy.cos(q[2]) * v[1] - sympy.sin(q[2]) * v[0]]
        q0, v0 = [1.0, 0.0, 0.5], [0.0, 0.0, float(omega) / 2]
        # consistent: k = cos(0.5) 0 - sin(0.5) 0 = 0
    elif name == "stiff-particle":
        L = T - w2 * (q[0] ** 2 + q[1] ** 2) / 2
        k = [v[2] - q[1] * v[0]]
        q0, v0 = [1.0, 0.0, 0.0], [0.0, float(omega), 0.0]
    else:
        raise ValueError(name)
    return LagrangianSystem(L, k, q, v, name=f"{name}-{omega}"), 0.0, q0, v0


def stiff_run(scene, method, hw, n=N_STIFF, omega=OMEGA):
    """One whole run at h = hw / omega on the compiled engine: {outcome, max_rel_dE, dE_growth
    (max |dE| second half / first half), iterations, full_newton_steps, generic_steps}."""
    from ...compiled.fast import fast_integrate
    system, t0, q0, v0 = stiff_scene(scene, omega)
    h = hw / omega
    row = {"scene": scene, "method": method, "hw": hw, "h": h, "N": n}
    try:
        sol = fast_integrate(system, method, t0, q0, v0, h, n, every=1, kernel="spark")
    except LdasparkError as exc:
        row.update(outcome=type(exc).__name__, message=str(exc).splitlines()[0][:160],
                   step=getattr(exc, "step", None))
        return row
    E = np.asarray(sol.energy, float)
    dE = np.abs(E - E[0]) / abs(E[0])
    half = max(len(dE) // 2, 2)
    first, second = float(dE[:half].max()), float(dE[half:].max()) if len(dE) > half else 0.0
    row.update(outcome="ok", max_rel_dE=float(dE.max()), dE_growth=second / first if first > 0 else None,
               max_k=float(np.abs(sol.constraint).max()), iterations=sol.stats["mean_iterations"],
               max_iterations=sol.stats["max_iterations"], full_newton_steps=sol.stats.get("full_newton_steps", 0),
               generic_steps=sol.stats.get("generic_steps", 0))
    return row


#: a run's energy error counts as growing when its maximum over the second half of the run
#: exceeds DE_GROWTH times that over the first half (a linear mode with rho = 1.001 grows by
#: e^1 = 2.7 over N = 1000 steps; a bounded oscillating error keeps the ratio near 1: measured
#: 0.76-1.3 for the Gauss methods at every h omega); errors below 1e-8 are not judged (round-off).
#: DE_BOUND: a failure with the energy error still below it is laid to Newton, not to the method
DE_GROWTH = 4.0
DE_BOUND = 0.5


def classify(row):
    """'bounded' (the energy error does not grow), 'growing', or 'failed' (the run stopped:
    Newton failed on every engine, or NaN/inf)."""
    if row["outcome"] != "ok":
        return "failed"
    g = row.get("dE_growth")
    return "growing" if g is not None and g > DE_GROWTH and row["max_rel_dE"] > 1e-8 else "bounded"


def stiff_sweep(scene, method, hws=HW, n=N_STIFF):
    """The h omega sweep of one method on one stiff scene, each row with its class and the
    linear prediction rho(M(h omega)), |R(i h omega)|."""
    rows = []
    for hw in hws:
        r = stiff_run(scene, method, hw, n)
        r["class"] = classify(r)
        r["rho"], r["R"] = linear_stability(method, hw)
        rows.append(r)
    return rows


def tiny_step_run(scene, method, h, n):
    """A whole run of n steps of h on the compiled engine from the scene's initial data."""
    from ...compiled.fast import fast_integrate
    from ...models.scenes import get_scene
    t = time.perf_counter()
    row = {"scene": scene, "method": method, "h": h, "N": n}
    try:
        sol = fast_integrate(get_scene(scene), method, h=h, n_steps=n, every=max(1, n // 100))
    except LdasparkError as exc:
        row.update(outcome=type(exc).__name__, message=str(exc).splitlines()[0][:160])
        return row
    E = np.asarray(sol.energy, float)
    row.update(outcome="ok", kernel=sol.stats["kernel"], iterations=sol.stats["mean_iterations"],
               full_newton_steps=sol.stats.get("full_newton_steps", 0),
               generic_steps=sol.stats.get("generic_steps", 0), max_k=float(np.abs(sol.constraint).max()),
               max_dE=float(np.abs(E - E[0]).max()), seconds=time.perf_counter() - t)
    return row


def tiny_step_grid(n=100_000, methods=TINY_METHODS, hs=TINY_H, scenes=("particle", "skate", "robot", "mp-particles")):
    return [tiny_step_run(sc, m, h, n) for sc in scenes for m in methods for h in hs]


def _skate_exact(t):
    from ...models.scenes import get_scene
    ex = get_scene("skate").exact
    tt = sympy.Rational(str(t))
    return (np.array([float(e.subs(ex["t"], tt)) for e in ex["q"]]),
            np.array([float(e.subs(ex["t"], tt)) for e in ex["v"]]))


def error_floor(method, hs=FLOOR_H, T=FLOOR_T):
    """Global error max |(q, v)(T) - exact| on the skate for h in hs (N = T / h steps), plain
    and compensated summation, compiled engine: {method, h, N, plain, kahan}."""
    from ...compiled.fast import fast_integrate
    from ...models.scenes import get_scene
    qe, ve = _skate_exact(T)
    out = {"method": method, "h": [], "N": [], "plain": [], "kahan": []}
    for h in hs:
        n = int(round(T / h))
        out["h"].append(h)
        out["N"].append(n)
        for key, comp in (("plain", False), ("kahan", True)):
            sol = fast_integrate(get_scene("skate"), method, h=T / n, n_steps=n, every=n, compensated=comp)
            out[key].append(float(max(np.abs(sol.q[-1] - qe).max(), np.abs(sol.v[-1] - ve).max())))
    return out


def failure_context(row, omega=OMEGA):
    """For a failed stiff run: the energy error of the run up to the step before the failure
    (the evidence for 'method' (the energy had already grown) or 'Newton' (it had not))."""
    k = row.get("step")
    if row["outcome"] == "ok" or not k:
        return None
    before = stiff_run(row["scene"], row["method"], row["hw"], n=k, omega=omega)
    return before.get("max_rel_dE")


def why(row):
    """Why a stiff run is not 'bounded': 'linear instability' (rho(M(h omega)) > 1, the method),
    'energy growth' (rho <= 1, the energy grew anyway: the nonlinear coupling of the constraint,
    the method), 'Newton' (the stage equations were not solved by any engine while the energy
    error was still below DE_BOUND)."""
    if row["class"] == "bounded":
        return ""
    if row["rho"] > 1 + 1e-9:
        return "linear instability"
    if row["class"] == "growing":
        return "energy growth"
    before = row.get("dE_before")
    return "Newton" if before is None or before < DE_BOUND else "energy growth, then Newton"


def stiff_job(scene, method, hws=HW, n=N_STIFF):
    rows = stiff_sweep(scene, method, hws, n)
    for r in rows:
        r["dE_before"] = failure_context(r)
        r["why"] = why(r)
    return rows


def dps_extreme(dpss=(400, 2000), n=3):
    """A few steps of the skate (gauss-2, h = 1/10) at dps beyond float64's exponent range:
    seconds, Newton iterations, and the difference to the run at dps + 40 digits (at the bound
    DPS_MAX, which the API does not exceed, to the run at dps - 40: then the difference measures
    that run's error, and both runs work)."""
    import mpmath
    from ...core.families import get_method
    from ...models.scenes import get_scene
    from ...core.spark import integrate
    from ...core.validate import DPS_MAX
    sc = get_scene("skate")
    out = []
    for dps in dpss:
        t = time.perf_counter()
        t0, q0, v0 = sc.initial(dps)
        a = integrate(sc.system, get_method("gauss-2"), t0, q0, v0, "1/10", n_steps=n, dps=dps)
        sec = time.perf_counter() - t
        ref = dps + 40 if dps + 40 <= DPS_MAX else dps - 40
        t0, q0, v0 = sc.initial(ref)
        b = integrate(sc.system, get_method("gauss-2"), t0, q0, v0, "1/10", n_steps=n, dps=ref)
        with mpmath.workdps(max(dps, ref)):
            d = max(abs(x - y) for x, y in zip(list(a.q[-1]) + list(a.v[-1]), list(b.q[-1]) + list(b.v[-1])))
            log10d = float(mpmath.log10(d)) if d else None
        out.append({"dps": dps, "N": n, "seconds": sec, "iterations": a.stats["mean_iterations"],
                    "log10_diff": log10d, "ref_dps": ref})
    return out
