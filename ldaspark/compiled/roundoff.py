"""Round-off study of the compensated summation of the compiled path (GNI VIII.5): the float64
kernels against the same discrete map in mpmath, on a linear test system where the 2-stage
Lobatto IIIA-B SPARK step is a linear map. Used by ``tests/compiled/test_kahan.py``,
``benchmarks/kahan_long_run.py`` and the stability report.
"""
from __future__ import annotations

import numpy as np
import sympy

from .runner import compile_system, run_compiled


def linear_test_system():
    """A linear mechanical system (n = 3, m = 1) on which the 2-stage Lobatto IIIA-B SPARK step
    is a linear map Phi: M = diag(1, 2, 1), U = (q1^2 + 2 q2^2 + 3 q3^2)/2, k = v1 + v2 + v3.
    All coefficients are exact binary numbers, so the float64 and mpmath runs apply the same map."""
    from ..core.system import LagrangianSystem
    q = list(sympy.symbols("q1:4"))
    v = list(sympy.symbols("v1:4"))
    U = (q[0] ** 2 + 2 * q[1] ** 2 + 3 * q[2] ** 2) / 2
    return LagrangianSystem.mechanical_form(sympy.diag(1, 2, 1), U, [[1, 1, 1]], q=q, v=v, name="linear-3")


def growth_exponent(N, err, start_fraction=0.01):
    """Least-squares slope of log err against log N over N >= start_fraction * N_max."""
    N = np.asarray(N, float)
    err = np.asarray(err, float)
    sel = (N >= start_fraction * N[-1]) & (err > 0)
    return float(np.polyfit(np.log(N[sel]), np.log(err[sel]), 1)[0])


def roundoff_errors(n_steps=10 ** 6, every=1000, n_ics=8, h=0.05, dps=40, seed=1):
    """Round-off error of the float64 fast path with and without Kahan summation, against the
    same discrete map in mpmath: Phi (one step of ``SparkMethod`` at ``dps`` digits applied to
    the 2n unit vectors), x_k = (Phi^every)^(k/every) x_0, so that truncation error cancels and
    only round-off is left. Returns {"N": steps, "h": h, "rms": {"compensated": [...], "plain":
    [...]}, "rms_neutral": {...}, "seconds": {...}}: RMS over ``n_ics`` consistent initial data
    of max_i |q_i - q_i^ref|, and of the error along the conserved direction q1 + q2 + q3 (the
    constraint v1 + v2 + v3 = 0 is integrable), where errors can only accumulate."""
    import mpmath
    import time as _time
    from ..core.spark import SparkMethod
    from ..core.families import lobatto_iiia_iiib
    system = linear_test_system()
    n = system.n
    rng = np.random.default_rng(seed)
    Q0 = rng.uniform(-1, 1, (n_ics, n))
    V0 = rng.uniform(-1, 1, (n_ics, n))
    V0[:, 2] = -(V0[:, 0] + V0[:, 1])                   # k = v1 + v2 + v3 = 0
    hm = mpmath.mpf(h)                                  # the exact binary value of the float h
    with mpmath.workdps(dps):
        meth = SparkMethod(system, lobatto_iiia_iiib(2), dps=dps, tol=mpmath.mpf(10) ** (-dps + 3))
        cols = []
        for i in range(2 * n):
            e = [mpmath.mpf(0)] * (2 * n)
            e[i] = mpmath.mpf(1)
            r = meth.step(mpmath.mpf(0), np.array(e[:n], dtype=object), np.array(e[n:], dtype=object), hm)
            cols.append(list(r.q1) + list(r.v1))
        Phi = mpmath.matrix(2 * n, 2 * n)
        for j, col in enumerate(cols):
            for i in range(2 * n):
                Phi[i, j] = col[i]
        B = Phi ** every
        refs = []
        for k in range(n_ics):
            x = mpmath.matrix([mpmath.mpf(float(a)) for a in list(Q0[k]) + list(V0[k])])
            traj = []
            for _ in range(n_steps // every):
                x = B * x
                traj.append([x[i] for i in range(n)])
            refs.append(np.array([[float(a) for a in row] for row in traj]))
    cs = compile_system(system)
    out = {"N": [every * (k + 1) for k in range(n_steps // every)], "h": h, "rms": {}, "rms_neutral": {},
           "seconds": {}}
    for label, comp in (("compensated", True), ("plain", False)):
        errs = []
        t = _time.perf_counter()
        for k in range(n_ics):
            r = run_compiled(cs, "lobatto-iiia-iiib-2", 0.0, Q0[k], V0[k], h, n_steps, every, comp)
            errs.append(r.q[1:] - refs[k])
        out["seconds"][label] = _time.perf_counter() - t
        errs = np.array(errs)                               # (ics, samples, n)
        out["rms"][label] = np.sqrt(np.mean(np.max(np.abs(errs), axis=2) ** 2, axis=0)).tolist()
        neutral = errs.sum(axis=2) / np.sqrt(n)
        out["rms_neutral"][label] = np.sqrt(np.mean(neutral ** 2, axis=0)).tolist()
    return out
