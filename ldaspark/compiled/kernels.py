"""The compiled kernels' entry points: the SPARK method (21a-f) for mechanical systems
(``spark_run``), for general L(t, q, v), k(t, q, v) (``general_run``), and the semi-implicit
2-stage methods (25), 8.4 and (26) (``lf2_run``).

The kernels are compiled ONCE, for every system: the model (the generated functions of
``codegen``) comes in as a tuple of first-class functions whose types (``modeltypes``) do not
depend on the system, so each kernel has one signature (``SIGNATURES``). ``entry_point`` compiles
a kernel on its first use (or loads it from numba's on-disk cache, ``cache=True``: ``__pycache__``
next to this file, or numba's per-user cache directory): a fresh checkout pays only for the
kernels it runs (spark_run ~14 s, general_run ~12 s, lf2_run ~4 s of CPU). Only the small model
functions compile per system.

The helpers that run inside the step loops (``newton``, ``kernels_mech``, ``kernels_general``,
the ``evaluate`` / ``store`` dispatch below) and the generated model functions are compiled
without numba's reference counting (``_nrt=False``): they never allocate, and never hand an
array to a reference-counted caller. With it, the atomic increments and decrements on every
array argument and view were most of a step (gauss-2 on the particle: 7.5 us per step before,
2.8 us after; the semi-implicit kernel of Fig. 4 1.7x). Only the entry points, which allocate
the workspaces, count references.

All kernels work on increments (Z_i = V_i - v0, Lambda_i = h Psi_i, dv = v1 - v0), so that the
q and v updates can be summed with Kahan's compensated summation (GNI VIII.5); the Newton and
bookkeeping steps they share are in ``newton``; the residuals and Newton matrices in
``kernels_mech`` and ``kernels_general``.
"""
import threading

import numba
import numpy as np
from numba import types
from numba.extending import overload

from . import modeltypes as mt


# numba keys a cached kernel on the content of the file that defines it (this one); the helpers
# it compiles in live in sibling modules. Their digest is written here so that editing a helper
# changes this file too (tests/compiled/test_compiled_general.py checks it; update it after an edit).
HELPERS = ("newton.py", "kernels_mech.py", "kernels_general.py", "kernels_sparse.py", "modeltypes.py")
HELPERS_SHA256 = "81000f5cfcb710a9b341bb0bcdf1d8e8446ca5cd67d3523d5337b258ccb11b99"

from .newton import (FAIL_NONFINITE, FAIL_SINGULAR, accept_step, advance, end_newton, factor_newton,  # noqa: E402
                     fail, lu_factor, lu_solve, newton_increment, newton_status, norm_inf, predict, record, shift)
from .kernels_mech import mech_begin, mech_point, mech_store, mech_workspace, spark_eval, spark_eval_sparse  # noqa: E402
from .kernels_sparse import sparse_factor, sparse_increment  # noqa: E402
from .kernels_general import general_begin, general_eval, general_store, workspace  # noqa: E402


def evaluate(model, tab, jac, x, t0, q0, v0, h, M, ws, G, J):
    """Residual and Newton matrix of (21) for the model's form (chosen by numba at typing time)."""


