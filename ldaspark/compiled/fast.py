"""Compiled float64 fast path (numba) for systems in mechanical form.

Mechanical form (section 7): L = 1/2 v^T M v - U(t, q) with constant M, k = K(t, q) v + b(t, q).
The parts M, U, K, b are taken from ``system.mechanical`` or detected from L and k with sympy
(L_vv constant, grad_v L = M v, k_vv = 0). From them the scene's sympy expressions are printed
to Python source (``sympy.cse`` + ``PythonCodePrinter``), written once to a cache file together
with the generic kernels below and compiled with ``numba.njit(cache=True)``; the same file is
loaded by worker processes (``ldaspark.compiled.ensemble``) or rebuilt from its source text on a remote
worker.

Kernels (all work on increments, so that the q and p updates can be summed with Kahan's
compensated summation, GNI VIII.5):

* ``spark_run``: any SPARK tableau (21a-f); unknowns Z_i = V_i - v0, Lambda_i = h Psi_i,
  dv = v1 - v0; P_i - p0 = M Z_i exactly for constant M.
* ``lf2_run``: the 2-stage Lobatto IIIA-B SPARK method in its semi-implicit form (25)
  (variant 0), the modified method of 8.4 (variant 1, constraint k(t0 + h/2, q0 + h/2 V1, V1) = 0)
  and McLachlan-Perlmutter's Lobatto IIIB-A method (26) (variant 2). Newton runs only on the m
  multipliers; grad U is evaluated once per step (twice for (25)).

Newton: predictor = linear extrapolation of the previous two steps' unknowns (first step: zero
increments), simplified Newton with one LU factorisation per step reused by every iteration,
stopping when |dx|_inf, or the estimate theta/(1 - theta) |dx|_inf of the remaining error
(theta = contraction of the last two increments), is <= tol (|x|_inf + h (1 + |v0|_inf)) (the
unknowns are increments of size O(h), so this is a relative test on them), or when the increments
stagnate at round-off level (same rule as ``SparkMethod.step``); tol defaults to 8 unit round-offs. Counters: steps,
newton_iterations, nfev (stage points evaluated), njev, nlu, max_iterations.

Where a system cannot be compiled (not in mechanical form, or an expression numba cannot
compile) ``fast_integrate`` prints one line ``ldaspark.compiled.fast: ... falling back to the generic
path`` to stderr and runs ``ldaspark.core.spark.integrate`` / ``ldaspark.core.comparators``.
"""
from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
from dataclasses import dataclass

import numpy as np
import sympy
from sympy.printing.pycode import PythonCodePrinter

from ..core.errors import InputError, LdasparkError, NewtonError

__all__ = ["fast_integrate", "FastSolution", "compile_system", "CompiledSystem", "mechanical_parts",
           "kernel_spec", "run_compiled", "generic_integrate", "FAST_METHODS", "NotCompilableError"]

# comparator names with a specialised kernel: name -> lf2 variant
LF2_VARIANTS = {
    "lobatto-iiia-iiib-2-leapfrog": 0,
    "lobatto-iiia-iiib-2-modified": 1,
    "lobatto-iiia-iiib-2-modified-leapfrog": 1,
    "mp-lobatto-iiib-a-2": 2,
}
FAST_METHODS = ("any SPARK tableau (gauss-S, lobatto-iiia-iiib-S, lobatto-iiia-iiib-iiid-S, euler-i, euler-ii)",
                ) + tuple(LF2_VARIANTS)
STAT_NAMES = ("steps", "newton_iterations", "nfev", "njev", "nlu", "max_iterations", "failed_step")


class NotCompilableError(LdasparkError):
    """The system cannot be put through the compiled fast path."""


# --- mechanical form ---------------------------------------------------------------------
def mechanical_parts(system) -> dict:
    """(M, U, K, b) as sympy objects with L = 1/2 v^T M v - U, k = K v + b, M constant.

    Uses ``system.mechanical`` when set, else detects the form: L_vv free of t, q, v;
    grad_v L - M v = 0 (no gyroscopic terms); k_v free of v. Raises NotCompilableError."""
    if getattr(system, "N", None) is not None:
        raise NotCompilableError(f"{system.name}: nonideal constraint term (3.3) is not compiled")
    q, v, t = list(system.q), list(system.v), system.t
    mech = system.mechanical
    if mech is not None:
        M = sympy.Matrix(mech["M"])
        U = sympy.sympify(mech["U"])
        K = sympy.Matrix(mech["K"])
        b = sympy.Matrix(mech.get("b") if mech.get("b") is not None else sympy.zeros(K.rows, 1))
        b = b.reshape(K.rows, 1)
    else:
        M = system.L_vv
        if M.free_symbols & (set(q) | set(v) | {t}):
            raise NotCompilableError(f"{system.name}: L_vv depends on (t, q, v); not mechanical form")
        zero_v = {x: 0 for x in v}
        gyro = (system.L_v - M * sympy.Matrix(v)).applyfunc(sympy.simplify)
        if gyro != sympy.zeros(system.n, 1):
            raise NotCompilableError(f"{system.name}: grad_v L is not M v (terms linear in v); not mechanical form")
        U = -system.L.subs(zero_v)
        K = system.k_v
        if K.free_symbols & set(v):
            raise NotCompilableError(f"{system.name}: k is not affine in v; not mechanical form")
        b = system.k.subs(zero_v)
    if M.free_symbols:
        raise NotCompilableError(f"{system.name}: mass matrix M is not constant")
    return {"M": M, "U": U, "K": K, "b": b}


# --- code generation ---------------------------------------------------------------------
class _Printer(PythonCodePrinter):
    def _print_Rational(self, expr):          # float literals, never integer division surprises
        return f"({float(expr.p)!r}/{float(expr.q)!r})"


