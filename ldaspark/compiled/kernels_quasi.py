"""A second root finder for the SPARK step (21), mechanical form (L = 1/2 v^T M v - U(t, q),
k = K(t, q) v + b(t, q), M constant): a quasi-Newton iteration on the multipliers only.

The Newton matrix of (21b, d, e, f) in the increments x = [Z | Lambda | dv] (``kernels_mech``)
is replaced by

    [ I (x) M     0    A~ (x) K^T ]        rows (21b): M Z_i + h sum A^_ij grad U_j + sum A~_ij K_j^T Lambda_j
    [   0         M    b~ (x) K^T ]        row  (21d)
    [  C_Z      C_dv       0      ]        rows (21e), (21f): k_q to first order in h

i.e. the velocity block frozen at the mass matrix M (the terms h^2 a^ a Hess U and
h a~ a d(K^T Lambda)/dq dropped) and the constraint rows exact to first order
(``newton.constraint_rows``), all at the predictor. Eliminating Z and dv (M^-1 is constant)
leaves the multiplier system S dLambda = G_c - C_Z M^-1 G_Z - C_dv M^-1 G_d with
S = sum_k C_Z[., k] A~_kj W_j + C_dv b~_j W_j, W_j = M^-1 K_j^T: (s m) x (s m), formed and
factored once per step. The iteration converges to the same root of (21) (the residual is the
exact one); its contraction rate is O(h^2 |Hess U| / |M| + h |Lambda| |K_q|), measured per step.

Predictor (IRKGaussLegendre.jl): the previous step's stage polynomial extrapolated, the velocity
polynomial through (0, v0) and (c_j, V_j) evaluated at 1 + c_i and 2, the multipliers' through
(c_j, Psi_j) at 1 + c_i (``quasi.extrapolation``). Stopping rule: ``newton.newton_status``
(RADAU5's rate test, lim = tol (|x| + |v0|), the round-off of the stage values), never the
round-off-floor clause (the matrix is not exact). Fallback: a step whose increments contract by
less than QUASI_THETA, or that has not converged after QUASI_MAX_ITER increments, or meets a
singular multiplier matrix or a non-finite increment, is solved again by the compiled Newton
chain of ``kernels.spark_newton`` (simplified Newton with fresh matrices, then full Newton from
zero increments), counted in qstats[QS_FALLBACKS]. q and v are summed with Kahan's compensated
summation (``newton.accept_step``).
"""
import numba
import numpy as np
from numba import types

from . import modeltypes as mt
from .kernels import spark_newton, evaluate, store   # noqa: F401 (evaluate: the overload spark_newton uses)
from .kernels_mech import mech_residual, mech_workspace
from .newton import (FAIL_NONFINITE, accept_step, end_newton, fail, lu_factor, lu_solve, newton_status, norm_inf,
                     predict)

# numba keys a cached kernel on the content of this file only; the helpers it compiles in live in
# the sibling modules below (kernels.py itself carries the digest of its own helpers). Their
# digest is written here so that editing one changes this file too (tests/test_kernels_quasi.py).
HELPERS = ("kernels.py", "newton.py", "kernels_mech.py", "kernels_general.py", "kernels_sparse.py",
           "modeltypes.py")
HELPERS_SHA256 = "8a4e187eb04fab1f74032fc7b2a0fae1410ec985d28d48e17774866968d19558"

#: a quasi-Newton increment that contracts by less than this (|dx_k| > QUASI_THETA |dx_k-1|)
#: sends the step to the Newton chain: at rate 1/2 the ~50 bits from a predictor error of 1e-2
#: to round-off would take ~45 iterations, more residuals than Newton's Jacobian and LU save
QUASI_THETA = 0.5
#: quasi-Newton increments per step before the Newton chain takes over
QUASI_MAX_ITER = 30
#: qstats entries: quasi-Newton iterations, steps solved by the quasi-Newton iteration, steps
#: sent to the Newton chain (fallbacks), multiplier matrices factored
QS_ITERATIONS, QS_STEPS, QS_FALLBACKS, QS_LU = 0, 1, 2, 3
#: ``predictor`` value selecting the collocation extrapolation (0-2: ``newton.predict``)
PREDICT_COLLOCATION = 3


