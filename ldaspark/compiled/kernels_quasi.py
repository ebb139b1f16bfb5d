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
round-off-floor clause (the matrix is not exact); at the second increment also RADAU5's test with
the one ratio there, while |dx_2| <= FIRST_RATE_FACTOR lim; at the first, RADAU5's test with the
rate carried from the previous steps, eta |dx_1| <= RATE_KAPPA lim (eta = theta / (1 - theta), theta
the slowest ratio |dx_k| / |dx_k-1| of the last step that measured one, grown as max(eta, eps)^RATE_GROWTH per step; none after a
fallback or a change of the frozen block; only for a |dx_1| within RATE_SPAN of the first increment it was measured on), which a user's tol = ``Newton(tol=...)`` above round-off
turns into one-increment steps (counted in qstats[QS_RATE_FIRST]). Fallback: a step whose increments contract by
less than QUASI_THETA, or that has not converged after QUASI_MAX_ITER increments, or meets a
singular multiplier matrix or a non-finite increment, is solved again by the compiled Newton
chain of ``kernels.spark_newton`` (simplified Newton with fresh matrices, then full Newton from
zero increments), counted in qstats[QS_FALLBACKS]; after a fallback the next steps go there
directly, for a wait that doubles while attempts keep failing (QS_SKIPPED, QUASI_WAIT_MAX). q and
v are summed with Kahan's compensated summation (``newton.accept_step``).

