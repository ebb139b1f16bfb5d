"""Definition 1 along trajectories: the nonholonomically constrained discrete Euler-Lagrange
equations (15a-b) at every interior point of an IVP trajectory q_0, ..., q_N of a SPARK method.

For each interval [t_k, t_{k+1}] the boundary-value solve of ``discrete`` (Theorem 1's implicit
functions of (t_k, q_k, t_{k+1}, q_{k+1}), pinned at the IVP step when the solve has a gauge)
gives L_d, f_d^-, f_d^+ as printed in Theorem 1; the partial derivatives
D2 L_d = dL_d/dq_k and D4 L_d = dL_d/dq_{k+1} are central differences of that solve
(Richardson over delta, delta/2), never the identities of Theorem 1. Then for k = 1..N-1

    (15a)  D4 L_d(t_{k-1}, q_{k-1}, t_k, q_k) + D2 L_d(t_k, q_k, t_{k+1}, q_{k+1})
           + f_d^+(t_{k-1}, q_{k-1}, t_k, q_k) + f_d^-(t_k, q_k, t_{k+1}, q_{k+1}) = 0,
    (15b)  c(t_{k-1}, q_{k-1}, t_k, q_k) = c(t_k, q_k, t_{k+1}, q_{k+1}) = 0,

with c(t_k, q_k, t_{k+1}, q_{k+1}) = k(t_{k+1}, q_{k+1}, u(t_{k+1})), u(t_{k+1}) = v1 of the solve
((21f)). Controls: the force-free sum D4 + D2 (what a variational integrator would need), and
c with the secant velocity (q_{k+1} - q_k)/h for u.
"""
from __future__ import annotations

import time

import mpmath
import numpy as np

from ...core.backend import Backend
from ...analysis.discrete import DiscreteBVP, _Solver, base_point, discrete_lagrangian


def _nrm(x):
    return float(max((abs(v) for v in np.asarray(x).reshape(-1)), default=0))


def _fd_gradient(bvp, res, t0, q0, t1, q1, delta):
    """(dL_d/dq0, dL_d/dq1) by Richardson-extrapolated central differences of the BVP."""
    sol = _Solver(bvp)
    gauge, fac = res.extra["gauge"], res.extra["fac"]
    dxdq = res.extra["dx_dq"][:bvp.size]
    n = bvp.n
    out = []
    for k in range(2 * n):
        def L_at(eps):
            qa, qb = q0.copy(), q1.copy()
            (qa if k < n else qb)[k % n] += eps
            xs, _, _, _ = sol.newton(t0, qa, t1, qb, res.x + dxdq[:, k] * eps, gauge, fac=fac)
            return bvp.L_d_only(t0, qa, t1, qb, xs)
        D = [(L_at(d) - L_at(-d)) / (2 * d) for d in (delta, delta / 2)]
        out.append((4 * D[1] - D[0]) / 3)
    g = np.array(out, dtype=object)
    return g[:n], g[n:]


def definition1_residuals(system, tableau, t0, q0, v0, h, n_steps=10, dps=30):
    """Residuals of (15a) (relative to max |p_k|) and (15b) (|c| / (1 + |v|)) for k = 1..N-1
    along the IVP trajectory from (t0, q0, v0); the working precision is ``dps`` + 20 so the
    finite differences (delta = 10^-(dps/2 - 3)) resolve the ``dps``-digit claim."""
    t_start = time.time()
    dps_fd = dps + 20
    bk = Backend(dps_fd)
    bvp = DiscreteBVP(system, tableau, dps_fd)
    delta = mpmath.mpf(10) ** (-(dps // 2 - 3))
    with bk.context():
        t, q, v = bk.scalar(t0), bk.array(q0), bk.array(v0)
        h = bk.scalar(h)
        per = []
        classes = set()
        for _ in range(n_steps):
            t1, q1, xg = base_point(system, tableau, t, q, v, h, dps_fd)
            r = discrete_lagrangian(system, tableau, t, q, t1, q1, dps=dps_fd, x_guess=xg)
            classes.add(r.wellposed)
            g0, g1 = _fd_gradient(bvp, r, t, q, t1, q1, delta)
            c = system.constraint(bk, t1, q1, r.v1)
            c_sec = system.constraint(bk, t1, q1, (q1 - q) / h)
            # control: c at the left end point k(t_k, q_k, v0 of the solve); 0 as well on C_d, so
            # only a run from inconsistent data (k(t0, q0, v0) != 0) tells the two ends apart
            c_left = system.constraint(bk, t, q, r.v0)
            per.append({"D2": g0, "D4": g1, "fm": r.f_d_minus, "fp": r.f_d_plus, "p0": r.p0, "p1": r.p1,
                        "c": _nrm(c) / (1 + _nrm(r.v1)), "c_secant": _nrm(c_sec), "c_left": _nrm(c_left), "mu": r.mu_norm})
            v = bvp.unpack(xg)[2]            # v1 of the IVP step: consistent data for the next step
            t, q = t1, q1
        res15a, free, scale = [], [], 0.0
        for k in range(1, n_steps):
            a, b = per[k - 1], per[k]
            sc = max(_nrm(a["p1"]), _nrm(b["p0"]), 1e-300)
            scale = max(scale, sc)
            res15a.append(_nrm(a["D4"] + b["D2"] + a["fp"] + b["fm"]) / sc)
            free.append(_nrm(a["D4"] + b["D2"]) / sc)
    return {"15a": max(res15a), "15a_per_k": res15a, "15a_without_forces": max(free),
            "15b": max(p["c"] for p in per), "15b_secant": max(p["c_secant"] for p in per),
            "15b_left_end": max(p["c_left"] for p in per),
            "f_scale": max(max(_nrm(p["fm"]), _nrm(p["fp"])) for p in per),
            "mu": max(p["mu"] for p in per), "wellposed": "/".join(sorted(classes)),
            "n_steps": n_steps, "dps": dps, "seconds": time.time() - t_start}