@numba.njit(cache=True)
def quasi_workspace(s, n, m, Minv):
    """Minv in CSR (row pointers, columns, values); W_j = M^-1 K_j^T (s, n, m); C_Z (s, m, s, n);
    S and its pivots; y_k = M^-1 G_k (s + 1, n); the multiplier right-hand side and increment
    u_j = W_j dLambda_j (s, n); D (m, n) scratch; the predictor's history: Z, Lambda, dv of the
    last step."""
    nnz = 0
    for a in range(n):
        for b in range(n):
            if Minv[a, b] != 0.0:
                nnz += 1
    Np, Nj, Nx = np.zeros(n + 1, dtype=np.int64), np.zeros(nnz, dtype=np.int64), np.zeros(nnz)
    e = 0
    for a in range(n):
        for b in range(n):
            if Minv[a, b] != 0.0:
                Nj[e] = b
                Nx[e] = Minv[a, b]
                e += 1
        Np[a + 1] = e
    sm = s * m
    return (Np, Nj, Nx, np.zeros((s, n, m)), np.zeros((s, m, s, n)), np.zeros((sm, sm)),
            np.zeros(sm, dtype=np.int64), np.zeros((s + 1, n)), np.zeros(sm), np.zeros((s, n)),
            np.zeros((m, n)), np.zeros(s * n + sm + n))


@numba.njit(cache=True, _nrt=False)
def csr_matvec(Np, Nj, Nx, x, off, out):
    """out = Minv x[off:off + n] with Minv in CSR."""
    for a in range(out.shape[0]):
        acc = 0.0
        for e in range(Np[a], Np[a + 1]):
            acc += Nx[e] * x[off + Nj[e]]
        out[a] = acc


@numba.njit(cache=True, _nrt=False)
def multiplier_matrix(model, tab, h, t, ws, qw):
    """C_Z, W_j and the factored multiplier matrix S at the stage values of the last residual
    (K_j there from ``mech_residual``; k_q evaluated here). False if S is singular."""
    kq_of = model[5]
    c, A, Ah, At, bw, bh, bt, om = tab
    T, Q, V, KK, kq, q1, v1, K1, kq1 = ws[0], ws[1], ws[2], ws[5], ws[10], ws[11], ws[12], ws[13], ws[15]
    Np, Nj, Nx, W, CZ, S, spiv, D = qw[0], qw[1], qw[2], qw[3], qw[4], qw[5], qw[6], qw[10]
    s, n, m = A.shape[0], q1.shape[0], K1.shape[0]
    for j in range(s):
        kq_of(T[j], Q[j], V[j], kq[j])
    kq_of(t + h, q1, v1, kq1)
    # W_j = M^-1 K_j^T
    for j in range(s):
        for a in range(n):
            for ll in range(m):
                acc = 0.0
                for e in range(Np[a], Np[a + 1]):
                    acc += Nx[e] * KK[j, ll, Nj[e]]
                W[j, a, ll] = acc
    # C_Z: (21e) row l, column block k: omega_lk K_k + h sum_j omega_lj a_jk k_q,j; (21f): h b_k k_q(q1, v1)
    for r in range(s):
        for k in range(s):
            for mm in range(m):
                for b in range(n):
                    if r < s - 1:
                        acc = om[r, k] * KK[k, mm, b]
                        for j in range(s):
                            acc += h * om[r, j] * A[j, k] * kq[j, mm, b]
                    else:
                        acc = h * bw[k] * kq1[mm, b]
                    CZ[r, mm, k, b] = acc
    # S[r, j] = (sum_k A~_kj C_Z[r, k] + [r = s-1] b~_j K1) W_j
    for r in range(s):
        for j in range(s):
            for mm in range(m):
                for b in range(n):
                    acc = 0.0
                    for k in range(s):
                        acc += At[k, j] * CZ[r, mm, k, b]
                    if r == s - 1:
                        acc += bt[j] * K1[mm, b]
                    D[mm, b] = acc
            for mm in range(m):
                for ll in range(m):
                    acc = 0.0
                    for b in range(n):
                        acc += D[mm, b] * W[j, b, ll]
                    S[r * m + mm, j * m + ll] = acc
    return lu_factor(S, spiv)


