"""Linear algebra and the Newton / bookkeeping steps every compiled kernel shares (plain numba
functions, compiled into the kernels of ``kernels`` that call them).

Newton is simplified Newton (one LU per step) from an extrapolating predictor, stopped by
``newton_status`` (a limit scaled with the round-off of the stage values, and RADAU5's rate
test); the fallback chain (fresh Newton matrix at the iterate, then full Newton from the generic
engine's starting guess) is in ``kernels.spark_newton``. stats holds the counters of
``fast.STAT_NAMES``; a failure sets stats[FAILED_STEP], stats[FAILURE] (``modeltypes`` codes:
Newton did not converge, singular Newton matrix, NaN/inf) and stats[FAILED_ITERATIONS].
"""
import numba
import numpy as np

from . import modeltypes as mt

FAIL_NEWTON, FAIL_SINGULAR, FAIL_NONFINITE = mt.FAIL_NEWTON, mt.FAIL_SINGULAR, mt.FAIL_NONFINITE


@numba.njit(cache=True, _nrt=False)
def lu_factor(A, piv):
    """In-place LU with partial pivoting (LAPACK getrf order); False if singular or not finite."""
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


@numba.njit(cache=True, _nrt=False)
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


@numba.njit(cache=True, _nrt=False)
def norm_inf(x):
    """max |x_i|, NaN if any entry is NaN."""
    r = 0.0
    for i in range(x.shape[0]):
        a = abs(x[i])
        if a > r or a != a:
            r = a
    return r


@numba.njit(cache=True, _nrt=False)
def matrix_finite(J):
    for r in range(J.shape[0]):
        for c in range(J.shape[1]):
            if not np.isfinite(J[r, c]):
                return False
    return True


@numba.njit(cache=True, _nrt=False)
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


@numba.njit(cache=True, _nrt=False)
def advance(q, v, cq, cv, dq, dv, compensated):
    """q += dq, v += dv (compensated or not); False when the new state is not finite."""
    add_to(q, cq, dq, compensated)
    add_to(v, cv, dv, compensated)
    return np.isfinite(norm_inf(q)) and np.isfinite(norm_inf(v))


@numba.njit(cache=True, _nrt=False)
def accept_step(q, v, cq, cv, dq, dv, compensated, x, x_last, x_prev, stats, step):
    """q += dq, v += dv, the unknowns x into the predictor's history, one step counted; False
    (failure recorded) when the new state is not finite."""
    if not advance(q, v, cq, cv, dq, dv, compensated):
        fail(stats, step, FAIL_NONFINITE)
        return False
    shift(x, x_last, x_prev)
    stats[0] += 1
    return True


@numba.njit(cache=True, _nrt=False)
def predict(x, x_last, x_prev, step, predictor):
    """Starting guess: 2 = linear extrapolation of the last two steps' unknowns, 1 = the last
    step's, 0 = zero increments (V_i = v1 = v0, Psi = 0)."""
    for r in range(x.shape[0]):
        if step >= 2 and predictor == 2:
            x[r] = 2.0 * x_last[r] - x_prev[r]
        elif step >= 1 and predictor >= 1:
            x[r] = x_last[r]
        else:
            x[r] = 0.0


@numba.njit(cache=True, _nrt=False)
def shift(x, x_last, x_prev):
    for r in range(x.shape[0]):
        x_prev[r] = x_last[r]
        x_last[r] = x[r]


@numba.njit(cache=True, _nrt=False)
def newton_increment(LU, piv, G, x):
    """Simplified Newton update x += -J^-1 G with J factored in LU (G is overwritten by the
    increment); returns |dx|_inf."""
    for r in range(G.shape[0]):
        G[r] = -G[r]
    lu_solve(LU, piv, G)
    for r in range(G.shape[0]):
        x[r] += G[r]
    return norm_inf(G)


#: increments that stopped contracting (theta >= 1/2) are accepted as round-off noise when they are
#: within NOISE_FACTOR of the round-off limit and were computed with a Newton matrix evaluated at
#: the iterate they correct (the matrix is then exact to first order, so a stalled Newton
#: iteration can only be stalled by the rounding of the residual: its noise, amplified by
#: cond(J), is what the increments measure)
NOISE_FACTOR = 1e3
#: RADAU5's kappa: the rate test accepts an estimated remaining error of kappa lim ~ 1 unit
#: round-off of the stage values (lim = 8 eps (|x| + |v0|)), so that stopping on the estimate
#: leaves the step as accurate as one more increment would (the estimate alone at kappa = 1 moved
#: 1000-step runs by ~1e-12, against ~3e-14 between the engines with a plain |dx| test)
RATE_KAPPA = 0.1