def _emit(name, args, unpack, outputs, printer):
    """Source of one njit function computing ``outputs`` = [(target, expr)] after CSE."""
    exprs = [e for _, e in outputs]
    reps, red = sympy.cse(exprs, symbols=sympy.numbered_symbols("_x"), optimizations="basic")
    lines = ["@numba.njit(cache=True)", f"def {name}({', '.join(args)}):"]
    lines += [f"    {a} = {b}" for a, b in unpack]
    for s, e in reps:
        lines.append(f"    {s} = {printer.doprint(e)}")
    for (target, _), e in zip(outputs, red):
        lines.append(f"    {target} = {printer.doprint(e)}")
    if len(outputs) == 1 and outputs[0][0] == "_r":
        lines.append("    return _r")
    return "\n".join(lines)


def _model_source(system, parts):
    q, v, t = list(system.q), list(system.v), system.t
    n, m = system.n, parts["K"].rows
    tq = [sympy.Symbol(f"_q{i}", real=True) for i in range(n)]
    tv = [sympy.Symbol(f"_v{i}", real=True) for i in range(n)]
    tl = [sympy.Symbol(f"_l{i}", real=True) for i in range(m)]
    tt = sympy.Symbol("_t", real=True)
    sub = dict(zip(q, tq)) | dict(zip(v, tv)) | {t: tt}
    U = sympy.sympify(parts["U"]).subs(sub)
    K = sympy.Matrix(parts["K"]).subs(sub)
    b = sympy.Matrix(parts["b"]).subs(sub)
    if K.free_symbols & set(tv) or b.free_symbols & set(tv) or U.free_symbols & set(tv):
        raise NotCompilableError(f"{system.name}: U, K or b depend on v")
    gU = [sympy.diff(U, x) for x in tq]
    H = [[sympy.diff(g, x) for x in tq] for g in gU]
    kvec = K * sympy.Matrix(tv) + b
    kq = kvec.jacobian(tq)
    KTl = K.T * sympy.Matrix(tl)
    KTl_q = KTl.jacobian(tq)
    pr = _Printer({"fully_qualified_modules": True})
    uq = [("_t", "t")] + [(f"_q{i}", f"q[{i}]") for i in range(n)]
    uv = [(f"_v{i}", f"v[{i}]") for i in range(n)]
    ul = [(f"_l{i}", f"lam[{i}]") for i in range(m)]
    fns = [
        _emit("U_of", ["t", "q"], uq, [("_r", U)], pr),
        _emit("grad_U", ["t", "q", "out"], uq, [(f"out[{i}]", gU[i]) for i in range(n)], pr),
        _emit("hess_U", ["t", "q", "out"], uq, [(f"out[{i}, {j}]", H[i][j]) for i in range(n) for j in range(n)], pr),
        _emit("K_of", ["t", "q", "out"], uq, [(f"out[{i}, {j}]", K[i, j]) for i in range(m) for j in range(n)], pr),
        _emit("b_of", ["t", "q", "out"], uq, [(f"out[{i}]", b[i]) for i in range(m)], pr),
        _emit("kq_of", ["t", "q", "v", "out"], uq + uv,
              [(f"out[{i}, {j}]", kq[i, j]) for i in range(m) for j in range(n)], pr),
        _emit("KTlam_q", ["t", "q", "lam", "out"], uq + ul,
              [(f"out[{i}, {j}]", KTl_q[i, j]) for i in range(n) for j in range(n)], pr),
    ]
    src = "\n\n\n".join(fns)
    if "Not supported" in src:
        raise NotCompilableError(f"{system.name}: an expression has no Python/numba translation")
    return src


_HEADER = '''"""Generated by ldaspark.compiled.fast for system {name!r} (n = {n}, m = {m}). Do not edit."""
import math
import numba
import numpy as np

N_DOF = {n}
N_CON = {m}
'''

