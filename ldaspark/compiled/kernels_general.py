"""Residual and Newton matrix of the SPARK method (21) for general L(t, q, v), k(t, q, v):
the same equations as ``ldaspark.core.spark.SparkMethod.residual``, with the momentum map
implicit ((21b) and (21d) are solved for V_i and v1 directly). Called by ``kernels.general_run``.

The model is the tuple ``codegen.general_source`` exports: (n, point_val, point_jac, energy,
nonideal, nonideal_jac, has_N), with point_val -> grad_v L, grad_q L, k, K = k_v and point_jac ->
L_vv, L_vq, L_qq, k_q and KRq, KRv = the q- and v-partials of K^T lam (= -h R of (21) with
lam = Lambda for ideal constraints); nonideal -> N(t, q, v, psi) and nonideal_jac -> N_q, N_v,
N_psi of 3.3. For a system without N, has_N is False and the nonideal terms below are skipped
without a call, so that the ideal path is the code it was before N (a model call per stage and
five more arrays in the workspace tuple passed to every helper measured 4-8% of the step of an
ideal n = 3 system; the flag and one flat array 1-2%).
With N: -h R_i = K_i^T Lambda_i - h N(T_i, Q_i, V_i, Lambda_i / h) (Lambda = h Psi), so the
stage reaction gains -h N, its q- and v-partials -h N_q, -h N_v, and d(-h R_i)/dLambda_i =
K_i^T - N_psi (as ``LagrangianSystem.stage`` with ``h``; the end point carries no reaction).
Workspace ``ws`` (see ``workspace``): stage arrays, end-point arrays, p0 = grad_v L(t0, q0, v0),
then one flat array holding N, N_q, N_v, N_psi at the stages and psi (``nonideal_views``).
"""
import numba
import numpy as np

from .newton import constraint_rows, record, stage_points


@numba.njit(cache=True)
def workspace(s, n, m):
    """Zeroed arrays; the model never writes structurally zero entries, so they stay zero."""
    return (np.zeros(s), np.zeros((s, n)), np.zeros((s, n)), np.zeros((s, n)), np.zeros((s, n)),
            np.zeros((s, m)), np.zeros((s, m, n)), np.zeros((s, n)),
            np.zeros((s, n, n)), np.zeros((s, n, n)), np.zeros((s, n, n)), np.zeros((s, m, n)),
            np.zeros((s, n, n)), np.zeros((s, n, n)),
            np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(m), np.zeros((m, n)),
            np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n)), np.zeros((m, n)), np.zeros((n, n)),
            np.zeros((n, n)), np.zeros(m), np.zeros(n), np.zeros(s * n * (1 + 2 * n + m) + m))


@numba.njit(cache=True, _nrt=False)
def nonideal_views(nw, s, n, m):
    """N (s, n), N_q (s, n, n), N_v (s, n, n), N_psi (s, n, m) at the stages and psi (m) as views
    of the workspace's flat array (zero-initialised: the model writes only nonzero entries)."""
    sn, snn = s * n, s * n * n
    o2, o3, o4 = sn + snn, sn + 2 * snn, sn + 2 * snn + sn * m
    return (nw[:sn].reshape((s, n)), nw[sn:o2].reshape((s, n, n)), nw[o2:o3].reshape((s, n, n)),
            nw[o3:o4].reshape((s, n, m)), nw[o4:o4 + m])


@numba.njit(cache=True, _nrt=False)
def nonideal_stages(model, jac, x, T, Q, V, h, nw, KTL):
    """-h R_j = K_j^T Lambda_j - h N(T_j, Q_j, V_j, Lambda_j / h) (3.3): subtracts h N from
    KTL = K^T Lambda and, if jac, evaluates N_q, N_v, N_psi at the stages."""
    nonideal, nonideal_jac = model[4], model[5]
    s, n = KTL.shape[0], KTL.shape[1]
    m = (x.shape[0] - s * n - n) // s
    sn = s * n
    Nst, Nq, Nv, Np, psi = nonideal_views(nw, s, n, m)
    for j in range(s):
        for l in range(m):
            psi[l] = x[sn + j * m + l] / h
        nonideal(T[j], Q[j], V[j], psi, Nst[j])
        if jac:
            nonideal_jac(T[j], Q[j], V[j], psi, Nq[j], Nv[j], Np[j])
        for a in range(n):
            KTL[j, a] -= h * Nst[j, a]