@numba.njit(cache=True, _nrt=False)
def newton_status(dn, prev, theta_prev, xn, scale, tol, exact):
    """1 converged, 0 continue, -1 increment not finite. lim = tol (|x| + scale) is the round-off
    of the stage values: the unknowns x are increments (Z_i = V_i - v0, Lambda_i, dv) and the
    stage values V_i = v0 + Z_i carry eps (|v0| + |Z_i|) of rounding, so ``scale`` = |v0|_inf
    (the caller's; the semi-implicit kernel converts it to multiplier units). The limit scales
    with the state and does not depend on h (an h-proportional limit, tol (|x| + h (1 + |v0|)),
    fell below the rounding of V_i at h <= 1e-5 and failed runs spuriously).
    Converged: |dx| <= lim; or the estimate theta/(1 - theta) |dx| <= lim of the remaining error
    of a contracting iteration (Hairer-Wanner IV.8, RADAU5's stopping rule with kappa tol = RATE_KAPPA lim),
    with RADAU5's rate theta = sqrt(theta_k theta_k-1), theta_k = |dx_k| / |dx_k-1| (theta_prev
    = theta_k-1, <= 0 when there is none yet: one sudden drop of |dx|, e.g. onto a noise floor
    far above round-off, is no evidence of contraction); or the round-off floor: the increments
    stopped shrinking (theta_k >= 1/2) at most NOISE_FACTOR lim and ``exact`` (matrix at the
    iterate)."""
    if not np.isfinite(dn):
        return -1
    lim = tol * (xn + scale)
    if dn <= lim:
        return 1
    if prev <= 0.0:
        return 0
    theta_k = dn / prev
    if theta_prev > 0.0:
        theta = np.sqrt(theta_k * theta_prev)
        if theta < 1.0 and theta / (1.0 - theta) * dn <= RATE_KAPPA * lim:
            return 1
    if exact and theta_k >= 0.5 and dn <= NOISE_FACTOR * lim:
        return 1
    return 0


@numba.njit(cache=True, _nrt=False)
def fail(stats, step, code):
    stats[mt.FAILED_STEP] = step
    stats[mt.FAILURE] = code


@numba.njit(cache=True, _nrt=False)
def end_newton(stats, step, it, status):
    """Count the iterations; on failure record why and after how many iterations (False: the
    kernel must return). status: 1 converged, 0 not converged, -1 not finite, -2 singular."""
    stats[1] += it
    if it > stats[5]:
        stats[5] = it
    if status == 1:
        return True
    stats[mt.FAILED_ITERATIONS] = it
    fail(stats, step, FAIL_NONFINITE if status == -1 else (FAIL_SINGULAR if status == -2 else FAIL_NEWTON))
    return False


@numba.njit(cache=True, _nrt=False)
def factor_newton(stats, G, J, piv):
    """Checks and factors the Newton matrix J (residual G at the same point): 1 factored, -1 not
    finite, -2 singular (the codes of ``end_newton``)."""
    stats[3] += 1
    if not (np.isfinite(norm_inf(G)) and matrix_finite(J)):
        return -1
    stats[4] += 1
    if not lu_factor(J, piv):
        return -2
    return 1


@numba.njit(cache=True, _nrt=False)
def record(j, t, q, v, E, k, out_t, out_q, out_v, out_E, out_k):
    """Store one sample; False when the energy or the constraint is not finite."""
    out_t[j] = t
    for a in range(q.shape[0]):
        out_q[j, a] = q[a]
        out_v[j, a] = v[a]
    out_E[j] = E
    for l in range(k.shape[0]):
        out_k[j, l] = k[l]
    return np.isfinite(E) and np.isfinite(norm_inf(k))


@numba.njit(cache=True, _nrt=False)
def constraint_rows(tab, h, Kst, kq, K1, kq1, P1v, J):
    """The rows of the Newton matrix both SPARK forms share, with Kst, kq = K, k_q at the stages
    and K1, kq1, P1v = K, k_q, dp/dv at the end point: d(21d)/dv1 = P1v,
    d(21e)_l/dV_k = omega_lk K_k + h sum_j omega_lj a_jk k_q,j, d(21f)/dV_k = h b_k k_q(t1, q1, v1),
    d(21f)/dv1 = K(t1, q1, v1)."""
    c, A, Ah, At, bw, bh, bt, om = tab
    s, m, n = kq.shape[0], kq.shape[1], kq.shape[2]
    sn, sm = s * n, s * m
    re0, rf0 = sn + n, sn + n + (s - 1) * m
    for a in range(n):
        for b in range(n):
            J[sn + a, sn + sm + b] = P1v[a, b]
    # accumulated in J over j in order, the coefficient formed once per (l, k, j): the same
    # products and sums as a sum per entry
    for l in range(s - 1):
        for k in range(s):
            for mm in range(m):
                for b in range(n):
                    J[re0 + l * m + mm, k * n + b] = om[l, k] * Kst[k, mm, b]
            for j in range(s):
                cj = h * om[l, j] * A[j, k]
                for mm in range(m):
                    for b in range(n):
                        J[re0 + l * m + mm, k * n + b] += cj * kq[j, mm, b]
    for mm in range(m):
        for k in range(s):
            for b in range(n):
                J[rf0 + mm, k * n + b] = h * bw[k] * kq1[mm, b]
        for b in range(n):
            J[rf0 + mm, sn + sm + b] = K1[mm, b]


@numba.njit(cache=True, _nrt=False)
def stage_points(tab, x, t0, q0, v0, h, m, T, Q, V, q1, v1):
    """(21a), (21c) from the increments x = [Z | Lambda | dv]: T_i = t0 + c_i h, V_i = v0 + Z_i,
    Q_i = q0 + h sum_j a_ij V_j, q1 = q0 + h sum_j b_j V_j, v1 = v0 + dv."""
    c, A, bw = tab[0], tab[1], tab[4]
    s, n = A.shape[0], q0.shape[0]
    off = s * n + s * m
    for i in range(s):
        T[i] = t0 + c[i] * h
        for a in range(n):
            V[i, a] = v0[a] + x[i * n + a]
    for a in range(n):
        for i in range(s):
            acc = 0.0
            for j in range(s):
                acc += A[i, j] * V[j, a]
            Q[i, a] = q0[a] + h * acc
        acc = 0.0
        for j in range(s):
            acc += bw[j] * V[j, a]
        q1[a] = q0[a] + h * acc
        v1[a] = v0[a] + x[off + a]
