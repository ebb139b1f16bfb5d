"""The quasi-Newton root finder of the SPARK step (21) for general L(t, q, v), k(t, q, v) (ideal
constraints): the analogue of ``kernels_quasi`` with the velocity block frozen at the Hessians
L_vv at the predictor.

The Newton matrix of (21b, d, e, f) in x = [Z | Lambda | dv] (``kernels_general.general_jacobian``)
is replaced by

    [ diag_i L_vv,i     0      A~ (x) K^T ]    rows (21b): P_i - p0 - h sum A^_ij L_q,j + sum A~_ij K_j^T Lambda_j
    [      0          L_vv,1   b~ (x) K^T ]    row  (21d)
    [     C_Z          C_dv        0      ]    rows (21e), (21f), exact (``newton.constraint_rows``)

with L_vv,i = L_vv(T_i, Q_i, V_i), L_vv,1 at (t1, q1, v1), K = k_v and k_q at the stages and the end
point, all at the predictor: the O(h) terms h a_ik L_vq,i - h a^_ik L_qv,k + a~_ik d(K^T Lambda)/dv
and the O(h^2) ones dropped. Eliminating Z and dv (s + 1 LUs of n x n) leaves the (s m) x (s m)
multiplier system S dLambda = G_c - C_Z y - C_dv y_s, y_i = L_vv,i^-1 G_i, with the columns
S[:, (j, l)] = C_Z (A~_ij L_vv,i^-1 K_j^T e_l)_i + C_dv b~_j L_vv,1^-1 K_j^T e_l, formed and factored
once per step. The residual is the exact one, so the iteration converges to the root of (21)
the Newton engine finds; its contraction rate is O(h |L_vq| / |L_vv| + h |Lambda| |K_v|).
Predictor, stopping rule, fallback to the compiled Newton chain, waits and counters: as
``kernels_quasi`` (the mechanical form's module, whose constants and predictor it uses).
"""
import numba
import numpy as np
from numba import types

from . import modeltypes as mt
from .kernels import finish_step, loop_arrays, spark_newton, evaluate, store   # noqa: F401 (evaluate: the overload spark_newton uses)
from .kernels_general import general_begin, general_eval, workspace
from .kernels_quasi import (EPS, FIRST_RATE_FACTOR, PREDICT_COLLOCATION, QS_FALLBACKS, QS_ITERATIONS, QS_LU,
                            QS_RATE_FIRST, QS_SKIPPED, QS_STEPS, QUASI_MAX_ITER, QUASI_THETA, QUASI_WAIT_MAX,
                            RATE_GROWTH, RATE_SPAN, collocation_predict, constraint_apply, FS_DREF, FS_ETA,
                            IS_BACKOFF, IS_J_OUT, IS_WAIT, STEPS_FAILED, steps_state)
from .newton import (FAIL_NONFINITE, RATE_KAPPA, end_newton, fail, lu_factor, lu_solve, newton_status,
                     norm_inf, predict)

# numba keys a cached kernel on the content of this file only: the digest of the modules it
# compiles in (tests/compiled/test_quasi_general.py checks it)
HELPERS = ("kernels.py", "newton.py", "kernels_mech.py", "kernels_general.py", "kernels_sparse.py",
           "modeltypes.py", "kernels_quasi.py")
HELPERS_SHA256 = "2564a8e3816ae0f0293b7493e4245f8809562f8cc8eba23cf2b923a1d3cb7ebb"


@numba.njit(cache=True)
def general_quasi_workspace(s, n, m):
    """The frozen K (s, m, n), k_q (s, m, n), K(t1), k_q(t1) (m, n); the LUs of L_vv at the stages
    and the end point (s + 1, n, n) and their pivots; the responses of (21b, d) to each multiplier
    (s m, (s + 1) n); S and its pivots; y ((s + 1) n); the multiplier right-hand side (s m);
    scratch z (s, n), Ky, kz (s, m), a column (n), C y (s m)."""
    N1 = (s + 1) * n
    return (np.zeros((s, m, n)), np.zeros((s, m, n)), np.zeros((m, n)), np.zeros((m, n)), np.zeros((s + 1, n, n)),
            np.zeros((s + 1, n), dtype=np.int64), np.zeros((s * m, N1)), np.zeros((s * m, s * m)),
            np.zeros(s * m, dtype=np.int64), np.zeros(N1), np.zeros(s * m), np.zeros((s, n)), np.zeros((s, m)),
            np.zeros((s, m)), np.zeros(n), np.zeros(s * m))