@numba.njit(cache=True, _nrt=False)
def general_begin(model, t0, q0, v0, ws):
    """p0 = grad_v L(t0, q0, v0) into ws[27] (as the first ``general_eval`` with jac does), for a
    step whose first residual reuses the previous step's Newton matrix."""
    model[1](t0, q0, v0, ws[27], ws[17], ws[18], ws[19])


@numba.njit(cache=True, _nrt=False)
def general_eval(model, tab, jac, x, t0, q0, v0, h, M, ws, G, J):
    """Residual G of (21b, d, e, f) in x = [Z | Lambda | dv] (V_i = v0 + Z_i, v1 = v0 + dv) and,
    if jac, its Jacobian J. The first call of a step (jac) also sets ws[27] = p0 = grad_v L(t0,
    q0, v0). M is unused (the signature is that of ``kernels_mech.spark_eval``). Returns the
    stage points of the residual, s + 1 (``nfev``'s meaning on every engine)."""
    point_val, point_jac = model[1], model[2]
    if jac:
        point_val(t0, q0, v0, ws[27], ws[17], ws[18], ws[19])
    c, A, Ah, At, bw, bh, bt, om = tab
    (T, Q, V, Lv, Lq, kst, kv, KTL, Lvv, Lvq, Lqq, kq, KRq, KRv,
     q1, v1, Lv1, Lq1, k1, kv1, Lvv1, Lvq1, Lqq1, kq1, KRq1, KRv1, zl, p0) = ws[:28]
    s, n, m = A.shape[0], q0.shape[0], k1.shape[0]
    sn = s * n
    stage_points(tab, x, t0, q0, v0, h, m, T, Q, V, q1, v1)
    for j in range(s):
        point_val(T[j], Q[j], V[j], Lv[j], Lq[j], kst[j], kv[j])
        for a in range(n):
            acc = 0.0
            for l in range(m):
                acc += kv[j, l, a] * x[sn + j * m + l]
            KTL[j, a] = acc
    if model[6]:                 # has_N: the nonideal term (3.3) in the stage reactions
        nonideal_stages(model, jac, x, T, Q, V, h, ws[28], KTL)
    point_val(t0 + h, q1, v1, Lv1, Lq1, k1, kv1)
    # (21b) rows i < s, (21d) row i = s: P_i - p0 - h sum_j A^_ij F_j + sum_j A~_ij K_j^T Lambda_j
    for i in range(s + 1):
        for a in range(n):
            acc2 = 0.0
            acc3 = 0.0
            for j in range(s):
                acc2 += (Ah[i, j] if i < s else bh[j]) * Lq[j, a]
                acc3 += (At[i, j] if i < s else bt[j]) * KTL[j, a]
            P = Lv[i, a] if i < s else Lv1[a]
            G[i * n + a] = (P - p0[a]) - h * acc2 + acc3
    re0 = sn + n
    for l in range(s - 1):                                   # (21e)
        for mm in range(m):
            acc = 0.0
            for j in range(s):
                acc += om[l, j] * kst[j, mm]
            G[re0 + l * m + mm] = acc
    for mm in range(m):                                      # (21f)
        G[re0 + (s - 1) * m + mm] = k1[mm]
    if jac:
        for j in range(s):
            point_jac(T[j], Q[j], V[j], x[sn + j * m:sn + (j + 1) * m], Lvv[j], Lvq[j], Lqq[j], kq[j],
                      KRq[j], KRv[j])
        point_jac(t0 + h, q1, v1, zl, Lvv1, Lvq1, Lqq1, kq1, KRq1, KRv1)
        general_jacobian(tab, h, ws, J)
        if model[6]:
            nonideal_jacobian(tab, h, ws[28], m, J)
    return s + 1          # nfev counts the residual's stage points on every engine; njev the Jacobians


