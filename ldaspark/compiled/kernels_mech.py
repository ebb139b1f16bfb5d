"""Residual and Newton matrix of the SPARK method (21) for mechanical systems (section 7,
L = 1/2 v^T M v - U(t, q), k = K(t, q) v + b(t, q)), and one step of the semi-implicit
2-stage methods (25), 8.4 and (26). Called by the entry points in ``kernels``.

The model is the tuple ``codegen.mechanical_source`` exports:
(n, grad_U, hess_U, K_of, b_of, kq_of, KTlam_q, U_of).
"""
import numba
import numpy as np

from .newton import FAIL_SINGULAR, constraint_rows, stage_points, end_newton, fail, lu_factor, lu_solve, newton_status, norm_inf, record


@numba.njit(cache=True)
def mech_point(model, t, q, v, M, kK, kb, kout):
    """E = 1/2 v^T M v + U (8) at one point; kout = k = K v + b."""
    K_of, b_of, U_of = model[3], model[4], model[7]
    n = q.shape[0]
    e = U_of(t, q)
    for a in range(n):
        s = 0.0
        for b in range(n):
            s += M[a, b] * v[b]
        e += 0.5 * v[a] * s
    K_of(t, q, kK)
    b_of(t, q, kb)
    for l in range(kK.shape[0]):
        s = kb[l]
        for a in range(n):
            s += kK[l, a] * v[a]
        kout[l] = s
    return e


@numba.njit(cache=True)
def mech_workspace(s, n, m):
    """T, Q, V, grad U, K^T Lambda, K, b, k at the stages; Hess U, d(K^T Lambda)/dq, k_q at the
    stages; q1, v1, K, b, k_q at the end point; k scratch."""
    return (np.zeros(s), np.zeros((s, n)), np.zeros((s, n)), np.zeros((s, n)), np.zeros((s, n)),
            np.zeros((s, m, n)), np.zeros((s, m)), np.zeros((s, m)), np.zeros((s, n, n)), np.zeros((s, n, n)),
            np.zeros((s, m, n)), np.zeros(n), np.zeros(n), np.zeros((m, n)), np.zeros(m), np.zeros((m, n)),
            np.zeros(m))