@numba.njit(cache=True, _nrt=False)
def general_multiplier_matrix(model, tab, h, t, x, ws, gw, stats):
    """At the stage values of the last residual: L_vv, k_q at the stages and the end point
    (``point_jac``), K = k_v from the residual, the LUs of L_vv and the factored S (module
    docstring). False if an L_vv or S is singular. Each L_vv factorisation is counted in nlu
    (stats[4]); S is counted by the caller (qstats[QS_LU], added to nlu by ``quasi.run_quasi``)."""
    point_jac = model[2]
    A, At, bw, bt, om = tab[1], tab[3], tab[4], tab[6], tab[7]
    T, Q, V, kv, Lvv, Lvq, Lqq, kq, KRq, KRv = ws[0], ws[1], ws[2], ws[6], ws[8], ws[9], ws[10], ws[11], ws[12], ws[13]
    q1, v1, kv1, Lvv1, Lvq1, Lqq1, kq1, KRq1, KRv1, zl = (ws[14], ws[15], ws[19], ws[20], ws[21], ws[22], ws[23],
                                                          ws[24], ws[25], ws[26])
    Kf, kqf, K1f, kq1f, LUv, pv, Wc, S, spiv, yv, rhs, z, Ky, kz, col = gw[:15]
    s, n, m = A.shape[0], q1.shape[0], zl.shape[0]
    sn = s * n
    for j in range(s):
        point_jac(T[j], Q[j], V[j], x[sn + j * m:sn + (j + 1) * m], Lvv[j], Lvq[j], Lqq[j], kq[j], KRq[j], KRv[j])
    point_jac(t + h, q1, v1, zl, Lvv1, Lvq1, Lqq1, kq1, KRq1, KRv1)
    for j in range(s + 1):
        for a in range(n):
            for b in range(n):
                LUv[j, a, b] = Lvv[j, a, b] if j < s else Lvv1[a, b]
        stats[4] += 1       # nlu: an LU factorisation like any other (it said 1 a step for s + 2)
        if not lu_factor(LUv[j], pv[j]):
            return False
    for j in range(s):
        for ll in range(m):
            for b in range(n):
                Kf[j, ll, b] = kv[j, ll, b]
                kqf[j, ll, b] = kq[j, ll, b]
    for ll in range(m):
        for b in range(n):
            K1f[ll, b] = kv1[ll, b]
            kq1f[ll, b] = kq1[ll, b]
    for j in range(s):
        for ll in range(m):
            c = j * m + ll
            for i in range(s + 1):
                w = At[i, j] if i < s else bt[j]
                for a in range(n):
                    col[a] = w * Kf[j, ll, a]
                lu_solve(LUv[i], pv[i], col)
                for a in range(n):
                    Wc[c, i * n + a] = col[a]
            constraint_apply(A, bw, om, h, Kf, kqf, K1f, kq1f, z, Ky, kz, Wc[c], rhs)
            for r in range(s * m):
                S[r, c] = rhs[r]
    return lu_factor(S, spiv)


@numba.njit(cache=True, _nrt=False)
def general_quasi_increment(tab, h, gw, G, x):
    """x += dx, the solution of the frozen system for the residual G; |dx|_inf."""
    A, bw, om = tab[1], tab[4], tab[7]
    Kf, kqf, K1f, kq1f, LUv, pv, Wc, S, spiv, yv, rhs, z, Ky, kz, col, r2 = gw
    s, n, m = A.shape[0], Kf.shape[2], Kf.shape[1]
    sn, sm = s * n, s * m
    N1 = sn + n
    for i in range(s + 1):
        for a in range(n):
            col[a] = G[i * n + a]
        lu_solve(LUv[i], pv[i], col)
        for a in range(n):
            yv[i * n + a] = col[a]
    constraint_apply(A, bw, om, h, Kf, kqf, K1f, kq1f, z, Ky, kz, yv, r2)
    for r in range(sm):
        rhs[r] = G[N1 + r] - r2[r]
    lu_solve(S, spiv, rhs)
    dn = 0.0
    for c in range(sm):
        d = rhs[c]
        x[sn + c] += d
        ad = abs(d)
        if ad > dn or ad != ad:
            dn = ad
    for r in range(N1):
        acc = yv[r]
        for c in range(sm):
            acc += Wc[c, r] * rhs[c]
        x[r if r < sn else r + sm] -= acc
        ad = abs(acc)
        if ad > dn or ad != ad:
            dn = ad
    return dn


@numba.njit(cache=True, _nrt=False)
def general_quasi_newton(model, tab, M, ws, gw, x, t, q, v, h, G, J, tol, max_iter, stats, qstats, eta, dref):
    """``kernels_quasi.quasi_newton`` for the general form: (status, iterations, rate, |dx_1|), eta
    the carried rate estimate of the first-increment test, measured on a first increment of dref."""
    scale = norm_inf(v)
    general_begin(model, t, q, v, ws)
    stats[2] += general_eval(model, tab, False, x, t, q, v, h, M, ws, G, J)
    qstats[QS_LU] += 1       # the multiplier matrix: derivatives, not residual points (nfev)
    if not general_multiplier_matrix(model, tab, h, t, x, ws, gw, stats):
        return 0, 0, -1.0, -1.0
    prev = -1.0
    d1 = -1.0
    theta = -1.0
    rate = -1.0
    it = 0
    status = 0
    while it < max_iter:
        it += 1
        dn = general_quasi_increment(tab, h, gw, G, x)
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
            th = dn / prev
            lim = tol * (norm_inf(x) + scale)
            if th < 1.0 and th / (1.0 - th) * dn <= RATE_KAPPA * lim and dn <= FIRST_RATE_FACTOR * lim:
                status = 1
        if prev > 0.0:          # the slowest ratio of the step (``kernels_quasi.quasi_newton``)
            rate = max(rate, dn / prev)
        if status != 0:
            break
        if prev > 0.0 and dn > QUASI_THETA * prev:
            break
        theta = dn / prev if prev > 0.0 else -1.0
        prev = dn
        stats[2] += general_eval(model, tab, False, x, t, q, v, h, M, ws, G, J)
    return status, it, rate, d1


