"""Residual and Newton matrix of the SPARK method (21) for mechanical systems (section 7,
L = 1/2 v^T M v - U(t, q), k = K(t, q) v + b(t, q)). Called by the entry points in ``kernels``.

The model is the tuple ``codegen.mechanical_source`` exports:
(n, grad_U, hess_U, K_of, b_of, kq_of, KTlam_q, U_of).
"""
import numba
import numpy as np

from .kernels_sparse import sparse_assemble
from .newton import constraint_rows, record, stage_points


@numba.njit(cache=True, _nrt=False)
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
def mech_workspace(s, n, m, M):
    """T, Q, V, grad U, K^T Lambda, K, b, k at the stages; Hess U, d(K^T Lambda)/dq, k_q at the
    stages; q1, v1, K, b, k_q at the end point; k scratch; M in CSR (row pointers, columns,
    values: the residual's M Z_i costs nnz(M), not n^2, per stage)."""
    nnz = 0
    for a in range(n):
        for b in range(n):
            if M[a, b] != 0.0:
                nnz += 1
    Mp, Mj, Mx = np.zeros(n + 1, dtype=np.int64), np.zeros(nnz, dtype=np.int64), np.zeros(nnz)
    e = 0
    for a in range(n):
        for b in range(n):
            if M[a, b] != 0.0:
                Mj[e] = b
                Mx[e] = M[a, b]
                e += 1
        Mp[a + 1] = e
    return (np.zeros(s), np.zeros((s, n)), np.zeros((s, n)), np.zeros((s, n)), np.zeros((s, n)),
            np.zeros((s, m, n)), np.zeros((s, m)), np.zeros((s, m)), np.zeros((s, n, n)), np.zeros((s, n, n)),
            np.zeros((s, m, n)), np.zeros(n), np.zeros(n), np.zeros((m, n)), np.zeros(m), np.zeros((m, n)),
            np.zeros(m), Mp, Mj, Mx)


@numba.njit(cache=True, _nrt=False)
def mech_store(model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
    """Sample j (end-point arrays of ws as scratch); False if not finite."""
    e = mech_point(model, t, q, v, M, ws[13], ws[14], ws[16])
    return record(j, t, q, v, e, ws[16], out_t, out_q, out_v, out_E, out_k)


@numba.njit(cache=True, _nrt=False)
def mech_begin(model, t0, q0, v0, ws):
    """Nothing: the mechanical residual needs no per-step value before the first residual."""
    return


@numba.njit(cache=True, _nrt=False)
def spark_eval(model, tab, jac, x, t0, q0, v0, h, M, ws, G, J):
    """Residual G of (21b, d, e, f) in the increment unknowns x = [Z | Lambda | dv] and, if jac,
    its Jacobian J (dense). Returns the stage points of the residual (s + 1: the meaning of
    ``nfev`` on every engine; the Jacobian's own evaluations are counted by ``njev``)."""
    mech_residual(model, tab, x, t0, q0, v0, h, ws, G)
    if jac:
        mech_jacobian_parts(model, tab, x, t0, h, ws)
        spark_jacobian(tab, h, M, ws, J)
    return tab[0].shape[0] + 1


@numba.njit(cache=True, _nrt=False)
def spark_eval_sparse(model, tab, jac, x, t0, q0, v0, h, M, ws, G, sp):
    """``spark_eval`` with the Newton matrix assembled by blocks into the sparse workspace sp
    (``kernels_sparse.sparse_assemble``)."""
    mech_residual(model, tab, x, t0, q0, v0, h, ws, G)
    if jac:
        mech_jacobian_parts(model, tab, x, t0, h, ws)
        sparse_assemble(tab, h, M, ws[8], ws[9], ws[5], ws[10], ws[13], ws[15], sp)
    return tab[0].shape[0] + 1


@numba.njit(cache=True, _nrt=False, inline="always")
def mech_residual(model, tab, x, t0, q0, v0, h, ws, G):
    """Residual G of (21b, d, e, f) in the increment unknowns x = [Z | Lambda | dv].
    gU = grad U = -F, KTL_j = K_j^T Lambda_j = -h R_j; P_i - p0 = M Z_i exactly."""
    grad_U, K_of, b_of = model[1], model[3], model[4]
    c, A, Ah, At, bw, bh, bt, om = tab
    T, Q, V, gU, KTL, KK, bb, kst, H, Rq, kq, q1, v1, K1, b1, kq1, kout, Mp, Mj, Mx = ws
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
            for e in range(Mp[a], Mp[a + 1]):
                acc += Mx[e] * x[off + Mj[e]]
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


@numba.njit(cache=True, _nrt=False)
def mech_jacobian_parts(model, tab, x, t0, h, ws):
    """Hess U, d(K^T Lambda)/dq, k_q at the stages and k_q at the end point, at the stage values
    of the last ``mech_residual``."""
    hess_U, kq_of, KTlam_q = model[2], model[5], model[6]
    T, Q, V, H, Rq, kq, q1, v1, K1, kq1 = ws[0], ws[1], ws[2], ws[8], ws[9], ws[10], ws[11], ws[12], ws[13], ws[15]
    s, n, m = T.shape[0], q1.shape[0], K1.shape[0]
    sn = s * n
    for j in range(s):
        hess_U(T[j], Q[j], H[j])
        KTlam_q(T[j], Q[j], x[sn + j * m:sn + (j + 1) * m], Rq[j])
        kq_of(T[j], Q[j], V[j], kq[j])
    kq_of(t0 + h, q1, v1, kq1)


@numba.njit(cache=True, _nrt=False)
def spark_jacobian(tab, h, M, ws, J):
    """d(21b, d, e, f)/d(Z, Lambda, dv), dense, from ``mech_jacobian_parts``."""
    c, A, Ah, At, bw, bh, bt, om = tab
    KK, H, Rq, kq, q1, K1, kq1 = ws[5], ws[8], ws[9], ws[10], ws[11], ws[13], ws[15]
    s, n, m = A.shape[0], q1.shape[0], K1.shape[0]
    sn = s * n
    J[:, :] = 0.0
    h2 = h * h
    # (21b) rows i < s and (21d) row i = s. Each entry is M_ab delta_ik + sum_j (h^2 a^_ij a_jk
    # Hess U_j + h a~_ij a_jk d(K^T Lambda)_j/dq) summed over j in order, accumulated in J block by
    # block: the coefficients are formed once per (i, k, j) instead of once per entry (the
    # same products in the same order as a sum per entry, so the same bits; 3-4x cheaper)
    for i in range(s + 1):
        for k in range(s):
            r0, c0 = i * n, k * n
            for a in range(n):
                for b in range(n):
                    J[r0 + a, c0 + b] = M[a, b] if i == k else 0.0
            for j in range(s):
                wh = Ah[i, j] if i < s else bh[j]
                wt = At[i, j] if i < s else bt[j]
                ch = h2 * wh * A[j, k]
                ct = h * wt * A[j, k]
                for a in range(n):
                    for b in range(n):
                        J[r0 + a, c0 + b] += ch * H[j, a, b] + ct * Rq[j, a, b]
            wt = At[i, k] if i < s else bt[k]
            for a in range(n):
                for l in range(m):
                    J[r0 + a, sn + k * m + l] = wt * KK[k, l, a]
    constraint_rows(tab, h, KK, kq, K1, kq1, M, J)