def store(model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
    """One sample (t, q, v, E, k) for the model's form (chosen by numba at typing time)."""


def begin_step(model, t0, q0, v0, ws):
    """What a step needs before a residual without the Newton matrix (a step that reuses the
    previous step's matrix): the general form's p0 = grad_v L(t0, q0, v0); nothing for the
    mechanical form (P_i - p0 = M Z_i)."""


def factor(stats, G, J, piv):
    """Check and factor the Newton matrix (1 factored, -1 not finite, -2 singular): dense LU
    (``newton.factor_newton``) or, for the sparse workspace, ``kernels_sparse.sparse_factor``."""


def increment(J, piv, G, x):
    """x += -J^-1 G with the factored Newton matrix; returns |dx|_inf."""


def _form(model, mechanical, general):
    """The model tuple is (n, 7 mechanical functions) or (n, 5 general functions, has_N)."""
    return mechanical if len(model.types) == 8 else general


def _sparse(J):
    """The Newton matrix argument is the sparse workspace tuple (``spark_sparse_run``), not an array."""
    return isinstance(J, types.BaseTuple)


@overload(evaluate, jit_options={"_nrt": False})
def _evaluate(model, tab, jac, x, t0, q0, v0, h, M, ws, G, J):
    fn = spark_eval_sparse if _sparse(J) else _form(model, spark_eval, general_eval)
    return lambda model, tab, jac, x, t0, q0, v0, h, M, ws, G, J: fn(model, tab, jac, x, t0, q0, v0, h, M, ws, G, J)


@overload(factor, jit_options={"_nrt": False})
def _factor(stats, G, J, piv):
    if _sparse(J):
        return lambda stats, G, J, piv: sparse_factor(stats, G, J)
    return lambda stats, G, J, piv: factor_newton(stats, G, J, piv)


@overload(increment, jit_options={"_nrt": False})
def _increment(J, piv, G, x):
    if _sparse(J):
        return lambda J, piv, G, x: sparse_increment(J, G, x)
    return lambda J, piv, G, x: newton_increment(J, piv, G, x)


@overload(begin_step, jit_options={"_nrt": False})
def _begin_step(model, t0, q0, v0, ws):
    fn = _form(model, mech_begin, general_begin)
    return lambda model, t0, q0, v0, ws: fn(model, t0, q0, v0, ws)


@overload(store, jit_options={"_nrt": False})
def _store(model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
    fn = _form(model, mech_store, general_store)
    return lambda model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, ws: fn(
        model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, ws)


#: fresh Newton matrices per step in the simplified phase before the full-Newton fallback
MAX_FRESH = 8
#: ``predictor`` >= REUSE_MATRIX (predictor + REUSE_MATRIX, from ``fast.run_compiled(reuse_matrix=True)``):
#: a step starts from the LU of the previous step's Newton matrix, without a Jacobian or an LU,
#: when that step needed at most one matrix (simplified Newton across steps, RADAU5's reuse); an
#: increment that does not contract by 1/2 brings a fresh matrix as within a step
REUSE_MATRIX = 4
#: ``predictor`` // NEWTON_MODE (from ``runner.KernelOptions.newton_mode``): the root finder's
#: kind (``ldaspark.core.rootfinder.Newton``): 0 "auto" (simplified Newton with fresh matrices
#: at slow contraction, the default), 1 "full" (a matrix at every iterate), 2 "simplified" (one
#: matrix per step, no fresh ones); each followed by the full-Newton rescue from the zero start
NEWTON_MODE = 8
#: (after a reuse attempt that did not stay under REUSE_THETA the next attempt waits 1, 2, 4, ...,
#: 64 steps: where the matrix changes too fast per step, reuse is then tried rarely)
#: the matrix is kept for the next step only if every increment of this step contracted by this
#: factor (RADAU5 keeps its Jacobian while theta < 1e-3): a stale matrix that contracts more slowly
#: costs more residuals than the Jacobian and LU it saves (measured: without the bound the matrix
#: aged for thousands of steps and Newton needed 10-17 iterations per step instead of 2-3)
REUSE_THETA = 0.01


@numba.njit(cache=True, _nrt=False)
def spark_newton(model, tab, M, ws, x, t, q, v, h, G, J, piv, tol, max_iter, mode, stats, stale):
    """Newton for the step equations (21) from the guess in x; returns (status, iterations),
    status as ``newton.end_newton``. Stopping rule ``newton.newton_status`` with the round-off
    scale |v0|_inf of the stage values V_i = v0 + Z_i. full=False: simplified Newton (one
    matrix, at the guess), with a fresh matrix at the current iterate (at most MAX_FRESH per
    step) whenever an increment does not contract by 1/2 (the matrix at the predictor too far
    off, e.g. k strongly nonlinear in v, or increments at noise level, which the exact matrix
    then lets ``newton_status`` recognise); full=True: the matrix at every iterate (the generic
    engine's full Newton). Returns (status, iterations, the largest contraction rate seen).
    stale=True: J, piv already hold the LU of the previous step's
    matrix, used as it is (no Jacobian, no LU) until an increment does not contract by 1/2;
    status -3 when its first increments are not finite (the caller predicts again and starts
    with a fresh matrix). ``mode`` (``NEWTON_MODE``): 0 simplified with fresh matrices, 1 full
    (``full``), 2 simplified with the one matrix of the step (no fresh ones)."""
    full = mode == 1
    max_fresh = 0 if mode == 2 else MAX_FRESH
    scale = norm_inf(v)
    if stale:
        begin_step(model, t, q, v, ws)
        stats[2] += evaluate(model, tab, False, x, t, q, v, h, M, ws, G, J)
    else:
        stats[2] += evaluate(model, tab, True, x, t, q, v, h, M, ws, G, J)
        status = factor(stats, G, J, piv)
        if status != 1:
            return status, 0, 0.0
    prev = -1.0
    theta = -1.0            # the previous contraction rate (none yet)
    it = 0
    status = 0
    fresh = 0
    exact = not stale       # the matrix was evaluated at the iterate the next increment corrects
    worst = 0.0             # the largest contraction rate |dx_k| / |dx_k-1| of the step
    while it < max_iter:
        it += 1
        dn = increment(J, piv, G, x)
        status = newton_status(dn, prev, theta, norm_inf(x), scale, tol, exact)
        if prev > 0.0:
            worst = max(worst, dn / prev)
        if status == -1 and stale:
            return -3, it, worst
        if status != 0:
            break
        if full or (prev > 0.0 and dn > 0.5 * prev and fresh < max_fresh):
            if not full:
                fresh += 1
            stats[2] += evaluate(model, tab, True, x, t, q, v, h, M, ws, G, J)
            code = factor(stats, G, J, piv)
            if code != 1:
                return code, it, worst
            stale = False
            # a new matrix starts a new rate history (full Newton: one matrix per increment)
            theta = dn / prev if (full and prev > 0.0) else -1.0
            prev = dn if full else -1.0
            exact = True
            continue
        theta = dn / prev if prev > 0.0 else -1.0
        prev = dn
        exact = False
        stats[2] += evaluate(model, tab, False, x, t, q, v, h, M, ws, G, J)
    return status, it, worst


@numba.njit(cache=True, _nrt=False)
def finish_step(model, M, ws, x, x_last, x_prev, q, v, cq, cv, dq, dv, bw, sb, h, t0, step, n_steps, every,
                compensated, stats, j_out, out_t, out_q, out_v, out_E, out_k, out_x):
    """The end of step ``step`` of every step loop once (21) is solved in x = [Z | Lambda | dv]:
    q1 - q0 = h sum_j b_j (v0 + Z_j) and v1 - v0 = dv (compensated sums, ``accept_step``), the
    stage multipliers Psi_i = Lambda_i / h of a step that starts at a saved sample (out_x beyond
    its first NN entries) and the sample at t_{n+1} when it is saved. Returns the next sample's
    index, or -1 when the new state is not finite (the failure recorded in stats)."""
    s, n, m = bw.shape[0], q.shape[0], out_k.shape[1]
    sn, sm, NN = s * n, s * m, x.shape[0]
    for a in range(n):
        acc = 0.0
        for j in range(s):
            acc += bw[j] * x[j * n + a]
        dq[a] = h * (sb * v[a] + acc)
        dv[a] = x[sn + sm + a]
    if not accept_step(q, v, cq, cv, dq, dv, compensated, x, x_last, x_prev, stats, step):
        return -1
    if step % every == 0 and out_x.shape[0] > NN:
        o = NN + (step // every) * sm
        for r in range(sm):
            out_x[o + r] = x[sn + r] / h
    if (step + 1) % every == 0 or step + 1 == n_steps:
        if not store(model, j_out, t0 + (step + 1) * h, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
            fail(stats, step, FAIL_NONFINITE)
            return -1
        j_out += 1
    return j_out


@numba.njit(cache=True)
def loop_arrays(tab, q0, v0, NN):
    """What every step loop keeps across its steps: the unknowns x of this step and of the last two
    (the predictor's history), the increments dq, dv and Kahan compensations cq, cv of
    ``accept_step``, the state q, v (copies of q0, v0) and sum_j b_j (``finish_step``)."""
    n = q0.shape[0]
    bw = tab[4]
    sb = 0.0
    for j in range(bw.shape[0]):
        sb += bw[j]
    return (np.zeros(NN), np.zeros(NN), np.zeros(NN), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n),
            q0.copy(), v0.copy(), sb)


@numba.njit(cache=True)
def spark_loop(model, tab, M, ws, J, piv, t0, q0, v0, h, n_steps, every, compensated, tol,
               max_iter, predictor, out_t, out_q, out_v, out_E, out_k, stats, out_x):
    """The step loop of the SPARK method (21) shared by both forms: ``evaluate`` (residual and
    Newton matrix: ``kernels_mech.spark_eval`` or ``kernels_general.general_eval``) and ``store``
    (one sample) are resolved from the model's type when numba compiles each entry point.
    (Passing the functions as values would keep numba from caching the kernels.)

    Newton per step, a fallback chain: simplified Newton from the predictor (with fresh matrices,
    ``spark_newton``); if it does not converge (or meets a singular or non-finite matrix or
    increment), full Newton from the generic engine's starting guess (V_i = v1 = v0, Psi = 0),
    as ``SparkMethod.step`` with newton="full", counted in stats[FULL_NEWTON_STEPS]; if that
    fails too, the failure (step, code, iterations of both phases) is recorded and out_x[0]
    receives the residual |G|_inf at the last iterate. out_x[:NN] receives the last step's
    unknowns; where out_x is longer, out_x[NN + j s m:NN + (j + 1) s m] receives the multipliers
    Psi_1..Psi_s (m each) of the step starting at sample j. J, piv: the Newton matrix's storage, a
    dense matrix and its pivots, or the sparse workspace (``sparse_workspace``) and a dummy."""
    s = tab[1].shape[0]
    n = q0.shape[0]
    m = out_k.shape[1]
    sn, sm = s * n, s * m
    NN = sn + sm + n
    G = np.zeros(NN)
    x, x_last, x_prev, dq, dv, cq, cv, q, v, sb = loop_arrays(tab, q0, v0, NN)
    bw = tab[4]
    stats[mt.FAILED_STEP] = -1
    if not store(model, 0, t0, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
        fail(stats, 0, FAIL_NONFINITE)
        return
    mode = predictor // NEWTON_MODE            # the root finder's kind: see NEWTON_MODE
    reuse = (predictor // REUSE_MATRIX) % 2 == 1 and mode != 1   # bit REUSE_MATRIX: see REUSE_MATRIX
    predictor = predictor % REUSE_MATRIX
    have = False            # J, piv hold the LU of a matrix of the last step, fit for reuse
    wait, backoff = 0, 1    # steps before the next reuse attempt after a failed one, and its growth
    j_out = 1
    for step in range(n_steps):
        t = t0 + step * h
        predict(x, x_last, x_prev, step, predictor)
        nj = stats[3]
        stale = reuse and have and wait == 0
        if wait > 0:
            wait -= 1
        status, it, worst = spark_newton(model, tab, M, ws, x, t, q, v, h, G, J, piv, tol, max_iter, mode,
                                         stats, stale)
        if status == -3:
            # the reused matrix sent the first increments to inf/NaN: predict again, fresh matrix
            predict(x, x_last, x_prev, step, predictor)
            status, it2, worst = spark_newton(model, tab, M, ws, x, t, q, v, h, G, J, piv, tol, max_iter, mode,
                                              stats, False)
            it += it2
        # reuse the matrix next step if this step needed at most one and contracted fast with it
        have = status == 1 and stats[3] - nj <= 1 and worst <= REUSE_THETA
        if stale:
            # a reuse attempt that did not stay fast: wait 1, 2, 4, ... 64 steps before the next
            if have:
                backoff = 1
            else:
                wait = backoff
                backoff = min(2 * backoff, 64)
        if status != 1:
            have = False
            # fallback: full Newton from the generic engine's starting guess
            stats[mt.FULL_NEWTON_STEPS] += 1
            for r in range(NN):
                x[r] = 0.0
            status, it2, worst = spark_newton(model, tab, M, ws, x, t, q, v, h, G, J, piv, tol, max_iter, 1,
                                              stats, False)
            it += it2
        if status != 1:
            stats[2] += evaluate(model, tab, False, x, t, q, v, h, M, ws, G, J)
            out_x[0] = norm_inf(G)
        if not end_newton(stats, step, it, status):
            return
        j_out = finish_step(model, M, ws, x, x_last, x_prev, q, v, cq, cv, dq, dv, bw, sb, h, t0, step, n_steps,
                            every, compensated, stats, j_out, out_t, out_q, out_v, out_E, out_k, out_x)
        if j_out < 0:
            return
    for r in range(NN):
        out_x[r] = x_last[r]


SPARK_SIG = types.void(mt.MECH_MODEL, mt.TABLEAU_T, mt.a2, *mt.RUN, mt.a1)


@numba.njit(cache=True, nogil=True)
def spark_run(model, tab, M, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
              out_t, out_q, out_v, out_E, out_k, stats, out_x):
    """n_steps of the SPARK method (21) for a mechanical system from (t0, q0, v0); samples every
    ``every`` steps and the last step; out_x receives the last step's unknowns."""
    s, n, m = tab[1].shape[0], q0.shape[0], out_k.shape[1]
    ws = mech_workspace(s, n, m, M)
    NN = s * (n + m) + n
    spark_loop(model, tab, M, ws, np.zeros((NN, NN)), np.zeros(NN, dtype=np.int64), t0, q0, v0, h, n_steps,
               every, compensated, tol, max_iter, predictor, out_t, out_q, out_v, out_E, out_k, stats, out_x)


SPARSE_SIG = types.void(mt.MECH_MODEL, mt.TABLEAU_T, mt.a2, *mt.RUN, mt.a1, *(mt.STATS,) * 7)


@numba.njit(cache=True)
def sparse_workspace(s, m, perm, pattern_ptr, pattern_col, pattern_slot, row_ptr, col_pos, diag_slot):
    """The sparse Newton workspace of ``kernels_sparse`` for the structure of ``sparse.NewtonStructure``."""
    n = perm.shape[0]
    b = s + 1
    ny, sm = b * n, s * m
    return (perm, pattern_ptr, pattern_col, pattern_slot, row_ptr, col_pos, diag_slot,
            np.zeros((col_pos.shape[0], b, b)), np.zeros((n, b, b)), np.zeros((ny, sm)), np.zeros((sm, ny)),
            np.zeros((ny, sm)), np.zeros((sm, sm)), np.zeros(sm, dtype=np.int64), np.zeros(ny), np.zeros(sm),
            np.zeros((b, b)), np.zeros(n, dtype=np.int64), np.zeros(b))


@numba.njit(cache=True, nogil=True)
def spark_sparse_run(model, tab, M, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
                     out_t, out_q, out_v, out_E, out_k, stats, out_x, perm, pattern_ptr, pattern_col,
                     pattern_slot, row_ptr, col_pos, diag_slot):
    """``spark_run`` with the Newton matrix factored by blocks (``sparse``, ``kernels_sparse``):
    the same iterates up to the rounding of the linear solves, at a cost per step that grows
    with the nonzeros of Hess U, d(K^T lam)/dq and M instead of n^3."""
    s, n, m = tab[1].shape[0], q0.shape[0], out_k.shape[1]
    ws = mech_workspace(s, n, m, M)
    sp = sparse_workspace(s, m, perm, pattern_ptr, pattern_col, pattern_slot, row_ptr, col_pos, diag_slot)
    spark_loop(model, tab, M, ws, sp, np.zeros(1, dtype=np.int64), t0, q0, v0, h, n_steps, every, compensated,
               tol, max_iter, predictor, out_t, out_q, out_v, out_E, out_k, stats, out_x)


GENERAL_SIG = types.void(mt.GEN_MODEL, mt.TABLEAU_T, mt.a2, *mt.RUN, mt.a1)


@numba.njit(cache=True, nogil=True)
def general_run(model, tab, M, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
                out_t, out_q, out_v, out_E, out_k, stats, out_x):
    """n_steps of the SPARK method (21) for general L(t, q, v), k(t, q, v) (``kernels_general``;
    M is unused); same sampling, counters and failure codes as ``spark_run``."""
    s, n, m = tab[1].shape[0], q0.shape[0], out_k.shape[1]
    ws = workspace(s, n, m)
    NN = s * (n + m) + n
    spark_loop(model, tab, M, ws, np.zeros((NN, NN)), np.zeros(NN, dtype=np.int64), t0, q0, v0, h, n_steps,
               every, compensated, tol, max_iter, predictor, out_t, out_q, out_v, out_E, out_k, stats, out_x)


@numba.njit(cache=True, _nrt=False)
def lf2_store(model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, kK, kb, kout):
    """Sample j of the semi-implicit kernel; False if not finite."""
    return record(j, t, q, v, mech_point(model, t, q, v, M, kK, kb, kout), kout, out_t, out_q, out_v, out_E, out_k)


LF2_SIG = types.void(mt.MECH_MODEL, types.int64, mt.a2, mt.a2, *mt.RUN)


@numba.njit(cache=True, nogil=True)
def lf2_run(model, variant, M, Minv, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
            out_t, out_q, out_v, out_E, out_k, stats):
    """Semi-implicit 2-stage methods with Newton on the m multipliers only (Lambda = h Psi).

    variant 0, Lobatto IIIA-B SPARK (25): M Z1 = -h/2 grad U(q0) - 1/2 K(q0)^T Lambda_1,
      0 = (k(q0, V1) + k(q1, V1))/2, q1 = q0 + h V1; then M dv + K(q1)^T mu = M Z1 - h/2 grad U(q1),
      K(q1) v1 + b(q1) = 0.
    variant 1, modified (8.4): constraint k(t0 + h/2, q0 + h/2 V1, V1) = 0 instead.
    variant 2, McLachlan-Perlmutter (26): Q1 = q0 + h/2 v0, M dv = -h grad U(Q1) - K(Q1)^T Lambda,
      q1 = q0 + h/2 (v0 + v1), 0 = K(q1) v1 + b(q1).

    One function of ~190 lines: the step is ~0.4 us, and the same code split into helper
    functions taking a workspace tuple measured 3-5x slower per step, at a time when numba
    counted references on every array of such a tuple at every call (the helpers now compile
    without reference counting, see the module docstring; the split was not measured again)."""
    grad_U, K_of, b_of, kq_of = model[1], model[3], model[4], model[5]
    n = q0.shape[0]
    m = out_k.shape[1]
    q, v = q0.copy(), v0.copy()
    cq, cv, g0, g1, u0 = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    Z, V1, q1, dq, dv = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    K0, K1, kq1, kK = np.zeros((m, n)), np.zeros((m, n)), np.zeros((m, n)), np.zeros((m, n))
    B0, B1, D, S = np.zeros((n, m)), np.zeros((n, m)), np.zeros((m, m)), np.zeros((m, m))
    b0, b1, cres, lam, lam_last = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros(m), np.zeros(m)
    lam_prev, mu, kb, kout = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros(m)
    piv = np.zeros(m, dtype=np.int64)
    predictor = predictor % 4      # the REUSE_MATRIX flag concerns the SPARK kernels only
    half = 0.5 * h
    stats[mt.FAILED_STEP] = -1
    if not lf2_store(model, 0, t0, q, v, M, out_t, out_q, out_v, out_E, out_k, kK, kb, kout):
        fail(stats, 0, FAIL_NONFINITE)
        return
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
        predict(lam, lam_last, lam_prev, step, predictor)
        # round-off scale of lam = h Psi: the velocity |v0| it must resolve, through Z = u0 - B0 lam
        bn = 0.0
        for a in range(n):
            acc = 0.0
            for l in range(m):
                acc += abs(B0[a, l])
            bn = max(bn, acc)
        floor = norm_inf(v) / bn if bn > 0.0 else 0.0
        status, prev, theta, it = 0, -1.0, -1.0, 0
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
                    fail(stats, step, FAIL_SINGULAR)
                    return
                stats[4] += 1
            for l in range(m):
                cres[l] = -cres[l]
            lu_solve(D, piv, cres)
            for l in range(m):
                lam[l] += cres[l]
            dn = norm_inf(cres)
            # (one matrix per step: the semi-implicit Newton has no fresh-matrix phase)
            status = newton_status(dn, prev, theta, norm_inf(lam), floor, tol, True)
            if status != 0:
                break
            theta = dn / prev if prev > 0.0 else -1.0
            prev = dn
        if not end_newton(stats, step, it, status):
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
                fail(stats, step, FAIL_SINGULAR)
                return
            lu_solve(S, piv, mu)
            for a in range(n):
                acc = 0.0
                for l in range(m):
                    acc += B1[a, l] * mu[l]
                dv[a] -= acc
        if not advance(q, v, cq, cv, dq, dv, compensated):
            fail(stats, step, FAIL_NONFINITE)
            return
        shift(lam, lam_last, lam_prev)
        stats[0] += 1
        if (step + 1) % every == 0 or step + 1 == n_steps:
            if not lf2_store(model, j_out, t0 + (step + 1) * h, q, v, M, out_t, out_q, out_v, out_E, out_k,
                                  kK, kb, kout):
                fail(stats, step, FAIL_NONFINITE)
                return
            j_out += 1


_COMPILE_LOCK = threading.Lock()
SIGNATURES = {"spark_run": SPARK_SIG, "general_run": GENERAL_SIG, "lf2_run": LF2_SIG,
              "spark_sparse_run": SPARSE_SIG}


def entry_point(name):
    """The compiled entry point of kernel ``name`` for its one signature, compiled or loaded from
    the cache now if not yet (once, whatever the threads); the dispatcher then accepts no other
    signature, as an eagerly compiled ``njit(sig)`` would not."""
    disp = globals()[name]
    sig = SIGNATURES[name]
    with _COMPILE_LOCK:
        cres = disp.overloads.get(tuple(sig.args))
        if cres is not None:
            return cres.entry_point
        ep = disp.compile(sig)
        disp.disable_compile()
        return ep