@numba.njit(cache=True, _nrt=False)
def general_jacobian(tab, h, ws, J):
    """d(21b, d, e, f)/d(Z, Lambda, dv): with dX_j/dV_k = delta_jk X_v(j) + h a_jk X_q(j),
    d(21b)_i/dV_k = delta_ik L_vv,i + h a_ik L_vq,i - h a^_ik L_qv,k - h^2 sum_j a^_ij a_jk L_qq,j
    + a~_ik KRv_k + h sum_j a~_ij a_jk KRq_j, d(21b)_i/dLambda_k = a~_ik K_k^T; (21d) alike with
    b, b^, b~ and dp1/dV_k = h b_k L_vq(t1, q1, v1), dp1/dv1 = L_vv(t1, q1, v1)."""
    c, A, Ah, At, bw, bh, bt, om = tab
    (T, Q, V, Lv, Lq, kst, kv, KTL, Lvv, Lvq, Lqq, kq, KRq, KRv,
     q1, v1, Lv1, Lq1, k1, kv1, Lvv1, Lvq1, Lqq1, kq1, KRq1, KRv1, zl, p0) = ws[:28]
    s, n, m = A.shape[0], q1.shape[0], k1.shape[0]
    sn = s * n
    J[:, :] = 0.0
    h2 = h * h
    # the sum over j accumulated in J block by block, h a~_ij and h^2 a^_ij formed once per
    # (i, k, j) instead of once per entry: the same products and sums in the same order
    for i in range(s + 1):
        for k in range(s):
            wk_h = Ah[i, k] if i < s else bh[k]
            wk_t = At[i, k] if i < s else bt[k]
            r0, c0 = i * n, k * n
            for a in range(n):
                for b in range(n):
                    if i < s:
                        acc = h * A[i, k] * Lvq[i, a, b] + (Lvv[i, a, b] if i == k else 0.0)
                    else:
                        acc = h * bw[k] * Lvq1[a, b]
                    J[r0 + a, c0 + b] = acc + (wk_t * KRv[k, a, b] - h * wk_h * Lvq[k, b, a])
            for j in range(s):
                wh = Ah[i, j] if i < s else bh[j]
                wt = At[i, j] if i < s else bt[j]
                ct = h * wt
                ch = h2 * wh
                ajk = A[j, k]
                for a in range(n):
                    for b in range(n):
                        J[r0 + a, c0 + b] += ajk * (ct * KRq[j, a, b] - ch * Lqq[j, a, b])
            for a in range(n):
                for l in range(m):
                    J[i * n + a, sn + k * m + l] = wk_t * kv[k, l, a]
    constraint_rows(tab, h, kv, kq, kv1, kq1, Lvv1, J)


@numba.njit(cache=True, _nrt=False)
def nonideal_jacobian(tab, h, nw, m, J):
    """The nonideal term's part of d(21b, d)/d(Z, Lambda) (3.3), added to ``general_jacobian``:
    -h N(T_j, Q_j, V_j, Lambda_j / h) in -h R_j gives d(21b)_i/dV_k += -h a~_ik N_v,k
    - h^2 sum_j a~_ij a_jk N_q,j and d(21b)_i/dLambda_k += -a~_ik N_psi,k; (21d) alike with b~.
    The model's output arrays are left as written (their structural zeros must stay zero)."""
    A, At, bt = tab[1], tab[3], tab[6]
    s = A.shape[0]
    n = (J.shape[0] - s * m) // (s + 1)
    sn = s * n
    Nst, Nq, Nv, Np, psi = nonideal_views(nw, s, n, m)
    h2 = h * h
    for i in range(s + 1):
        for k in range(s):
            wk_t = At[i, k] if i < s else bt[k]
            for a in range(n):
                for b in range(n):
                    acc = -h * wk_t * Nv[k, a, b]
                    for j in range(s):
                        wt = At[i, j] if i < s else bt[j]
                        acc -= h2 * wt * A[j, k] * Nq[j, a, b]
                    J[i * n + a, k * n + b] += acc
                for l in range(m):
                    J[i * n + a, sn + k * m + l] -= wk_t * Np[k, a, l]


@numba.njit(cache=True, _nrt=False)
def general_store(model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
    """Sample j: the energy (8) and k at (t, q, v) (end-point arrays of ws as scratch; M unused)."""
    point_val, energy = model[1], model[3]
    Lv1, Lq1, k1, kv1 = ws[16], ws[17], ws[18], ws[19]
    point_val(t, q, v, Lv1, Lq1, k1, kv1)
    return record(j, t, q, v, energy(t, q, v), k1, out_t, out_q, out_v, out_E, out_k)