Curvature variant (``curvature_refresh``, ``curvature_matrix``, ``curvature_increment``; CURV_*):
where h^2 |A^ A| |M^-1| |Hess U| is not small the velocity block is frozen at I (x) M + h^2 (A^ A)
(x) H (and the (21d) row's h^2 (b^ A) (x) H), H = Hess U at the predicted midpoint, its inverse
built from the eigenvectors of (H, M) as n systems of size s and kept while H is not stale: the
contraction rate drops from O(h^2 |Hess U| / |M|) to that of the terms still dropped (the
constraint curvature, the change of H), and the particle of 8.1 needs 3 increments per step
instead of 4-8. The residual is the same, so is the root.
"""
import numba
import numpy as np
from numba import types

from . import modeltypes as mt
from .kernels import finish_step, loop_arrays, spark_newton, evaluate, store   # noqa: F401 (evaluate: the overload spark_newton uses)
from .kernels_mech import mech_residual, mech_workspace
from .newton import (FAIL_NONFINITE, RATE_KAPPA, end_newton, fail, lu_factor, lu_solve, newton_status,
                     norm_inf, predict)

# numba keys a cached kernel on the content of this file only; the helpers it compiles in live in
# the sibling modules below (kernels.py itself carries the digest of its own helpers). Their
# digest is written here so that editing one changes this file too (tests/test_kernels_quasi.py).
HELPERS = ("kernels.py", "newton.py", "kernels_mech.py", "kernels_general.py", "kernels_sparse.py",
           "modeltypes.py")
HELPERS_SHA256 = "427c00b586cdd0a92d1275618e37e8838e84779e0b70674ef9bc952483b6c27e"

#: a quasi-Newton increment that contracts by less than this (|dx_k| > QUASI_THETA |dx_k-1|)
#: sends the step to the Newton chain: at rate 1/2 the ~50 bits from a predictor error of 1e-2
#: to round-off would take ~45 iterations, more residuals than Newton's Jacobian and LU save
QUASI_THETA = 0.5
#: quasi-Newton increments per step before the Newton chain takes over
QUASI_MAX_ITER = 30
#: qstats entries: quasi-Newton iterations, steps solved by the quasi-Newton iteration, steps
#: sent to the Newton chain (fallbacks), multiplier matrices factored
QS_ITERATIONS, QS_STEPS, QS_FALLBACKS, QS_LU = 0, 1, 2, 3
#: steps sent to the Newton chain without a quasi-Newton attempt (counted in QS_FALLBACKS too):
#: after a fallback the next QUASI_WAIT_MAX >= wait >= 1 steps go straight to the Newton chain,
#: the wait doubling after every fallback that follows one and reset by a converged attempt (the
#: choice per run: where the iteration does not contract, as for a stiff spring, it is tried
#: rarely instead of costing up to QUASI_MAX_ITER residuals before every Newton step)
QS_SKIPPED = 4
QUASI_WAIT_MAX = 64
#: the single-ratio rate test at the second increment applies while |dx_2| <= FIRST_RATE_FACTOR lim
FIRST_RATE_FACTOR = 1e3
#: ``predictor`` value selecting the collocation extrapolation (0-2: ``newton.predict``)
PREDICT_COLLOCATION = 3
#: the carried rate estimate eta of ``quasi_newton``'s first-increment test grows as
#: max(eta, EPS)^RATE_GROWTH at every step that does not measure it (RADAU5's FACCON), so that a
#: run of one-increment steps soon takes a second increment and measures the rate again
RATE_GROWTH = 0.8
#: the carried rate is applied to a first increment within a factor RATE_SPAN of the first increment of
#: the step that measured it: a ratio is evidence about the predictor error it was measured on, and a
#: first increment far from that size comes from another error (ball-turntable, gauss-5, h = 0.8: step
#: 0's zero-increment guess measured 0.065 then 1.2e-13, a ratio at round-off, and steps 1 and 2
#: accepted first increments of 1.9e-6 on it, where the collocation predictor's error contracts at
#: 0.1-0.25 and one increment left 1e-9 at tol = 1e-12)
RATE_SPAN = 100.0
EPS = float(np.finfo(np.float64).eps)


@numba.njit(cache=True)
def quasi_workspace(tab, n, m, Minv):
    """Minv in CSR (row pointers, columns, values); W_j = M^-1 K_j^T (s, n, m); the frozen K_j,
    k_q,j at the stages and K, k_q at the end point (at the predictor); a column of
    ``multiplier_matrix``'s B (s); the tableau product A A~ (s, s); S and its pivots; y_k = M^-1 G_k
    (s + 1, n); the multiplier right-hand side; u_j = W_j dLambda_j (s, n); z_j = sum_k a_jk y_k
    (s, n); (b A~)_j (s); K_k y_k and k_q,j z_j (s, m)."""
    c, A, Ah, At, bw, bh, bt, om = tab
    s = A.shape[0]
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
    AAt = np.zeros((s, s))
    bAt = np.zeros(s)
    for jp in range(s):
        acc = 0.0
        for k in range(s):
            acc += bw[k] * At[k, jp]
        bAt[jp] = acc
    for j in range(s):
        for jp in range(s):
            acc = 0.0
            for k in range(s):
                acc += A[j, k] * At[k, jp]
            AAt[j, jp] = acc
    return (Np, Nj, Nx, np.zeros((s, n, m)), np.zeros((s, m, n)), np.zeros((s, m, n)), np.zeros((m, n)),
            np.zeros((m, n)), np.zeros(s), AAt, np.zeros((sm, sm)),
            np.zeros(sm, dtype=np.int64), np.zeros((s + 1, n)), np.zeros(sm), np.zeros((s, n)), np.zeros((s, n)),
            bAt, np.zeros((s, m)), np.zeros((s, m)))


@numba.njit(cache=True, _nrt=False)
def csr_matvec(Np, Nj, Nx, x, off, out):
    """out = Minv x[off:off + n] with Minv in CSR."""
    for a in range(out.shape[0]):
        acc = 0.0
        for e in range(Np[a], Np[a + 1]):
            acc += Nx[e] * x[off + Nj[e]]
        out[a] = acc


@numba.njit(cache=True, _nrt=False)
def freeze_constraint(model, h, t, ws, qw):
    """The frozen constraint geometry of the step (``multiplier_matrix``, ``curvature_matrix``): K_j
    (from the last residual) and k_q,j at the stages, K and k_q at (t + h, q1, v1), into qw."""
    kq_of = model[5]
    T, Q, V, KK, q1, v1, K1 = ws[0], ws[1], ws[2], ws[5], ws[11], ws[12], ws[13]
    Kf, kqf, K1f, kq1f = qw[4], qw[5], qw[6], qw[7]
    s, m, n = Kf.shape[0], Kf.shape[1], Kf.shape[2]
    for j in range(s):
        kq_of(T[j], Q[j], V[j], kqf[j])
        for ll in range(m):
            for b in range(n):
                Kf[j, ll, b] = KK[j, ll, b]
    kq_of(t + h, q1, v1, kq1f)
    for ll in range(m):
        for b in range(n):
            K1f[ll, b] = K1[ll, b]


@numba.njit(cache=True, _nrt=False)
def multiplier_matrix(model, tab, h, t, ws, qw):
    """The frozen K, k_q, W_j and the factored multiplier matrix S at the stage values of the last
    residual (K_j there from ``mech_residual``; k_q evaluated here). False if S is singular.

    With C_Z[r, k] = omega_rk K_k + h sum_j omega_rj a_jk k_q,j (21e) and h b_k k_q(q1, v1) (21f):
    S[r, j'] = sum_k omega_rk B_kj' (r < s - 1), B_kj' = a~_kj' K_k W_j' + h (A A~)_kj' k_q,k W_j',
    S[s - 1, j'] = (h (b A~)_j' k_q(q1, v1) + b~_j' K(q1)) W_j': O(s^3 m^2 + s^2 m^2 n), C_Z never
    formed; B a column at a time, so that omega multiplies one sum (s^2 (s - 1) m^2 products, not
    twice that: ~0.3 us of the ~1.1 us this took for gauss-8, n = 3, m = 1)."""
    At, bt, om = tab[3], tab[6], tab[7]
    q1, K1 = ws[11], ws[13]
    Np, Nj, Nx, W, Kf, kqf, K1f, kq1f, Bv, AAt, S, spiv = (qw[0], qw[1], qw[2], qw[3], qw[4], qw[5], qw[6], qw[7],
                                                         qw[8], qw[9], qw[10], qw[11])
    bAt = qw[16]
    s, n, m = At.shape[0], q1.shape[0], K1.shape[0]
    freeze_constraint(model, h, t, ws, qw)
    # W_j = M^-1 K_j^T
    for j in range(s):
        for a in range(n):
            for ll in range(m):
                acc = 0.0
                for e in range(Np[a], Np[a + 1]):
                    acc += Nx[e] * Kf[j, ll, Nj[e]]
                W[j, a, ll] = acc
    for jp in range(s):
        for mm in range(m):
            for ll in range(m):
                for k in range(s):
                    p = 0.0
                    qq = 0.0
                    for b in range(n):
                        p += Kf[k, mm, b] * W[jp, b, ll]
                        qq += kqf[k, mm, b] * W[jp, b, ll]
                    Bv[k] = At[k, jp] * p + h * (AAt[k, jp] * qq)
                for r in range(s - 1):
                    acc = 0.0
                    for k in range(s):
                        acc += om[r, k] * Bv[k]
                    S[r * m + mm, jp * m + ll] = acc
                acc = 0.0
                for b in range(n):
                    acc += (h * bAt[jp] * kq1f[mm, b] + bt[jp] * K1f[mm, b]) * W[jp, b, ll]
                S[(s - 1) * m + mm, jp * m + ll] = acc
    return lu_factor(S, spiv)


@numba.njit(cache=True, _nrt=False, inline="always")
def quasi_increment(tab, h, qw, G, x):
    """x += dx with dx the solution of the frozen system above for the residual G; |dx|_inf.
    y_k = M^-1 G_k; S dLambda = G_c - C_Z y - C_dv y_s with C_Z y formed from the frozen K_k y_k and
    k_q,j z_j, z_j = sum_k a_jk y_k (C_Z never formed); then dZ_k = -y_k - sum_j a~_kj W_j dLambda_j
    and ddv = -y_s - sum_j b~_j W_j dLambda_j."""
    A, At, bw, bt, om = tab[1], tab[3], tab[4], tab[6], tab[7]
    Np, Nj, Nx, W, Kf, kqf, K1f, kq1f = qw[0], qw[1], qw[2], qw[3], qw[4], qw[5], qw[6], qw[7]
    S, spiv, y, rhs, u, z, Ky, kz = qw[10], qw[11], qw[12], qw[13], qw[14], qw[15], qw[17], qw[18]
    s, n, m = A.shape[0], y.shape[1], Kf.shape[1]
    sn, sm = s * n, s * m
    re0 = sn + n
    for k in range(s + 1):
        csr_matvec(Np, Nj, Nx, G, k * n, y[k])
    for j in range(s):
        for a in range(n):
            acc = 0.0
            for k in range(s):
                acc += A[j, k] * y[k, a]
            z[j, a] = acc
        for mm in range(m):
            acc = 0.0
            acc2 = 0.0
            for a in range(n):
                acc += Kf[j, mm, a] * y[j, a]
                acc2 += kqf[j, mm, a] * z[j, a]
            Ky[j, mm] = acc
            kz[j, mm] = acc2
    # (21e) rows: C_Z y = sum_k omega_rk K_k y_k + h sum_j omega_rj k_q,j z_j
    for r in range(s - 1):
        for mm in range(m):
            acc = 0.0
            for k in range(s):
                acc += om[r, k] * (Ky[k, mm] + h * kz[k, mm])
            rhs[r * m + mm] = G[re0 + r * m + mm] - acc
    # (21f) row: h k_q(q1, v1) sum_k b_k y_k + K(q1) y_s
    r = s - 1
    for mm in range(m):
        acc = 0.0
        acc2 = 0.0
        for a in range(n):
            yb = 0.0
            for k in range(s):
                yb += bw[k] * y[k, a]
            acc += kq1f[mm, a] * yb
            acc2 += K1f[mm, a] * y[s, a]
        rhs[r * m + mm] = G[re0 + r * m + mm] - h * acc - acc2
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


#: the curvature variant (``curvature_*``): the velocity block frozen at I (x) M + h^2 (A^ A) (x) H
#: with H = Hess U at the step's predicted midpoint, used on a run with n <= CURV_N_MAX (the
#: transformation costs O(n^2) per stage and increment, the decomposition O(n^3)) and on a step
#: where eta = h^2 |A^ A|_inf |M^-1|_inf |H|_inf >= CURV_MIN (below it the M-only iteration already
#: contracts at about eta: the skate, H = 0, stays there); the decomposition is kept while the
#: dropped part h^2 |A^ A| |M^-1| |H - H_frozen| stays below max(CURV_STALE, CURV_STALE_REL eta)
#: (a constant Hessian, the particle's, is decomposed once per run). The choice per run: once
#: CURV_WARMUP steps have passed with more than one refresh (the first not counted) in
#: CURV_REFRESH_EVERY steps, the run continues with the M-only block (a decomposition, O(s^2 n^3)
#: and a LAPACK call, measured 2.5-3 us at n = 3, costs more than the ~1 residual it saves per step)
CURV_N_MAX = 16
CURV_MIN = 1e-3
CURV_STALE = 1e-4
CURV_STALE_REL = 0.25
CURV_WARMUP = 32
CURV_REFRESH_EVERY = 8
#: qstats entry: Hessian decompositions (``curvature_refresh``) and steps iterated with the curvature
QS_CURV_REFRESH, QS_CURV_STEPS = 5, 6
#: qstats entry: steps accepted after one increment by the carried rate (``quasi_newton``'s eta)
QS_RATE_FIRST = 7


@numba.njit(cache=True)
def curvature_workspace(tab, n, m, M, Minv):
    """L^-1 (M = L L^T, Cholesky), P = A^ A (s, s), p = b^ A (s), info = [|P|_inf, |M^-1|_inf, the LU
    factorisations of the last ``curvature_refresh``], the frozen H and a new one (n, n), X (n, n), mu (n), the inverses of I + h^2 mu_a P (n, s, s) and
    pivots, the response matrices T_j ((s + 1) n, n) per stage, R ((s + 1) n, (s + 1) n) (see
    ``curvature_refresh``), the responses of the step's multipliers (s m, (s + 1) n), M^-1, scratch."""
    A, Ah, bh = tab[1], tab[2], tab[5]
    s = A.shape[0]
    Lc = np.linalg.cholesky(M)
    Linv = np.linalg.inv(Lc)
    P = Ah @ A
    p = bh @ A
    info = np.zeros(3)
    pn = 0.0
    for i in range(s):
        acc = 0.0
        for k in range(s):
            acc += abs(P[i, k])
        pn = max(pn, acc)
    mn = 0.0
    for a in range(n):
        acc = 0.0
        for b in range(n):
            acc += abs(Minv[a, b])
        mn = max(mn, acc)
    info[0] = pn
    info[1] = mn
    N1 = (s + 1) * n
    return (np.ascontiguousarray(Linv), np.ascontiguousarray(P), np.ascontiguousarray(p), info, np.zeros((n, n)),
            np.zeros((n, n)), np.zeros((n, n)), np.zeros(n), np.zeros((n, s, s)), np.zeros(s, dtype=np.int64),
            np.zeros((s, N1, n)), np.zeros((N1, N1)), np.zeros((s * m, N1)), np.zeros(N1), np.zeros(s),
            np.ascontiguousarray(Minv), np.zeros(s * m))


@numba.njit(cache=True)
def curvature_refresh(tab, h, cw):
    """The frozen velocity block's inverse from H = cw[4] (Hess U). With M = L L^T,
    L^-1 H L^-T = U diag(mu) U^T and X = L^-T U (X^T M X = I, X^T H X = diag(mu)), the stage block
    B = I (x) M + h^2 P (x) H of (21b) has B^-1_ik = sum_a [(I + h^2 mu_a P)^-1]_ik X_a X_a^T (n
    systems of size s, not one of size s n). R maps the residual rows [G_Z; G_d] of (21b, d) to
    [y; y_s] = [B^-1 G_Z; M^-1 (G_d - h^2 H sum_k p_k y_k)], and T_j = R (A~_ij I; b~_j I)_i: the
    response of (21b, d) to a multiplier of stage j is T_j K_j^T e_l. False if singular or not finite."""
    At, bt = tab[3], tab[6]
    Linv, P, p, Hf, X, mu, Inv, piv, Tw, R, Minv, col = (cw[0], cw[1], cw[2], cw[4], cw[6], cw[7], cw[8], cw[9],
                                                         cw[10], cw[11], cw[15], cw[14])
    n, s = Hf.shape[0], P.shape[0]
    cw[3][2] = 0.0          # the LUs below, counted in nlu by the caller
    C = Linv @ Hf @ Linv.T
    C = 0.5 * (C + C.T)
    for a in range(n):
        for b in range(n):
            if not np.isfinite(C[a, b]):
                return False
    w, U = np.linalg.eigh(C)
    Xn = Linv.T @ U
    h2 = h * h
    LU = np.zeros((s, s))
    for a in range(n):
        mu[a] = w[a]
        for b in range(n):
            X[a, b] = Xn[a, b]
        for i in range(s):
            for k in range(s):
                LU[i, k] = (1.0 if i == k else 0.0) + h2 * w[a] * P[i, k]
        cw[3][2] += 1.0
        if not lu_factor(LU, piv):
            return False
        for k in range(s):
            for i in range(s):
                col[i] = 1.0 if i == k else 0.0
            lu_solve(LU, piv, col)
            for i in range(s):
                Inv[a, i, k] = col[i]
    sn = s * n
    R[:, :] = 0.0
    for i in range(s):
        for k in range(s):
            for a in range(n):
                xa = X[:, a]
                f = Inv[a, i, k]
                for r in range(n):
                    for c2 in range(n):
                        R[i * n + r, k * n + c2] += f * xa[r] * xa[c2]
    F = h2 * (Minv @ Hf)
    # y_s = M^-1 G_d - F sum_k p_k y_k, y_k = sum_i' B^-1_ki' G_i'
    for ip in range(s):
        for r in range(n):
            for c2 in range(n):
                acc = 0.0
                for k in range(s):
                    for e in range(n):
                        acc += p[k] * F[r, e] * R[k * n + e, ip * n + c2]
                R[sn + r, ip * n + c2] = -acc
    for r in range(n):
        for c2 in range(n):
            R[sn + r, sn + c2] = Minv[r, c2]
    for j in range(s):
        for r in range((s + 1) * n):
            for c2 in range(n):
                acc = bt[j] * R[r, sn + c2]
                for ip in range(s):
                    acc += At[ip, j] * R[r, ip * n + c2]
                Tw[j, r, c2] = acc
    for j in range(s):
        for r in range((s + 1) * n):
            for c2 in range(n):
                if not np.isfinite(Tw[j, r, c2]):
                    return False
    return True


@numba.njit(cache=True, _nrt=False, inline="always")
def constraint_apply(A, bw, om, h, Kf, kqf, K1f, kq1f, z, Ky, kz, y, out):
    """out = C_Z y_Z + C_dv y_s, the frozen (21e, f) rows, y = [y_Z (s, n) | y_s (n)] flat:
    sum_k omega_rk K_k y_k + h sum_j omega_rj k_q,j sum_k a_jk y_k (r < s - 1); h k_q(q1, v1)
    sum_k b_k y_k + K(q1) y_s (the frozen K, k_q of ``multiplier_matrix``; scratch z, Ky, kz;
    arrays rather than the workspace tuples are passed: a call copies its arguments)."""
    s, n, m = A.shape[0], Kf.shape[2], Kf.shape[1]
    sn = s * n
    for j in range(s):
        for a in range(n):
            acc = 0.0
            for k in range(s):
                acc += A[j, k] * y[k * n + a]
            z[j, a] = acc
        for mm in range(m):
            acc = 0.0
            acc2 = 0.0
            for a in range(n):
                acc += Kf[j, mm, a] * y[j * n + a]
                acc2 += kqf[j, mm, a] * z[j, a]
            Ky[j, mm] = acc
            kz[j, mm] = acc2
    for r in range(s - 1):
        for mm in range(m):
            acc = 0.0
            for k in range(s):
                acc += om[r, k] * (Ky[k, mm] + h * kz[k, mm])
            out[r * m + mm] = acc
    r = s - 1
    for mm in range(m):
        acc = 0.0
        acc2 = 0.0
        for a in range(n):
            yb = 0.0
            for k in range(s):
                yb += bw[k] * y[k * n + a]
            acc += kq1f[mm, a] * yb
            acc2 += K1f[mm, a] * y[sn + a]
        out[r * m + mm] = h * acc + acc2


@numba.njit(cache=True, _nrt=False)
def curvature_matrix(model, tab, h, t, ws, qw, cw):
    """``multiplier_matrix`` with the velocity block I (x) M + h^2 P (x) H (``curvature_refresh``):
    for every multiplier (j, l) its response w = T_j K_j^T e_l in (21b, d) and the column
    S[:, (j, l)] = C_Z w_Z + C_dv w_s. O(s m (s + 1) n^2 + s m s^2 n). False if S is singular."""
    A, bw, om = tab[1], tab[4], tab[7]
    q1, K1 = ws[11], ws[13]
    Kf, kqf, K1f, kq1f, S, spiv = qw[4], qw[5], qw[6], qw[7], qw[10], qw[11]
    z, Ky, kz = qw[15], qw[17], qw[18]
    Tw, Wc, rhs = cw[10], cw[12], cw[16]
    s, n, m = A.shape[0], q1.shape[0], K1.shape[0]
    N1 = (s + 1) * n
    freeze_constraint(model, h, t, ws, qw)
    for j in range(s):
        for ll in range(m):
            col = j * m + ll
            for r in range(N1):
                acc = 0.0
                for b in range(n):
                    acc += Tw[j, r, b] * Kf[j, ll, b]
                Wc[col, r] = acc
            constraint_apply(A, bw, om, h, Kf, kqf, K1f, kq1f, z, Ky, kz, Wc[col], rhs)
            for r in range(s * m):
                S[r, col] = rhs[r]
    return lu_factor(S, spiv)


@numba.njit(cache=True, _nrt=False, inline="always")
def curvature_increment(tab, h, qw, cw, G, x):
    """``quasi_increment`` with the velocity block of ``curvature_matrix``: y = R [G_Z; G_d],
    S dLambda = G_c - C_Z y_Z - C_dv y_s, [dZ; ddv] = -y - sum w dLambda; |dx|_inf."""
    A, bw, om = tab[1], tab[4], tab[7]
    Kf, kqf, K1f, kq1f, S, spiv = qw[4], qw[5], qw[6], qw[7], qw[10], qw[11]
    rhs, z, Ky, kz = qw[13], qw[15], qw[17], qw[18]
    R, Wc, y, r2 = cw[11], cw[12], cw[13], cw[16]
    s, n, m = A.shape[0], Kf.shape[2], Kf.shape[1]
    sn, sm = s * n, s * m
    N1 = sn + n
    for r in range(N1):
        acc = 0.0
        for c2 in range(N1):
            acc += R[r, c2] * G[c2]
        y[r] = acc
    constraint_apply(A, bw, om, h, Kf, kqf, K1f, kq1f, z, Ky, kz, y, r2)
    for r in range(sm):
        rhs[r] = G[N1 + r] - r2[r]
    lu_solve(S, spiv, rhs)
    dn = 0.0
    for col in range(sm):
        d = rhs[col]
        x[sn + col] += d
        ad = abs(d)
        if ad > dn or ad != ad:
            dn = ad
    for r in range(N1):
        acc = y[r]
        for col in range(sm):
            acc += Wc[col, r] * rhs[col]
        x[r if r < sn else r + sm] -= acc
        ad = abs(acc)
        if ad > dn or ad != ad:
            dn = ad
    return dn


@numba.njit(cache=True, _nrt=False, inline="always")
def quasi_newton(model, tab, ws, qw, cw, curv, x, t, q, v, h, G, tol, max_iter, stats, qstats, eta, dref):
    """The quasi-Newton iteration from the guess in x, with the velocity block frozen at M (curv
    False) or at I (x) M + h^2 P (x) H (``curvature_matrix``); (status, iterations, rate, |dx_1|):
    status 1 converged, 0 not converged, slow (rate > QUASI_THETA) or singular (the caller falls
    back), -1 not finite; rate the slowest contraction ratio |dx_k| / |dx_k-1| measured (-1 if one
    increment). eta > 0: the rate estimate theta / (1 - theta) carried from the previous steps
    (``quasi_loop``), measured on a first increment of dref; the first increment is accepted when
    eta |dx_1| <= RATE_KAPPA lim (RADAU5's test at its first iteration, Hairer-Wanner IV.8: the
    error left after it is eta |dx_1|) and |dx_1| is within a factor RATE_SPAN of dref."""
    scale = norm_inf(v)
    mech_residual(model, tab, x, t, q, v, h, ws, G)
    stats[2] += tab[0].shape[0] + 1
    qstats[QS_LU] += 1
    if curv:
        if not curvature_matrix(model, tab, h, t, ws, qw, cw):
            return 0, 0, -1.0, -1.0
    elif not multiplier_matrix(model, tab, h, t, ws, qw):
        return 0, 0, -1.0, -1.0
    prev = -1.0
    d1 = -1.0
    theta = -1.0
    rate = -1.0
    it = 0
    status = 0
    while it < max_iter:
        it += 1
        dn = curvature_increment(tab, h, qw, cw, G, x) if curv else quasi_increment(tab, h, qw, G, x)
        status = newton_status(dn, prev, theta, norm_inf(x), scale, tol, False)
        if prev <= 0.0:
            d1 = dn
            if (status == 0 and eta > 0.0 and eta * dn <= RATE_KAPPA * tol * (norm_inf(x) + scale)
                    and dref <= RATE_SPAN * dn and dn <= RATE_SPAN * dref):
                status = 1
                # counted here, where the carried rate decides: a first increment that passed
                # the plain test |dx_1| <= lim was counted too (skate, gauss-4, tol = 0.1: 99 of 100)
                qstats[QS_RATE_FIRST] += 1
        if status == 0 and prev > 0.0 and theta <= 0.0:
            # RADAU5 at its second increment: the rate of the one ratio there, theta_1 =
            # |dx_2| / |dx_1|, stops the iteration when theta_1 / (1 - theta_1) |dx_2| <= kappa lim,
            # here only while |dx_2| is within FIRST_RATE_FACTOR lim (a drop onto a noise floor far
            # above round-off is no evidence of contraction)
            th = dn / prev
            lim = tol * (norm_inf(x) + scale)
            if th < 1.0 and th / (1.0 - th) * dn <= RATE_KAPPA * lim and dn <= FIRST_RATE_FACTOR * lim:
                status = 1
        if prev > 0.0:
            # the slowest ratio the step measured, carried as the rate: a last increment at
            # round-off makes a ratio that is no rate (particle, lobatto-iiia-iiib-2, step 0:
            # 5e-3 then 8.6e-19 / 9.9e-4; carried, it accepted first increments of 0.29)
            rate = max(rate, dn / prev)
        if status != 0:
            break
        if prev > 0.0 and dn > QUASI_THETA * prev:
            break
        theta = dn / prev if prev > 0.0 else -1.0
        prev = dn
        mech_residual(model, tab, x, t, q, v, h, ws, G)
        stats[2] += tab[0].shape[0] + 1
    return status, it, rate, d1


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


#: ``quasi_steps``' integer state (``istate``): the steps still sent straight to the Newton chain,
#: the next wait, the last step's block had Hess U, a frozen decomposition exists, the curvature
#: block is in use, the next sample's index, the refresh asked for at this step was done (the
#: step re-entered after ``curvature_refresh``)
IS_WAIT, IS_BACKOFF, IS_CURV_LAST, IS_HAVE_FROZEN, IS_USE_CURV, IS_J_OUT, IS_REFRESHED = 0, 1, 2, 3, 4, 5, 6
#: its float state (``fstate``): the carried rate estimate eta and the first increment it was measured on
FS_ETA, FS_DREF = 0, 1


@numba.njit(cache=True)
def steps_state(use_curv):
    """(istate, fstate) of a run's start: no wait, back-off 1, the next sample 1, the curvature
    block in use where ``use_curv``; no carried rate (eta = dref = -1: none, as after a fallback or
    a change of the frozen block)."""
    istate = np.zeros(IS_REFRESHED + 1, dtype=np.int64)
    istate[IS_BACKOFF] = 1
    istate[IS_J_OUT] = 1
    istate[IS_USE_CURV] = 1 if use_curv else 0
    fstate = np.zeros(FS_DREF + 1)
    fstate[FS_ETA] = -1.0
    fstate[FS_DREF] = -1.0
    return istate, fstate
#: ``quasi_steps`` returns this instead of a step index when the run has failed (recorded in stats)
STEPS_FAILED = -1


@numba.njit(cache=True, _nrt=False)
def quasi_steps(model, tab, M, Ev, El, t0, h, n_steps, every, compensated, tol, max_iter, predictor, quasi_max,
                ws, qw, cw, J, piv, G, x, x_last, x_prev, x_pred, q, v, dq, dv, cq, cv, qmid, sb, step0, istate,
                fstate, out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats):
    """Steps step0, step0 + 1, ... of ``quasi_loop`` (the whole loop body; the state carried in
    istate (IS_*) and fstate (FS_*)). Returns n_steps when done, STEPS_FAILED when a step failed,
    or the step at which the curvature block needs a new decomposition (``curvature_refresh``
    allocates and calls LAPACK, so the caller runs it and re-enters at that step with
    istate[IS_REFRESHED] set: the step's predictor is computed again, the same). Not reference
    counted: the per-step work runs in one call with the workspaces passed once, not one call of
    ``quasi_newton`` with every workspace array passed by value per step (skate, gauss-8: ~8% of
    the step was that call), and NRT reference counting of the arrays (``finish_step``)."""
    s = tab[1].shape[0]
    n = q.shape[0]
    m = out_k.shape[1]
    sn, sm = s * n, s * m
    NN = sn + sm + n
    bw = tab[4]
    hess_U = model[2]
    cinfo, Hf, Hn = cw[3], cw[4], cw[5]
    hpm = h * h * cinfo[0] * cinfo[1]
    for step in range(step0, n_steps):
        t = t0 + step * h
        if predictor == PREDICT_COLLOCATION and step >= 1:
            collocation_predict(Ev, El, x_last, x, s, n, m)
        else:
            predict(x, x_last, x_prev, step, 2 if predictor == PREDICT_COLLOCATION else predictor)
        for r in range(NN):
            x_pred[r] = x[r]
        if istate[IS_WAIT] > 0:
            istate[IS_WAIT] -= 1
            status, it = 0, 0
            fstate[FS_ETA] = -1.0
            qstats[QS_SKIPPED] += 1
        else:
            curv = False
            refreshes = qstats[QS_CURV_REFRESH]
            if istate[IS_USE_CURV] != 0:
                active = False              # Hess U large enough for the curvature block
                if istate[IS_REFRESHED] != 0:
                    # re-entered after the refresh this step asked for (counted there)
                    istate[IS_REFRESHED] = 0
                    refreshes -= 1
                    curv = istate[IS_HAVE_FROZEN] != 0
                    active = True
                else:
                    # Hess U at the predicted midpoint; the frozen one kept while the difference
                    # would contract at most CURV_STALE
                    for a in range(n):
                        qmid[a] = q[a] + 0.5 * h * v[a]
                    hess_U(t + 0.5 * h, qmid, Hn)
                    hn = 0.0
                    dh = 0.0
                    for a in range(n):
                        acc = 0.0
                        acc2 = 0.0
                        for b in range(n):
                            acc += abs(Hn[a, b])
                            acc2 += abs(Hn[a, b] - Hf[a, b])
                        hn = max(hn, acc)
                        dh = max(dh, acc2)
                    if hpm * hn >= CURV_MIN:
                        if istate[IS_HAVE_FROZEN] == 0 or not (hpm * dh <= max(CURV_STALE, CURV_STALE_REL * hpm * hn)):
                            for a in range(n):
                                for b in range(n):
                                    Hf[a, b] = Hn[a, b]
                            return step
                        curv = True
                        active = True
                if active and step >= CURV_WARMUP and (qstats[QS_CURV_REFRESH] - 1) * CURV_REFRESH_EVERY > step:
                    istate[IS_USE_CURV] = 0
                    curv = False
            if curv != (istate[IS_CURV_LAST] != 0) or qstats[QS_CURV_REFRESH] != refreshes:
                fstate[FS_ETA] = -1.0           # another frozen block: its rate is not known yet
            istate[IS_CURV_LAST] = 1 if curv else 0
            eta = fstate[FS_ETA]
            if eta >= 0.0:
                eta = max(eta, EPS) ** RATE_GROWTH
            status, it, rate, d1 = quasi_newton(model, tab, ws, qw, cw, curv, x, t, q, v, h, G, tol, quasi_max,
                                                stats, qstats, eta, fstate[FS_DREF])
            qstats[QS_ITERATIONS] += it
            if curv and status == 1:
                qstats[QS_CURV_STEPS] += 1
            if status == 1:
                istate[IS_BACKOFF] = 1
                if 0.0 <= rate < 1.0:
                    eta = rate / (1.0 - rate)
                    fstate[FS_DREF] = d1
                elif rate >= 1.0:
                    eta = -1.0                  # stopped on the round-off limit while not contracting
            else:
                eta = -1.0
                istate[IS_WAIT] = istate[IS_BACKOFF]
                istate[IS_BACKOFF] = min(2 * istate[IS_BACKOFF], QUASI_WAIT_MAX)
            fstate[FS_ETA] = eta
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
            return STEPS_FAILED
        j_out = finish_step(model, M, ws, x, x_last, x_prev, q, v, cq, cv, dq, dv, bw, sb, h, t0, step, n_steps,
                            every, compensated, stats, istate[IS_J_OUT], out_t, out_q, out_v, out_E, out_k, out_x)
        if j_out < 0:
            return STEPS_FAILED
        istate[IS_J_OUT] = j_out
    return n_steps


@numba.njit(cache=True)
def quasi_loop(model, tab, M, Minv, Ev, El, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter,
               predictor, out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats, curvature):
    """The step loop of ``spark_loop`` (same sampling, counters, failure codes and out_x layout)
    with the quasi-Newton iteration first and the Newton chain as the fallback; curvature: the
    velocity block with Hess U where it pays (CURV_N_MAX, CURV_MIN, CURV_STALE). The workspaces
    are allocated here and the steps run in ``quasi_steps``, left only for a new decomposition of
    the curvature block (``curvature_refresh``)."""
    s = tab[1].shape[0]
    n = q0.shape[0]
    m = out_k.shape[1]
    sn, sm = s * n, s * m
    NN = sn + sm + n
    ws = mech_workspace(s, n, m, M)
    qw = quasi_workspace(tab, n, m, Minv)
    J = np.zeros((NN, NN))
    piv = np.zeros(NN, dtype=np.int64)
    G = np.zeros(NN)
    x, x_last, x_prev, dq, dv, cq, cv, q, v, sb = loop_arrays(tab, q0, v0, NN)
    x_pred = np.zeros(NN)
    quasi_max = min(max_iter, QUASI_MAX_ITER)
    cw = curvature_workspace(tab, n, m, M, Minv)
    cinfo = cw[3]
    qmid = np.zeros(n)
    istate, fstate = steps_state(curvature and n <= CURV_N_MAX and cinfo[0] > 0.0)
    stats[mt.FAILED_STEP] = -1
    if not store(model, 0, t0, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
        fail(stats, 0, FAIL_NONFINITE)
        return
    step = 0
    while step < n_steps:
        step = quasi_steps(model, tab, M, Ev, El, t0, h, n_steps, every, compensated, tol, max_iter, predictor,
                           quasi_max, ws, qw, cw, J, piv, G, x, x_last, x_prev, x_pred, q, v, dq, dv, cq, cv, qmid,
                           sb, step, istate, fstate, out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats)
        if step == STEPS_FAILED:
            return
        if step < n_steps:
            istate[IS_HAVE_FROZEN] = 1 if curvature_refresh(tab, h, cw) else 0
            qstats[QS_CURV_REFRESH] += 1
            # nlu: its n LUs of I + h^2 mu_a P (uncounted before: particle, 1 refresh, 3)
            stats[4] += int(cinfo[2])
            istate[IS_REFRESHED] = 1
    for r in range(NN):
        out_x[r] = x_last[r]


QUASI_SIG = types.void(mt.MECH_MODEL, mt.TABLEAU_T, mt.a2, mt.a2, mt.a2, mt.a2, *mt.RUN, mt.a1, mt.STATS, mt.b1)


@numba.njit(cache=True, nogil=True)
def quasi_run(model, tab, M, Minv, Ev, El, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
              out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats, curvature):
    """n_steps of the SPARK method (21) for a mechanical system with the quasi-Newton root finder
    (``quasi_loop``); arguments as ``kernels.spark_run`` plus M^-1, the predictor's extrapolation
    coefficients Ev (s + 1, s), El (s, s), the quasi-Newton counters qstats (QS_*) and whether the
    velocity block carries Hess U where it pays (``curvature_matrix``)."""
    quasi_loop(model, tab, M, Minv, Ev, El, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
               out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats, curvature)