@numba.njit(cache=True, _nrt=False)
def general_quasi_steps(model, tab, M, Ev, El, t0, h, n_steps, every, compensated, tol, max_iter, predictor,
                        quasi_max, ws, gw, J, piv, G, x, x_last, x_prev, x_pred, q, v, dq, dv, cq, cv, sb, istate,
                        fstate, out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats):
    """The steps of ``general_quasi_loop`` in one call that is not reference counted (as
    ``kernels_quasi.quasi_steps``; the state in istate, fstate with its IS_*, FS_* entries);
    n_steps when done, STEPS_FAILED when a step failed (recorded in stats). The predictor, the
    carried rate and the Newton chain repeat ``quasi_steps``' lines on purpose: as functions of their
    own the step got slower (numba-inlined: skate gauss-6 2.04 -> 2.82 us; called: particle gauss-6
    3.45 -> 3.85 us, the arrays passed by value every step), stop 65."""
    s = tab[1].shape[0]
    n = q.shape[0]
    m = out_k.shape[1]
    sn, sm = s * n, s * m
    NN = sn + sm + n
    bw = tab[4]
    for step in range(n_steps):
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
            eta = fstate[FS_ETA]
            if eta >= 0.0:
                eta = max(eta, EPS) ** RATE_GROWTH
            status, it, rate, d1 = general_quasi_newton(model, tab, M, ws, gw, x, t, q, v, h, G, J, tol, quasi_max,
                                                        stats, qstats, eta, fstate[FS_DREF])
            qstats[QS_ITERATIONS] += it
            if status == 1:
                istate[IS_BACKOFF] = 1
                if 0.0 <= rate < 1.0:
                    eta = rate / (1.0 - rate)
                    fstate[FS_DREF] = d1
                elif rate >= 1.0:
                    eta = -1.0
            else:
                eta = -1.0
                istate[IS_WAIT] = istate[IS_BACKOFF]
                istate[IS_BACKOFF] = min(2 * istate[IS_BACKOFF], QUASI_WAIT_MAX)
            fstate[FS_ETA] = eta
        if status == 1:
            qstats[QS_STEPS] += 1
        else:
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
def general_quasi_loop(model, tab, M, Ev, El, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter,
                       predictor, out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats):
    """``kernels_quasi.quasi_loop`` for the general form (no curvature variant: L_vv is the block):
    the workspaces allocated here, the steps run in ``general_quasi_steps``."""
    s = tab[1].shape[0]
    n = q0.shape[0]
    m = out_k.shape[1]
    sn, sm = s * n, s * m
    NN = sn + sm + n
    ws = workspace(s, n, m)
    gw = general_quasi_workspace(s, n, m)
    J = np.zeros((NN, NN))
    piv = np.zeros(NN, dtype=np.int64)
    G = np.zeros(NN)
    x, x_last, x_prev, dq, dv, cq, cv, q, v, sb = loop_arrays(tab, q0, v0, NN)
    x_pred = np.zeros(NN)
    quasi_max = min(max_iter, QUASI_MAX_ITER)
    istate, fstate = steps_state(False)
    stats[mt.FAILED_STEP] = -1
    if not store(model, 0, t0, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
        fail(stats, 0, FAIL_NONFINITE)
        return
    if general_quasi_steps(model, tab, M, Ev, El, t0, h, n_steps, every, compensated, tol, max_iter, predictor,
                           quasi_max, ws, gw, J, piv, G, x, x_last, x_prev, x_pred, q, v, dq, dv, cq, cv, sb, istate,
                           fstate, out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats) == STEPS_FAILED:
        return
    for r in range(NN):
        out_x[r] = x_last[r]


GENERAL_QUASI_SIG = types.void(mt.GEN_MODEL, mt.TABLEAU_T, mt.a2, mt.a2, mt.a2, *mt.RUN, mt.a1, mt.STATS)


@numba.njit(cache=True, nogil=True)
def general_quasi_run(model, tab, M, Ev, El, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
                      out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats):
    """n_steps of the SPARK method (21) for a general ideal system with the quasi-Newton root
    finder (``general_quasi_loop``); arguments as ``kernels.general_run`` plus the predictor's
    extrapolation coefficients Ev, El and the counters qstats (``kernels_quasi.QS_*``)."""
    general_quasi_loop(model, tab, M, Ev, El, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
                       out_t, out_q, out_v, out_E, out_k, stats, out_x, qstats)