# The kernels: plain loops, float64, written once against the model functions above them.
_KERNELS = r'''

@numba.njit(cache=True)
def lu_factor(A, piv):
    """In-place LU with partial pivoting (LAPACK getrf order); False if singular."""
    n = A.shape[0]
    dmax = 0.0
    dmin = np.inf
    for k in range(n):
        p = k
        amax = abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > amax:
                amax = abs(A[i, k])
                p = i
        piv[k] = p
        if not (amax > 0.0) or not np.isfinite(amax):
            return False
        dmax = max(dmax, amax)
        dmin = min(dmin, amax)
        if p != k:
            for j in range(n):
                tmp = A[k, j]
                A[k, j] = A[p, j]
                A[p, j] = tmp
        inv = 1.0 / A[k, k]
        for i in range(k + 1, n):
            A[i, k] *= inv
            f = A[i, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= f * A[k, j]
    return dmin > 1e-13 * dmax


@numba.njit(cache=True)
def lu_solve(LU, piv, b):
    n = LU.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
    for i in range(n):
        s = b[i]
        for j in range(i):
            s -= LU[i, j] * b[j]
        b[i] = s
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= LU[i, j] * b[j]
        b[i] = s / LU[i, i]


@numba.njit(cache=True)
def add_to(x, c, inc, compensated):
    """x += inc; with compensated summation the low-order bits lost are kept in c (Kahan)."""
    for i in range(x.shape[0]):
        if compensated:
            a = inc[i] + c[i]
            b = x[i]
            x[i] = b + a
            c[i] = (b - x[i]) + a
        else:
            x[i] += inc[i]


@numba.njit(cache=True)
def norm_inf(x):
    r = 0.0
    for i in range(x.shape[0]):
        a = abs(x[i])
        if a > r or a != a:
            r = a
    return r


@numba.njit(cache=True)
def energy_constraint(t, q, v, M, kK, kb, kout):
    """E = 1/2 v^T M v + U (8) and k = K v + b at one point."""
    e = 0.0
    n = q.shape[0]
    for a in range(n):
        s = 0.0
        for b in range(n):
            s += M[a, b] * v[b]
        e += 0.5 * v[a] * s
    e += U_of(t, q)
    K_of(t, q, kK)
    b_of(t, q, kb)
    for l in range(kK.shape[0]):
        s = kb[l]
        for a in range(n):
            s += kK[l, a] * v[a]
        kout[l] = s
    return e


@numba.njit(cache=True)
def store(j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, kK, kb, kout):
    out_t[j] = t
    for a in range(q.shape[0]):
        out_q[j, a] = q[a]
        out_v[j, a] = v[a]
    out_E[j] = energy_constraint(t, q, v, M, kK, kb, kout)
    for l in range(kout.shape[0]):
        out_k[j, l] = kout[l]


@numba.njit(cache=True)
def converged(dn, prev, xn, floor, tol):
    """Increment test: |dx| <= lim, or the error estimate theta/(1 - theta) |dx| <= lim of the
    linearly converging simplified Newton (theta = |dx_k| / |dx_k-1|, Hairer-Wanner IV.8), or the
    round-off floor of SparkMethod.step (increments stopped shrinking at noise level)."""
    lim = tol * (xn + floor)
    if dn <= lim:
        return True
    if prev <= 0.0:
        return False
    theta = dn / prev
    if theta < 0.5 and theta / (1.0 - theta) * dn <= lim:
        return True
    return dn >= 0.5 * prev and dn <= 1e3 * lim


@numba.njit(cache=True)
def spark_eval(jac, x, t0, q0, v0, h, c, A, Ah, At, bw, bh, bt, om, M, s, n, m,
               T, Q, V, gU, KTL, KK, bb, kst, H, Rq, kq, q1, v1, K1, b1, kq1, G, J):
    """Residual G of (21b, d, e, f) in the increment unknowns x = [Z | Lambda | dv] and, if jac,
    its Jacobian J. gU = grad U = -F, KTL_j = K_j^T Lambda_j = -h R_j."""
    sn = s * n
    sm = s * m
    t1 = t0 + h
    for i in range(s):
        T[i] = t0 + c[i] * h
        for a in range(n):
            V[i, a] = v0[a] + x[i * n + a]
    for i in range(s):
        for a in range(n):
            acc = 0.0
            for j in range(s):
                acc += A[i, j] * V[j, a]
            Q[i, a] = q0[a] + h * acc
    for a in range(n):
        acc = 0.0
        for j in range(s):
            acc += bw[j] * V[j, a]
        q1[a] = q0[a] + h * acc
        v1[a] = v0[a] + x[sn + sm + a]
    for j in range(s):
        grad_U(T[j], Q[j], gU[j])
        K_of(T[j], Q[j], KK[j])
        b_of(T[j], Q[j], bb[j])
        for a in range(n):
            acc = 0.0
            for l in range(m):
                acc += KK[j, l, a] * x[sn + j * m + l]
            KTL[j, a] = acc
        for l in range(m):
            acc = bb[j, l]
            for a in range(n):
                acc += KK[j, l, a] * V[j, a]
            kst[j, l] = acc
    K_of(t1, q1, K1)
    b_of(t1, q1, b1)
    # (21b): M Z_i + h sum_j A^_ij grad U_j + sum_j A~_ij K_j^T Lambda_j
    for i in range(s):
        for a in range(n):
            acc = 0.0
            for b in range(n):
                acc += M[a, b] * x[i * n + b]
            acc2 = 0.0
            acc3 = 0.0
            for j in range(s):
                acc2 += Ah[i, j] * gU[j, a]
                acc3 += At[i, j] * KTL[j, a]
            G[i * n + a] = acc + h * acc2 + acc3
    # (21d)
    for a in range(n):
        acc = 0.0
        for b in range(n):
            acc += M[a, b] * x[sn + sm + b]
        acc2 = 0.0
        acc3 = 0.0
        for j in range(s):
            acc2 += bh[j] * gU[j, a]
            acc3 += bt[j] * KTL[j, a]
        G[sn + a] = acc + h * acc2 + acc3
    # (21e)
    re0 = sn + n
    for l in range(s - 1):
        for mm in range(m):
            acc = 0.0
            for j in range(s):
                acc += om[l, j] * kst[j, mm]
            G[re0 + l * m + mm] = acc
    # (21f)
    rf0 = re0 + (s - 1) * m
    for mm in range(m):
        acc = b1[mm]
        for a in range(n):
            acc += K1[mm, a] * v1[a]
        G[rf0 + mm] = acc
    if not jac:
        return
    for j in range(s):
        hess_U(T[j], Q[j], H[j])
        KTlam_q(T[j], Q[j], x[sn + j * m:sn + (j + 1) * m], Rq[j])
        kq_of(T[j], Q[j], V[j], kq[j])
    kq_of(t1, q1, v1, kq1)
    NN = J.shape[0]
    for r in range(NN):
        for cc in range(NN):
            J[r, cc] = 0.0
    h2 = h * h
    for i in range(s):
        for k in range(s):
            for a in range(n):
                for b in range(n):
                    acc = M[a, b] if i == k else 0.0
                    for j in range(s):
                        acc += h2 * Ah[i, j] * A[j, k] * H[j, a, b] + h * At[i, j] * A[j, k] * Rq[j, a, b]
                    J[i * n + a, k * n + b] = acc
            for a in range(n):
                for l in range(m):
                    J[i * n + a, sn + k * m + l] = At[i, k] * KK[k, l, a]
    for k in range(s):
        for a in range(n):
            for b in range(n):
                acc = 0.0
                for j in range(s):
                    acc += h2 * bh[j] * A[j, k] * H[j, a, b] + h * bt[j] * A[j, k] * Rq[j, a, b]
                J[sn + a, k * n + b] = acc
            for l in range(m):
                J[sn + a, sn + k * m + l] = bt[k] * KK[k, l, a]
    for a in range(n):
        for b in range(n):
            J[sn + a, sn + sm + b] = M[a, b]
    for l in range(s - 1):
        for mm in range(m):
            for k in range(s):
                for b in range(n):
                    acc = om[l, k] * KK[k, mm, b]
                    for j in range(s):
                        acc += h * om[l, j] * A[j, k] * kq[j, mm, b]
                    J[re0 + l * m + mm, k * n + b] = acc
    for mm in range(m):
        for k in range(s):
            for b in range(n):
                J[rf0 + mm, k * n + b] = h * bw[k] * kq1[mm, b]
        for b in range(n):
            J[rf0 + mm, sn + sm + b] = K1[mm, b]


@numba.njit(cache=True, nogil=True)
def spark_run(c, A, Ah, At, bw, bh, bt, om, M, t0, q0, v0, h, n_steps, every, compensated, tol,
              max_iter, predictor, out_t, out_q, out_v, out_E, out_k, out_x, stats):
    """n_steps of the SPARK method (21) from (t0, q0, v0); samples every ``every`` steps and
    the last step. out_x receives the last step's unknowns. stats: see STAT_NAMES."""
    s = A.shape[0]
    n = q0.shape[0]
    m = out_k.shape[1]
    sn = s * n
    sm = s * m
    NN = sn + sm + n
    T = np.zeros(s)
    Q = np.zeros((s, n))
    V = np.zeros((s, n))
    gU = np.zeros((s, n))
    KTL = np.zeros((s, n))
    KK = np.zeros((s, m, n))
    bb = np.zeros((s, m))
    kst = np.zeros((s, m))
    H = np.zeros((s, n, n))
    Rq = np.zeros((s, n, n))
    kq = np.zeros((s, m, n))
    q1 = np.zeros(n)
    v1 = np.zeros(n)
    K1 = np.zeros((m, n))
    b1 = np.zeros(m)
    kq1 = np.zeros((m, n))
    G = np.zeros(NN)
    J = np.zeros((NN, NN))
    piv = np.zeros(NN, dtype=np.int64)
    x = np.zeros(NN)
    x_last = np.zeros(NN)
    x_prev = np.zeros(NN)
    dq = np.zeros(n)
    dv = np.zeros(n)
    kK = np.zeros((m, n))
    kb = np.zeros(m)
    kout = np.zeros(m)
    q = q0.copy()
    v = v0.copy()
    cq = np.zeros(n)
    cv = np.zeros(n)
    stats[6] = -1
    store(0, t0, q, v, M, out_t, out_q, out_v, out_E, out_k, kK, kb, kout)
    j_out = 1
    for step in range(n_steps):
        t = t0 + step * h
        if step >= 2 and predictor == 2:
            for r in range(NN):
                x[r] = 2.0 * x_last[r] - x_prev[r]
        elif step >= 1 and predictor >= 1:
            for r in range(NN):
                x[r] = x_last[r]
        else:
            for r in range(NN):
                x[r] = 0.0
        spark_eval(True, x, t, q, v, h, c, A, Ah, At, bw, bh, bt, om, M, s, n, m,
                   T, Q, V, gU, KTL, KK, bb, kst, H, Rq, kq, q1, v1, K1, b1, kq1, G, J)
        stats[2] += 2 * s + 1
        stats[3] += 1
        ok = lu_factor(J, piv)
        stats[4] += 1
        if not ok:
            stats[6] = step
            return
        floor = abs(h) * (1.0 + norm_inf(v))
        prev = -1.0
        it = 0
        done = False
        while it < max_iter:
            it += 1
            for r in range(NN):
                G[r] = -G[r]
            lu_solve(J, piv, G)
            for r in range(NN):
                x[r] += G[r]
            dn = norm_inf(G)
            if not np.isfinite(dn):
                break
            if converged(dn, prev, norm_inf(x), floor, tol):
                done = True
                break
            prev = dn
            spark_eval(False, x, t, q, v, h, c, A, Ah, At, bw, bh, bt, om, M, s, n, m,
                       T, Q, V, gU, KTL, KK, bb, kst, H, Rq, kq, q1, v1, K1, b1, kq1, G, J)
            stats[2] += s + 1
        stats[1] += it
        if it > stats[5]:
            stats[5] = it
        if not done:
            stats[6] = step
            return
        # q1 - q0 = h sum_j b_j (v0 + Z_j); v1 - v0 = dv
        sb = 0.0
        for j in range(s):
            sb += bw[j]
        for a in range(n):
            acc = 0.0
            for j in range(s):
                acc += bw[j] * x[j * n + a]
            dq[a] = h * (sb * v[a] + acc)
            dv[a] = x[sn + sm + a]
        add_to(q, cq, dq, compensated)
        add_to(v, cv, dv, compensated)
        for r in range(NN):
            x_prev[r] = x_last[r]
            x_last[r] = x[r]
        stats[0] += 1
        if (step + 1) % every == 0 or step + 1 == n_steps:
            store(j_out, t0 + (step + 1) * h, q, v, M, out_t, out_q, out_v, out_E, out_k, kK, kb, kout)
            j_out += 1
    for r in range(NN):
        out_x[r] = x_last[r]


@numba.njit(cache=True, nogil=True)
def lf2_run(variant, M, Minv, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
            out_t, out_q, out_v, out_E, out_k, stats):
    """Semi-implicit 2-stage methods with Newton on the m multipliers only (Lambda = h Psi).

    variant 0, Lobatto IIIA-B SPARK (25): M Z1 = -h/2 grad U(q0) - 1/2 K(q0)^T Lambda_1,
      0 = (k(q0, V1) + k(q1, V1))/2, q1 = q0 + h V1; then M dv + K(q1)^T mu = M Z1 - h/2 grad U(q1),
      K(q1) v1 + b(q1) = 0.
    variant 1, modified (8.4): constraint k(t0 + h/2, q0 + h/2 V1, V1) = 0 instead.
    variant 2, McLachlan-Perlmutter (26): Q1 = q0 + h/2 v0, M dv = -h grad U(Q1) - K(Q1)^T Lambda,
      q1 = q0 + h/2 (v0 + v1), 0 = K(q1) v1 + b(q1)."""
    n = q0.shape[0]
    m = out_k.shape[1]
    q = q0.copy()
    v = v0.copy()
    cq = np.zeros(n)
    cv = np.zeros(n)
    g0 = np.zeros(n)
    g1 = np.zeros(n)
    K0 = np.zeros((m, n))
    b0 = np.zeros(m)
    K1 = np.zeros((m, n))
    b1 = np.zeros(m)
    kq1 = np.zeros((m, n))
    B0 = np.zeros((n, m))
    B1 = np.zeros((n, m))
    u0 = np.zeros(n)
    Z = np.zeros(n)
    V1 = np.zeros(n)
    q1 = np.zeros(n)
    dq = np.zeros(n)
    dv = np.zeros(n)
    cres = np.zeros(m)
    D = np.zeros((m, m))
    S = np.zeros((m, m))
    piv = np.zeros(m, dtype=np.int64)
    lam = np.zeros(m)
    lam_last = np.zeros(m)
    lam_prev = np.zeros(m)
    mu = np.zeros(m)
    kK = np.zeros((m, n))
    kb = np.zeros(m)
    kout = np.zeros(m)
    half = 0.5 * h
    stats[6] = -1
    store(0, t0, q, v, M, out_t, out_q, out_v, out_E, out_k, kK, kb, kout)
    j_out = 1
    for step in range(n_steps):
        t = t0 + step * h
        t1 = t + h
        # explicit part: u0 and B0 = M^-1 K^T at the stage where grad U and K are frozen
        if variant == 2:
            for a in range(n):
                q1[a] = q[a] + half * v[a]
            grad_U(t + half, q1, g0)
            K_of(t + half, q1, K0)
            fu = h
            fb = 1.0
        else:
            grad_U(t, q, g0)
            K_of(t, q, K0)
            b_of(t, q, b0)
            fu = half
            fb = 0.5
        stats[2] += 1
        for a in range(n):
            acc = 0.0
            for b in range(n):
                acc += Minv[a, b] * g0[b]
            u0[a] = -fu * acc
            for l in range(m):
                acc = 0.0
                for b in range(n):
                    acc += Minv[a, b] * K0[l, b]
                B0[a, l] = fb * acc
        if step >= 2 and predictor == 2:
            for l in range(m):
                lam[l] = 2.0 * lam_last[l] - lam_prev[l]
        elif step >= 1 and predictor >= 1:
            for l in range(m):
                lam[l] = lam_last[l]
        else:
            for l in range(m):
                lam[l] = 0.0
        floor = abs(h) * (1.0 + norm_inf(v))
        prev = -1.0
        it = 0
        done = False
        while it < max_iter:
            it += 1
            # Z = u0 - B0 lam is the velocity increment (V1 - v0, or v1 - v0 for variant 2)
            for a in range(n):
                acc = 0.0
                for l in range(m):
                    acc += B0[a, l] * lam[l]
                Z[a] = u0[a] - acc
                V1[a] = v[a] + Z[a]
            if variant == 0:
                for a in range(n):
                    q1[a] = q[a] + h * V1[a]
                tc = t1
            elif variant == 1:
                for a in range(n):
                    q1[a] = q[a] + half * V1[a]
                tc = t + half
            else:
                for a in range(n):
                    q1[a] = q[a] + h * v[a] + half * Z[a]
                tc = t1
            K_of(tc, q1, K1)
            b_of(tc, q1, b1)
            stats[2] += 1
            for l in range(m):
                acc = b1[l]
                for a in range(n):
                    acc += K1[l, a] * V1[a]
                if variant == 0:
                    acc2 = b0[l]
                    for a in range(n):
                        acc2 += K0[l, a] * V1[a]
                    cres[l] = 0.5 * (acc + acc2)
                else:
                    cres[l] = acc
            if it == 1:
                # simplified Newton: dc/dlam at the predictor, factorised once per step
                kq_of(tc, q1, V1, kq1)
                stats[3] += 1
                fq = h if variant == 0 else half
                for l in range(m):
                    for r in range(m):
                        acc = 0.0
                        for a in range(n):
                            Cla = K1[l, a] + fq * kq1[l, a]
                            if variant == 0:
                                Cla = 0.5 * (Cla + K0[l, a])
                            acc += Cla * B0[a, r]
                        D[l, r] = -acc
                if not lu_factor(D, piv):
                    stats[6] = step
                    return
                stats[4] += 1
            for l in range(m):
                cres[l] = -cres[l]
            lu_solve(D, piv, cres)
            for l in range(m):
                lam[l] += cres[l]
            dn = norm_inf(cres)
            if not np.isfinite(dn):
                break
            if converged(dn, prev, norm_inf(lam), floor, tol):
                done = True
                break
            prev = dn
        stats[1] += it
        if it > stats[5]:
            stats[5] = it
        if not done:
            stats[6] = step
            return
        for a in range(n):
            acc = 0.0
            for l in range(m):
                acc += B0[a, l] * lam[l]
            Z[a] = u0[a] - acc
        if variant == 2:
            for a in range(n):
                dq[a] = h * v[a] + half * Z[a]
                dv[a] = Z[a]
        else:
            for a in range(n):
                V1[a] = v[a] + Z[a]
                dq[a] = h * V1[a]
                q1[a] = q[a] + dq[a]
            # second stage: M dv + K(q1)^T mu = M Z - h/2 grad U(q1), K(q1)(v0 + dv) + b(q1) = 0
            grad_U(t1, q1, g1)
            K_of(t1, q1, K1)
            b_of(t1, q1, b1)
            stats[2] += 1
            for a in range(n):
                acc = 0.0
                for b in range(n):
                    acc += Minv[a, b] * g1[b]
                dv[a] = Z[a] - half * acc
                for l in range(m):
                    acc = 0.0
                    for b in range(n):
                        acc += Minv[a, b] * K1[l, b]
                    B1[a, l] = acc
            for l in range(m):
                acc = b1[l]
                for a in range(n):
                    acc += K1[l, a] * v[a]
                acc2 = 0.0
                for a in range(n):
                    acc2 += K1[l, a] * (dv[a] + cv[a])
                mu[l] = acc + acc2
                for r in range(m):
                    acc = 0.0
                    for a in range(n):
                        acc += K1[l, a] * B1[a, r]
                    S[l, r] = acc
            if not lu_factor(S, piv):
                stats[6] = step
                return
            lu_solve(S, piv, mu)
            for a in range(n):
                acc = 0.0
                for l in range(m):
                    acc += B1[a, l] * mu[l]
                dv[a] -= acc
        add_to(q, cq, dq, compensated)
        add_to(v, cv, dv, compensated)
        for l in range(m):
            lam_prev[l] = lam_last[l]
            lam_last[l] = lam[l]
        stats[0] += 1
        if (step + 1) % every == 0 or step + 1 == n_steps:
            store(j_out, t0 + (step + 1) * h, q, v, M, out_t, out_q, out_v, out_E, out_k, kK, kb, kout)
            j_out += 1
'''