@numba.njit(cache=True, _nrt=False)
def quasi_increment(tab, ws, qw, G, x):
    """x += dx with dx the solution of the frozen system above for the residual G; |dx|_inf."""
    A, At, bt = tab[1], tab[3], tab[6]
    K1 = ws[13]
    Np, Nj, Nx, W, CZ, S, spiv, y, rhs, u = qw[0], qw[1], qw[2], qw[3], qw[4], qw[5], qw[6], qw[7], qw[8], qw[9]
    s, n, m = A.shape[0], y.shape[1], K1.shape[0]
    sn, sm = s * n, s * m
    re0 = sn + n
    for k in range(s + 1):
        csr_matvec(Np, Nj, Nx, G, k * n, y[k])
    # S dLambda = G_c - C_Z y - C_dv y_s
    for r in range(s):
        for mm in range(m):
            acc = G[re0 + r * m + mm]
            for k in range(s):
                for b in range(n):
                    acc -= CZ[r, mm, k, b] * y[k, b]
            if r == s - 1:
                for b in range(n):
                    acc -= K1[mm, b] * y[s, b]
            rhs[r * m + mm] = acc
    lu_solve(S, spiv, rhs)
    dn = 0.0
    for j in range(s):
        for ll in range(m):
            d = rhs[j * m + ll]
            x[sn + j * m + ll] += d
            ad = abs(d)
            if ad > dn or ad != ad:
                dn = ad
        for a in range(n):
            acc = 0.0
            for ll in range(m):
                acc += W[j, a, ll] * rhs[j * m + ll]
            u[j, a] = acc
    # dZ_k = -y_k - sum_j A~_kj u_j, ddv = -y_s - sum_j b~_j u_j
    for k in range(s + 1):
        off = k * n if k < s else sn + sm
        for a in range(n):
            acc = y[k, a]
            for j in range(s):
                acc += (At[k, j] if k < s else bt[j]) * u[j, a]
            x[off + a] -= acc
            ad = abs(acc)
            if ad > dn or ad != ad:
                dn = ad
    return dn


@numba.njit(cache=True, _nrt=False)
def quasi_newton(model, tab, ws, qw, x, t, q, v, h, G, tol, max_iter, stats, qstats):
    """The quasi-Newton iteration from the guess in x; (status, iterations): 1 converged, 0 not
    converged, slow (rate > QUASI_THETA) or singular (the caller falls back), -1 not finite."""
    scale = norm_inf(v)
    mech_residual(model, tab, x, t, q, v, h, ws, G)
    stats[2] += tab[0].shape[0] + 1
    qstats[QS_LU] += 1
    if not multiplier_matrix(model, tab, h, t, ws, qw):
        return 0, 0
    prev = -1.0
    theta = -1.0
    it = 0
    status = 0
    while it < max_iter:
        it += 1
        dn = quasi_increment(tab, ws, qw, G, x)
        status = newton_status(dn, prev, theta, norm_inf(x), scale, tol, False)
        if status != 0:
            break
        if prev > 0.0 and dn > QUASI_THETA * prev:
            break
        theta = dn / prev if prev > 0.0 else -1.0
        prev = dn
        mech_residual(model, tab, x, t, q, v, h, ws, G)
        stats[2] += tab[0].shape[0] + 1
    return status, it


@numba.njit(cache=True, _nrt=False)
def collocation_predict(Ev, El, hist, x, s, n, m):
    """IRKGaussLegendre.jl's predictor in the increments: with the last step's Z_j = V_j - v0',
    dv' = v0 - v0' (v0' its initial velocity, Z = 0 at the node 0), Z_i = sum_j Ev[i, j] Z_j - dv',
    dv = sum_j Ev[s, j] Z_j - dv', Lambda_i = sum_j El[i, j] Lambda_j (h constant)."""
    sn, sm = s * n, s * m
    for i in range(s + 1):
        off = i * n if i < s else sn + sm
        for a in range(n):
            acc = 0.0
            for j in range(s):
                acc += Ev[i, j] * hist[j * n + a]
            x[off + a] = acc - hist[sn + sm + a]
    for i in range(s):
        for ll in range(m):
            acc = 0.0
            for j in range(s):
                acc += El[i, j] * hist[sn + j * m + ll]
            x[sn + i * m + ll] = acc