@numba.njit(cache=True)
def mech_store(model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
    """Sample j (end-point arrays of ws as scratch); False if not finite."""
    e = mech_point(model, t, q, v, M, ws[13], ws[14], ws[16])
    return record(j, t, q, v, e, ws[16], out_t, out_q, out_v, out_E, out_k)


@numba.njit(cache=True)
def spark_eval(model, tab, jac, x, t0, q0, v0, h, M, ws, G, J):
    """Residual G of (21b, d, e, f) in the increment unknowns x = [Z | Lambda | dv] and, if jac,
    its Jacobian J. gU = grad U = -F, KTL_j = K_j^T Lambda_j = -h R_j; P_i - p0 = M Z_i exactly.
    Returns the number of points evaluated."""
    grad_U, K_of, b_of = model[1], model[3], model[4]
    c, A, Ah, At, bw, bh, bt, om = tab
    T, Q, V, gU, KTL, KK, bb, kst, H, Rq, kq, q1, v1, K1, b1, kq1, kout = ws
    s, n, m = A.shape[0], q0.shape[0], K1.shape[0]
    sn, sm = s * n, s * m
    t1 = t0 + h
    stage_points(tab, x, t0, q0, v0, h, m, T, Q, V, q1, v1)
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
    # (21b): M Z_i + h sum_j A^_ij grad U_j + sum_j A~_ij K_j^T Lambda_j; (21d) likewise
    for i in range(s + 1):
        off = i * n if i < s else sn + sm
        for a in range(n):
            acc = 0.0
            for b in range(n):
                acc += M[a, b] * x[off + b]
            acc2 = 0.0
            acc3 = 0.0
            for j in range(s):
                wh = Ah[i, j] if i < s else bh[j]
                wt = At[i, j] if i < s else bt[j]
                acc2 += wh * gU[j, a]
                acc3 += wt * KTL[j, a]
            G[i * n + a] = acc + h * acc2 + acc3
    # (21e), (21f)
    re0 = sn + n
    for l in range(s - 1):
        for mm in range(m):
            acc = 0.0
            for j in range(s):
                acc += om[l, j] * kst[j, mm]
            G[re0 + l * m + mm] = acc
    rf0 = re0 + (s - 1) * m
    for mm in range(m):
        acc = b1[mm]
        for a in range(n):
            acc += K1[mm, a] * v1[a]
        G[rf0 + mm] = acc
    if jac:
        spark_jacobian(model, tab, x, t0, h, M, ws, J)
        return 2 * s + 1
    return s + 1


@numba.njit(cache=True)
def spark_jacobian(model, tab, x, t0, h, M, ws, J):
    """d(21b, d, e, f)/d(Z, Lambda, dv) at the stage values of the last ``spark_eval``."""
    hess_U, kq_of, KTlam_q = model[2], model[5], model[6]
    c, A, Ah, At, bw, bh, bt, om = tab
    T, Q, V, gU, KTL, KK, bb, kst, H, Rq, kq, q1, v1, K1, b1, kq1, kout = ws
    s, n, m = A.shape[0], q1.shape[0], K1.shape[0]
    sn = s * n
    for j in range(s):
        hess_U(T[j], Q[j], H[j])
        KTlam_q(T[j], Q[j], x[sn + j * m:sn + (j + 1) * m], Rq[j])
        kq_of(T[j], Q[j], V[j], kq[j])
    kq_of(t0 + h, q1, v1, kq1)
    J[:, :] = 0.0
    h2 = h * h
    # (21b) rows i < s and (21d) row i = s
    for i in range(s + 1):
        for k in range(s):
            for a in range(n):
                for b in range(n):
                    acc = M[a, b] if i == k else 0.0
                    for j in range(s):
                        wh = Ah[i, j] if i < s else bh[j]
                        wt = At[i, j] if i < s else bt[j]
                        acc += h2 * wh * A[j, k] * H[j, a, b] + h * wt * A[j, k] * Rq[j, a, b]
                    J[i * n + a, k * n + b] = acc
                wt = At[i, k] if i < s else bt[k]
                for l in range(m):
                    J[i * n + a, sn + k * m + l] = wt * KK[k, l, a]
    constraint_rows(tab, h, KK, kq, K1, kq1, M, J)


@numba.njit(cache=True)
def lf2_constraint(model, variant, t, q, v, Z, h, ws):
    """The multiplier equation c(lam) = 0 of the semi-implicit step at Z = u0 - B0 lam; returns
    the time of the constraint point (q1 holds its position, V1 = v0 + Z)."""
    K_of, b_of = model[3], model[4]
    K0, b0, K1, b1, V1, q1, cres = ws[2], ws[3], ws[4], ws[5], ws[11], ws[12], ws[13]
    n, m = q.shape[0], K0.shape[0]
    half = 0.5 * h
    for a in range(n):
        V1[a] = v[a] + Z[a]
        if variant == 0:
            q1[a] = q[a] + h * V1[a]
        elif variant == 1:
            q1[a] = q[a] + half * V1[a]
        else:
            q1[a] = q[a] + h * v[a] + half * Z[a]
    tc = t + half if variant == 1 else t + h
    K_of(tc, q1, K1)
    b_of(tc, q1, b1)
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
    return tc


@numba.njit(cache=True)
def lf2_matrix(model, variant, tc, h, ws):
    """dc/dlam at the predictor (simplified Newton: factorised once per step)."""
    kq_of = model[5]
    K0, K1, kq1, B0, V1, q1, D, piv = ws[2], ws[4], ws[6], ws[7], ws[11], ws[12], ws[14], ws[16]
    n, m = q1.shape[0], K0.shape[0]
    kq_of(tc, q1, V1, kq1)
    fq = h if variant == 0 else 0.5 * h
    for l in range(m):
        for r in range(m):
            acc = 0.0
            for a in range(n):
                Cla = K1[l, a] + fq * kq1[l, a]
                if variant == 0:
                    Cla = 0.5 * (Cla + K0[l, a])
                acc += Cla * B0[a, r]
            D[l, r] = -acc
    return lu_factor(D, piv)


@numba.njit(cache=True)
def lf2_explicit(model, variant, Minv, t, q, v, h, ws):
    """u0 and B0 = M^-1 K^T at the stage where grad U and K are frozen."""
    grad_U, K_of, b_of = model[1], model[3], model[4]
    g0, K0, b0, B0, u0, q1 = ws[0], ws[2], ws[3], ws[7], ws[9], ws[12]
    n, m = q.shape[0], K0.shape[0]
    half = 0.5 * h
    if variant == 2:
        for a in range(n):
            q1[a] = q[a] + half * v[a]
        grad_U(t + half, q1, g0)
        K_of(t + half, q1, K0)
        fu, fb = h, 1.0
    else:
        grad_U(t, q, g0)
        K_of(t, q, K0)
        b_of(t, q, b0)
        fu, fb = half, 0.5
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


@numba.njit(cache=True)
def lf2_velocity(lam, ws):
    """Z = u0 - B0 lam, the velocity increment (V1 - v0, or v1 - v0 for variant 2)."""
    B0, u0, Z = ws[7], ws[9], ws[10]
    for a in range(Z.shape[0]):
        acc = 0.0
        for l in range(lam.shape[0]):
            acc += B0[a, l] * lam[l]
        Z[a] = u0[a] - acc


@numba.njit(cache=True)
def lf2_step(model, variant, M, Minv, t, q, v, cv, h, tol, max_iter, lam, dq, dv, ws, stats, step):
    """One step of the semi-implicit method ``variant`` (see ``kernels.lf2_run``) with Newton on
    the m multipliers lam only: fills dq, dv; False after recording a failure in stats.
    variant 0, Lobatto IIIA-B SPARK (25): M Z1 = -h/2 grad U(q0) - 1/2 K(q0)^T Lambda_1,
      0 = (k(q0, V1) + k(q1, V1))/2, q1 = q0 + h V1; then M dv + K(q1)^T mu = M Z1 - h/2 grad U(q1),
      K(q1) v1 + b(q1) = 0.
    variant 1, modified (8.4): constraint k(t0 + h/2, q0 + h/2 V1, V1) = 0 instead.
    variant 2, McLachlan-Perlmutter (26): Q1 = q0 + h/2 v0, M dv = -h grad U(Q1) - K(Q1)^T Lambda,
      q1 = q0 + h/2 (v0 + v1), 0 = K(q1) v1 + b(q1)."""
    Z, V1, q1, cres, D, piv = ws[10], ws[11], ws[12], ws[13], ws[14], ws[16]
    n, m = q.shape[0], lam.shape[0]
    lf2_explicit(model, variant, Minv, t, q, v, h, ws)
    stats[2] += 1
    status, prev = 0, -1.0
    floor = abs(h) * (1.0 + norm_inf(v))
    for it in range(1, max_iter + 1):
        lf2_velocity(lam, ws)
        tc = lf2_constraint(model, variant, t, q, v, Z, h, ws)
        stats[2] += 1
        if it == 1:
            stats[3] += 1
            if not lf2_matrix(model, variant, tc, h, ws):
                fail(stats, step, FAIL_SINGULAR)
                return False
            stats[4] += 1
        for l in range(m):
            cres[l] = -cres[l]
        lu_solve(D, piv, cres)
        for l in range(m):
            lam[l] += cres[l]
        status = newton_status(norm_inf(cres), prev, norm_inf(lam), floor, tol)
        if status != 0:
            break
        prev = norm_inf(cres)
    if not end_newton(stats, step, it, status):
        return False
    lf2_velocity(lam, ws)
    if variant == 2:
        for a in range(n):
            dq[a] = h * v[a] + 0.5 * h * Z[a]
            dv[a] = Z[a]
        return True
    for a in range(n):
        V1[a] = v[a] + Z[a]
        dq[a] = h * V1[a]
        q1[a] = q[a] + dq[a]
    return lf2_second_stage(model, M, Minv, t + h, v, cv, h, dv, ws, stats, step)


@numba.njit(cache=True)
def lf2_second_stage(model, M, Minv, t1, v, cv, h, dv, ws, stats, step):
    """M dv + K(q1)^T mu = M Z - h/2 grad U(q1), K(q1)(v0 + dv) + b(q1) = 0 (a linear solve)."""
    grad_U, K_of, b_of = model[1], model[3], model[4]
    g1, K1, b1, B1, Z, q1, S, piv, mu = ws[1], ws[4], ws[5], ws[8], ws[10], ws[12], ws[15], ws[16], ws[17]
    n, m = v.shape[0], K1.shape[0]
    grad_U(t1, q1, g1)
    K_of(t1, q1, K1)
    b_of(t1, q1, b1)
    stats[2] += 1
    for a in range(n):
        acc = 0.0
        for b in range(n):
            acc += Minv[a, b] * g1[b]
        dv[a] = Z[a] - 0.5 * h * acc
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
        fail(stats, step, FAIL_SINGULAR)
        return False
    lu_solve(S, piv, mu)
    for a in range(n):
        acc = 0.0
        for l in range(m):
            acc += B1[a, l] * mu[l]
        dv[a] -= acc
    return True