def _cache_dir():
    """$LDASPARK_CACHE_DIR, else ~/.cache/ldaspark/fast, else a temp directory (read-only home)."""
    import tempfile
    for d in (os.environ.get("LDASPARK_CACHE_DIR"),
              os.path.join(os.path.expanduser("~"), ".cache", "ldaspark", "fast"),
              os.path.join(tempfile.gettempdir(), "ldaspark-fast")):
        if not d:
            continue
        try:
            os.makedirs(d, exist_ok=True)
            if os.access(d, os.W_OK):
                return d
        except OSError:
            continue
    raise NotCompilableError("no writable cache directory for the generated fast-path modules")


_MODULES: dict[str, object] = {}


def load_source(source: str):
    """Import (compiling on first use) the generated module with this source text; usable in
    worker processes of any executor (the file is written if this machine lacks it)."""
    key = hashlib.sha256(source.encode()).hexdigest()[:20]
    if key in _MODULES:
        return _MODULES[key]
    from ..core.io import atomic_write_text
    modname = f"ldaspark_fast_{key}"
    path = os.path.join(_cache_dir(), modname + ".py")
    if not os.path.exists(path):
        atomic_write_text(path, source)
    spec = importlib.util.spec_from_file_location(modname, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[modname] = mod
    spec.loader.exec_module(mod)
    _MODULES[key] = mod
    return mod


@dataclass
class CompiledSystem:
    """A system's generated module (source + loaded module), constant M and M^-1."""

    name: str
    n: int
    m: int
    source: str
    M: np.ndarray
    Minv: np.ndarray

    @property
    def module(self):
        return load_source(self.source)


_COMPILED: dict[int, CompiledSystem] = {}


def compile_system(system) -> CompiledSystem:
    """Generate (and cache per system object) the compiled model of a mechanical system.
    Raises NotCompilableError."""
    key = id(system)
    hit = _COMPILED.get(key)
    if hit is not None and hit[0] is system:
        return hit[1]
    parts = mechanical_parts(system)
    m = parts["K"].rows
    M = np.array(parts["M"].tolist(), dtype=float)
    try:
        Minv = np.linalg.inv(M)
    except np.linalg.LinAlgError:
        raise NotCompilableError(f"{system.name}: mass matrix M is singular") from None
    src = _HEADER.format(name=system.name, n=system.n, m=m) + "\n\n" + _model_source(system, parts) + "\n\n" + _KERNELS
    cs = CompiledSystem(system.name, system.n, m, src, M, Minv)
    _COMPILED[key] = (system, cs)
    return cs


@dataclass
class FastSolution:
    """Samples at steps 0, every, 2 every, ..., and the last step. Unpacks as
    (t, q, v, energy, constraint, stats)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    energy: np.ndarray
    constraint: np.ndarray
    stats: dict

    def __iter__(self):
        return iter((self.t, self.q, self.v, self.energy, self.constraint, self.stats))


def n_samples(n_steps: int, every: int) -> int:
    return n_steps // every + 1 + (1 if n_steps % every else 0)


def _resolve(method):
    """method name or SparkTableau -> ("lf2", variant, name) or ("spark", tableau, name)."""
    from ..core.tableau import SparkTableau
    from ..core.families import get_method
    if isinstance(method, SparkTableau):
        return "spark", method, method.name
    if method in LF2_VARIANTS:
        return "lf2", LF2_VARIANTS[method], method
    try:
        return "spark", get_method(method), method
    except LdasparkError:
        raise InputError(f"unknown method {method!r} for the fast path; choose a SPARK name "
                         f"or one of {', '.join(LF2_VARIANTS)}") from None


def kernel_spec(method, kernel="auto"):
    """Picklable description of the kernel to run: ("lf2", variant, name) or
    ("spark", {c, A, A_hat, A_tilde, b, b_hat, b_tilde, omega float arrays}, name).
    ``kernel`` "auto" runs lobatto-iiia-iiib-2 with the semi-implicit kernel (the same method,
    (25)); "spark" forces the general kernel."""
    if kernel not in ("auto", "spark"):
        raise InputError(f"kernel must be 'auto' or 'spark', got {kernel!r}")
    kind, what, name = _resolve(method)
    if kind == "spark" and kernel == "auto" and what.name == "lobatto-iiia-iiib-2":
        return "lf2", 0, name
    if kind == "lf2":
        return "lf2", what, name
    ta = what.arrays(None)
    arr = {k: np.asarray(getattr(ta, k), dtype=float) for k in
           ("c", "A", "A_hat", "A_tilde", "b", "b_hat", "b_tilde")}
    arr["omega"] = np.asarray(ta.omega, dtype=float).reshape(max(what.s - 1, 0), what.s)
    return "spark", arr, name


def run_compiled(cs: CompiledSystem, method, t0, q0, v0, h, n_steps, every=1, compensated=True,
                 tol=None, max_iter=50, kernel="auto", predictor=2):
    """Run a compiled kernel (no fallback); ``method`` a name, a SparkTableau or a kernel_spec.
    predictor: 2 = linear extrapolation of the last two steps' unknowns, 1 = last step's,
    0 = zero increments (V_i = v1 = v0, Psi = 0)."""
    if predictor not in (0, 1, 2):
        raise InputError(f"predictor must be 0, 1 or 2, got {predictor!r}")
    spec = method if isinstance(method, tuple) else kernel_spec(method, kernel)
    kind, what, name = spec
    if not isinstance(n_steps, (int, np.integer)) or n_steps <= 0:
        raise InputError(f"n_steps must be a positive integer, got {n_steps!r}")
    if not isinstance(every, (int, np.integer)) or every <= 0:
        raise InputError(f"every must be a positive integer, got {every!r}")
    q0 = np.asarray(q0, dtype=float).copy()
    v0 = np.asarray(v0, dtype=float).copy()
    if q0.shape != (cs.n,) or v0.shape != (cs.n,):
        raise InputError(f"initial data must have n = {cs.n} entries")
    h = float(h)
    if not (np.isfinite(h) and h != 0 and np.all(np.isfinite(q0)) and np.all(np.isfinite(v0))):
        raise InputError("initial data or step size contain NaN/inf, or h = 0")
    tol = 8 * np.finfo(float).eps if tol is None else float(tol)
    S = n_samples(int(n_steps), int(every))
    out_t = np.zeros(S)
    out_q = np.zeros((S, cs.n))
    out_v = np.zeros((S, cs.n))
    out_E = np.zeros(S)
    out_k = np.zeros((S, cs.m))
    stats = np.zeros(7, dtype=np.int64)
    mod = cs.module
    if kind == "lf2":
        mod.lf2_run(int(what), cs.M, cs.Minv, float(t0), q0, v0, h, int(n_steps), int(every), bool(compensated),
                    tol, int(max_iter), int(predictor), out_t, out_q, out_v, out_E, out_k, stats)
    else:
        s = what["A"].shape[0]
        out_x = np.zeros(s * cs.n + s * cs.m + cs.n)
        mod.spark_run(what["c"], what["A"], what["A_hat"], what["A_tilde"], what["b"], what["b_hat"],
                      what["b_tilde"], what["omega"], cs.M, float(t0), q0, v0, h, int(n_steps), int(every),
                      bool(compensated), tol, int(max_iter), int(predictor), out_t, out_q, out_v, out_E, out_k, out_x, stats)
    st = dict(zip(STAT_NAMES, (int(x) for x in stats)))
    if st["failed_step"] >= 0:
        k = st["failed_step"]
        raise NewtonError(f"fast path ({name}): Newton failed at step {k}, t = {float(t0) + k * h:.6g}, "
                          f"h = {h:.3g}", step=k, time=float(t0) + k * h)
    st.pop("failed_step")
    st["mean_iterations"] = st["newton_iterations"] / max(st["steps"], 1)
    st["path"] = "fast"
    st["kernel"] = kind
    st["compensated"] = bool(compensated)
    return FastSolution(out_t, out_q, out_v, out_E, out_k, st)


def _diagnose_newton_failure(exc, system, cs, method, t0, q0, v0, h, compensated, tol, max_iter, kernel,
                             predictor):
    """The kernels report only the failing step; for SPARK methods, recompute the state there
    (the same compiled arithmetic, k steps) and let the generic step report residual and
    iterations. Returns the NewtonError to raise."""
    from ..core.spark import SparkMethod
    from ..core.tableau import SparkTableau
    from ..core.families import get_method
    k = exc.step
    try:
        tab = method if isinstance(method, SparkTableau) else get_method(method)
    except LdasparkError:
        return exc                      # a comparator kernel: no generic step to ask
    if k:
        pre = run_compiled(cs, method, t0, q0, v0, h, k, k, compensated, tol, max_iter, kernel, predictor)
        qk, vk = pre.q[-1], pre.v[-1]
    else:
        qk, vk = np.asarray(q0, float), np.asarray(v0, float)
    tk = float(t0) + k * float(h)
    try:
        SparkMethod(system, tab, max_iter=max_iter).step(tk, qk, vk, float(h), step_index=k)
    except NewtonError as gen:
        return NewtonError(f"{exc} (generic step at the same state: residual {gen.residual:.3e} after "
                           f"{gen.iterations} iterations)", step=k, time=tk, residual=gen.residual,
                           iterations=gen.iterations)
    return NewtonError(f"{exc} (the generic full-Newton step converges at this state: use "
                       "ldaspark.core.spark.integrate for this step size)", step=k, time=tk)


def _setup_checks(system, t0, q0, v0):
    """The generic path's set-up checks, in float64: finite data of the right shape, (4)
    nonsingular with K of full rank, consistent v0 (the compiled kernels assume all three)."""
    from ..core.backend import Backend
    bk = Backend(None)
    try:
        q, v = bk.array(q0), bk.array(v0)
        t = float(t0)
    except (TypeError, ValueError) as exc:
        raise InputError(f"t0, q0 and v0 must be numbers: {exc}") from None
    if q.shape != (system.n,) or v.shape != (system.n,):
        raise InputError(f"initial data have shapes q: {q.shape}, v: {v.shape}; the system has n = {system.n}")
    if not (np.isfinite(t) and bk.isfinite(q) and bk.isfinite(v)):
        raise InputError("initial data contain NaN or infinity")
    system.check_saddle(bk, t, q, v)
    system.check_consistent(bk, t, q, v)


def _notice(msg):
    print(f"ldaspark.compiled.fast: {msg}; falling back to the generic path", file=sys.stderr, flush=True)


def generic_integrate(system, method, t0, q0, v0, h, n_steps, every=1, tol=None):
    """The generic (Python) path with the same outputs as ``run_compiled``."""
    kind, what, name = _resolve(method)
    if kind == "lf2":
        from ..core.comparators import integrate_comparator
        sol = integrate_comparator(name, system, t0, q0, v0, h, int(n_steps), tol=tol)
    else:
        from ..core.spark import integrate
        sol = integrate(system, what, t0, q0, v0, h, n_steps=int(n_steps), tol=tol)
    idx = list(range(0, int(n_steps) + 1, int(every)))
    if idx[-1] != n_steps:
        idx.append(int(n_steps))
    st = dict(sol.stats)
    st["path"] = "generic"
    return FastSolution(np.asarray(sol.t, float)[idx], np.asarray(sol.q, float)[idx],
                        np.asarray(sol.v, float)[idx], np.asarray(sol.energy, float)[idx],
                        np.asarray(sol.constraint, float)[idx], st)


def fast_integrate(scene_or_system, method, t0=None, q0=None, v0=None, h=None, n_steps=None,
                   every=1, compensated=True, tol=None, max_iter=50, kernel="auto", predictor=2) -> FastSolution:
    """Integrate with the compiled float64 path; returns FastSolution (t, q, v, energy,
    constraint, stats) sampled every ``every`` steps (and at the last step).

    scene_or_system: a Scene (t0, q0, v0 default to its initial data) or a LagrangianSystem.
    method: SPARK method name / SparkTableau, or one of ``LF2_VARIANTS`` (Fig. 4 comparators).
    compensated: Kahan summation of the q and v (= M^-1 p) updates.
    Falls back to the generic path, with one line on stderr, if the system cannot be compiled."""
    system = getattr(scene_or_system, "system", scene_or_system)
    if t0 is None or q0 is None or v0 is None:
        if not hasattr(scene_or_system, "initial"):
            raise InputError("give t0, q0, v0 (or pass a Scene)")
        st0, sq0, sv0 = scene_or_system.initial()
        t0 = st0 if t0 is None else t0
        q0 = sq0 if q0 is None else q0
        v0 = sv0 if v0 is None else v0
    if h is None or n_steps is None:
        raise InputError("give h and n_steps")
    kernel_spec(method, kernel)
    _setup_checks(system, t0, q0, v0)
    try:
        cs = compile_system(system)
        cs.module  # noqa: B018  (import / compile now so that failures fall back)
    except NotCompilableError as exc:
        _notice(str(exc))
        return generic_integrate(system, method, t0, q0, v0, h, n_steps, every, tol)
    except Exception as exc:  # numba typing/lowering errors of generated code
        _notice(f"{system.name}: compilation failed ({type(exc).__name__}: {str(exc).splitlines()[0][:120]})")
        return generic_integrate(system, method, t0, q0, v0, h, n_steps, every, tol)
    try:
        return run_compiled(cs, method, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, kernel, predictor)
    except NewtonError as exc:
        raise _diagnose_newton_failure(exc, system, cs, method, t0, q0, v0, h, compensated, tol, max_iter,
                                       kernel, predictor) from None
    except LdasparkError:
        raise
    except Exception as exc:  # numba compiles lazily at the first call: typing errors land here
        if "numba" not in type(exc).__module__:
            raise
        _notice(f"{system.name}: compilation failed ({type(exc).__name__}: {str(exc).splitlines()[0][:120]})")
        return generic_integrate(system, method, t0, q0, v0, h, n_steps, every, tol)


# --- round-off study of the compensated summation ------------------------------------------
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


# --- warming the compile cache -------------------------------------------------------------
def _warm(scene_name, method, kernel):
    from ..core.scenes import get_scene
    import time as _time
    t = _time.perf_counter()
    sc = get_scene(scene_name) if scene_name != "linear-3" else None
    system = sc.system if sc is not None else linear_test_system()
    cs = compile_system(system)
    n = system.n
    q0 = np.zeros(n)
    v0 = np.zeros(n)
    run_compiled(cs, method, 0.0, q0, v0, 0.01, 1, kernel=kernel)
    return _time.perf_counter() - t


def precompile(jobs, max_workers=2):
    """Compile (scene name, method, kernel) jobs in parallel worker processes so that numba's
    on-disk cache holds them, then load them here. ``scene name`` may be "linear-3"
    (``linear_test_system``). Returns {job: seconds}; already loaded jobs are skipped."""
    import concurrent.futures
    todo = []
    for job in jobs:
        name, method, kernel = job
        system = linear_test_system() if name == "linear-3" else None
        if system is None:
            from ..core.scenes import get_scene
            system = get_scene(name).system
        cs = compile_system(system)
        key = hashlib.sha256(cs.source.encode()).hexdigest()[:20]
        kind = kernel_spec(method, kernel)[0]
        mod = _MODULES.get(key)
        fn = None if mod is None else (mod.lf2_run if kind == "lf2" else mod.spark_run)
        if fn is None or not fn.signatures:
            todo.append(job)
    out = {}
    if todo:
        with concurrent.futures.ProcessPoolExecutor(max_workers=max_workers) as ex:
            futs = {job: ex.submit(_warm, *job) for job in todo}
            out = {job: f.result() for job, f in futs.items()}
        for job in todo:
            _warm(*job)                     # loads the cached machine code in this process
    return out