@numba.njit(cache=True)
def quasi_loop(model, tab, M, Minv, Ev, El, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter,
               predictor, out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats):
    """The step loop of ``spark_loop`` (same sampling, counters, failure codes and out_x layout)
    with the quasi-Newton iteration first and the Newton chain as the fallback."""
    s = tab[1].shape[0]
    n = q0.shape[0]
    m = out_k.shape[1]
    sn, sm = s * n, s * m
    NN = sn + sm + n
    ws = mech_workspace(s, n, m, M)
    qw = quasi_workspace(s, n, m, Minv)
    J = np.zeros((NN, NN))
    piv = np.zeros(NN, dtype=np.int64)
    G = np.zeros(NN)
    x, x_last, x_prev, x_pred = np.zeros(NN), np.zeros(NN), np.zeros(NN), np.zeros(NN)
    dq, dv, cq, cv = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    q, v = q0.copy(), v0.copy()
    bw = tab[4]
    sb = 0.0
    for j in range(s):
        sb += bw[j]
    quasi_max = min(max_iter, QUASI_MAX_ITER)
    stats[mt.FAILED_STEP] = -1
    if not store(model, 0, t0, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
        fail(stats, 0, FAIL_NONFINITE)
        return
    j_out = 1
    for step in range(n_steps):
        t = t0 + step * h
        if predictor == PREDICT_COLLOCATION and step >= 1:
            collocation_predict(Ev, El, x_last, x, s, n, m)
        else:
            predict(x, x_last, x_prev, step, 2 if predictor == PREDICT_COLLOCATION else predictor)
        for r in range(NN):
            x_pred[r] = x[r]
        status, it = quasi_newton(model, tab, ws, qw, x, t, q, v, h, G, tol, quasi_max, stats, qstats)
        qstats[QS_ITERATIONS] += it
        if status == 1:
            qstats[QS_STEPS] += 1
        else:
            # the Newton chain of ``spark_loop``: simplified Newton with fresh matrices from the
            # predictor, then full Newton from zero increments
            qstats[QS_FALLBACKS] += 1
            for r in range(NN):
                x[r] = x_pred[r]
            status, it2, worst = spark_newton(model, tab, M, ws, x, t, q, v, h, G, J, piv, tol, max_iter, False,
                                              stats, False)
            it += it2
            if status != 1:
                stats[mt.FULL_NEWTON_STEPS] += 1
                for r in range(NN):
                    x[r] = 0.0
                status, it2, worst = spark_newton(model, tab, M, ws, x, t, q, v, h, G, J, piv, tol, max_iter,
                                                  True, stats, False)
                it += it2
            if status != 1:
                stats[2] += evaluate(model, tab, False, x, t, q, v, h, M, ws, G, J)
                out_x[0] = norm_inf(G)
        if not end_newton(stats, step, it, status):
            return
        for a in range(n):
            acc = 0.0
            for j in range(s):
                acc += bw[j] * x[j * n + a]
            dq[a] = h * (sb * v[a] + acc)
            dv[a] = x[sn + sm + a]
        if not accept_step(q, v, cq, cv, dq, dv, compensated, x, x_last, x_prev, stats, step):
            return
        if step % every == 0 and out_x.shape[0] > NN:
            o = NN + (step // every) * sm
            for r in range(sm):
                out_x[o + r] = x[sn + r] / h
        if (step + 1) % every == 0 or step + 1 == n_steps:
            if not store(model, j_out, t0 + (step + 1) * h, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
                fail(stats, step, FAIL_NONFINITE)
                return
            j_out += 1
    for r in range(NN):
        out_x[r] = x_last[r]


QUASI_SIG = types.void(mt.MECH_MODEL, mt.TABLEAU_T, mt.a2, mt.a2, mt.a2, mt.a2, *mt.RUN, mt.a1, mt.STATS)


@numba.njit(cache=True, nogil=True)
def quasi_run(model, tab, M, Minv, Ev, El, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
              out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats):
    """n_steps of the SPARK method (21) for a mechanical system with the quasi-Newton root finder
    (``quasi_loop``); arguments as ``kernels.spark_run`` plus M^-1, the predictor's extrapolation
    coefficients Ev (s + 1, s), El (s, s) and the quasi-Newton counters qstats (QS_*)."""
    quasi_loop(model, tab, M, Minv, Ev, El, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
               out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats)
