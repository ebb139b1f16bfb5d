"""The compiled kernels' entry points: the SPARK method (21a-f) for mechanical systems
(``spark_run``), for general L(t, q, v), k(t, q, v) (``general_run``), and the semi-implicit
2-stage methods (25), 8.4 and (26) (``lf2_run``).

The kernels are compiled ONCE, for every system: the model (the generated functions of
``codegen``) comes in as a tuple of first-class functions whose types (``modeltypes``) do not
depend on the system, so each kernel has one explicit signature, is compiled eagerly when this
module is imported and cached on disk by numba (``cache=True``: ``__pycache__`` next to this
file, or numba's per-user cache directory). Only the small model functions compile per system.

All kernels work on increments (Z_i = V_i - v0, Lambda_i = h Psi_i, dv = v1 - v0), so that the
q and v updates can be summed with Kahan's compensated summation (GNI VIII.5); the Newton and
bookkeeping steps they share are in ``newton``; the residuals and Newton matrices in
``kernels_mech`` and ``kernels_general``.
"""
import numba
import numpy as np
from numba import types
from numba.extending import overload

from . import modeltypes as mt


# numba keys a cached kernel on the content of the file that defines it (this one); the helpers
# it compiles in live in sibling modules. Their digest is written here so that editing a helper
# changes this file too (tests/test_compiled_general.py checks it; update it after an edit).
HELPERS = ("newton.py", "kernels_mech.py", "kernels_general.py", "modeltypes.py")
HELPERS_SHA256 = "c236d564a2d31bc537b2f69c158aed67a305b7ede0886a88395f830f873292f8"

from .newton import (FAIL_NONFINITE, accept_step, end_newton, fail, newton_increment, newton_status,  # noqa: E402
                     norm_inf, predict, record, start_newton)
from .kernels_mech import lf2_step, mech_point, mech_store, mech_workspace, spark_eval  # noqa: E402
from .kernels_general import general_eval, general_store, workspace  # noqa: E402


def evaluate(model, tab, jac, x, t0, q0, v0, h, M, ws, G, J):
    """Residual and Newton matrix of (21) for the model's form (chosen by numba at typing time)."""


def store(model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
    """One sample (t, q, v, E, k) for the model's form (chosen by numba at typing time)."""


def _form(model, mechanical, general):
    """The model tuple is (n, 7 mechanical functions) or (n, 3 general functions)."""
    return mechanical if len(model.types) == 8 else general


@overload(evaluate)
def _evaluate(model, tab, jac, x, t0, q0, v0, h, M, ws, G, J):
    fn = _form(model, spark_eval, general_eval)
    return lambda model, tab, jac, x, t0, q0, v0, h, M, ws, G, J: fn(model, tab, jac, x, t0, q0, v0, h, M, ws, G, J)


@overload(store)
def _store(model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
    fn = _form(model, mech_store, general_store)
    return lambda model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, ws: fn(
        model, j, t, q, v, M, out_t, out_q, out_v, out_E, out_k, ws)


@numba.njit(cache=True)
def spark_loop(model, tab, M, ws, t0, q0, v0, h, n_steps, every, compensated, tol,
               max_iter, predictor, out_t, out_q, out_v, out_E, out_k, stats, out_x):
    """The step loop of the SPARK method (21) shared by both forms: ``evaluate`` (residual and
    Newton matrix: ``kernels_mech.spark_eval`` or ``kernels_general.general_eval``) and ``store``
    (one sample) are resolved from the model's type when numba compiles each entry point.
    (Passing the functions as values would keep numba from caching the kernels.)"""
    s = tab[1].shape[0]
    n = q0.shape[0]
    m = out_k.shape[1]
    sn, sm = s * n, s * m
    NN = sn + sm + n
    G, J = np.zeros(NN), np.zeros((NN, NN))
    piv = np.zeros(NN, dtype=np.int64)
    x, x_last, x_prev = np.zeros(NN), np.zeros(NN), np.zeros(NN)
    dq, dv, cq, cv = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    q, v = q0.copy(), v0.copy()
    bw = tab[4]
    sb = 0.0
    for j in range(s):
        sb += bw[j]
    stats[mt.FAILED_STEP] = -1
    if not store(model, 0, t0, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
        fail(stats, 0, FAIL_NONFINITE)
        return
    j_out = 1
    for step in range(n_steps):
        t = t0 + step * h
        predict(x, x_last, x_prev, step, predictor)
        stats[2] += evaluate(model, tab, True, x, t, q, v, h, M, ws, G, J)
        if not start_newton(stats, step, G, J, piv):
            return
        floor = abs(h) * (1.0 + norm_inf(v))
        prev = -1.0
        it = 0
        status = 0
        while it < max_iter:
            it += 1
            dn = newton_increment(J, piv, G, x)
            status = newton_status(dn, prev, norm_inf(x), floor, tol)
            if status != 0:
                break
            prev = dn
            stats[2] += evaluate(model, tab, False, x, t, q, v, h, M, ws, G, J)
        if not end_newton(stats, step, it, status):
            return
        # q1 - q0 = h sum_j b_j (v0 + Z_j); v1 - v0 = dv
        for a in range(n):
            acc = 0.0
            for j in range(s):
                acc += bw[j] * x[j * n + a]
            dq[a] = h * (sb * v[a] + acc)
            dv[a] = x[sn + sm + a]
        if not accept_step(q, v, cq, cv, dq, dv, compensated, x, x_last, x_prev, stats, step):
            return
        if (step + 1) % every == 0 or step + 1 == n_steps:
            if not store(model, j_out, t0 + (step + 1) * h, q, v, M, out_t, out_q, out_v, out_E, out_k, ws):
                fail(stats, step, FAIL_NONFINITE)
                return
            j_out += 1
    for r in range(NN):
        out_x[r] = x_last[r]


SPARK_SIG = types.void(mt.MECH_MODEL, mt.TABLEAU_T, mt.a2, *mt.RUN, mt.a1)


@numba.njit(SPARK_SIG, cache=True, nogil=True)
def spark_run(model, tab, M, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
              out_t, out_q, out_v, out_E, out_k, stats, out_x):
    """n_steps of the SPARK method (21) for a mechanical system from (t0, q0, v0); samples every
    ``every`` steps and the last step; out_x receives the last step's unknowns."""
    ws = mech_workspace(tab[1].shape[0], q0.shape[0], out_k.shape[1])
    spark_loop(model, tab, M, ws, t0, q0, v0, h, n_steps, every, compensated, tol,
               max_iter, predictor, out_t, out_q, out_v, out_E, out_k, stats, out_x)


GENERAL_SIG = types.void(mt.GEN_MODEL, mt.TABLEAU_T, mt.a2, *mt.RUN, mt.a1)


@numba.njit(GENERAL_SIG, cache=True, nogil=True)
def general_run(model, tab, M, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
                out_t, out_q, out_v, out_E, out_k, stats, out_x):
    """n_steps of the SPARK method (21) for general L(t, q, v), k(t, q, v) (``kernels_general``;
    M is unused); same sampling, counters and failure codes as ``spark_run``."""
    ws = workspace(tab[1].shape[0], q0.shape[0], out_k.shape[1])
    spark_loop(model, tab, M, ws, t0, q0, v0, h, n_steps, every, compensated, tol,
               max_iter, predictor, out_t, out_q, out_v, out_E, out_k, stats, out_x)


LF2_SIG = types.void(mt.MECH_MODEL, types.int64, mt.a2, mt.a2, *mt.RUN)


@numba.njit(LF2_SIG, cache=True, nogil=True)
def lf2_run(model, variant, M, Minv, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, predictor,
            out_t, out_q, out_v, out_E, out_k, stats):
    """Semi-implicit 2-stage methods with Newton on the m multipliers only (Lambda = h Psi):
    variant 0 the Lobatto IIIA-B SPARK method in the form (25), 1 the modified method of 8.4,
    2 McLachlan-Perlmutter's (26); one step is ``kernels_mech.lf2_step``."""
    n = q0.shape[0]
    m = out_k.shape[1]
    q, v = q0.copy(), v0.copy()
    cq, cv, dq, dv = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    ws = (np.zeros(n), np.zeros(n), np.zeros((m, n)), np.zeros(m), np.zeros((m, n)), np.zeros(m),
          np.zeros((m, n)), np.zeros((n, m)), np.zeros((n, m)), np.zeros(n), np.zeros(n), np.zeros(n),
          np.zeros(n), np.zeros(m), np.zeros((m, m)), np.zeros((m, m)), np.zeros(m, dtype=np.int64),
          np.zeros(m))
    lam, lam_last, lam_prev = np.zeros(m), np.zeros(m), np.zeros(m)
    kK, kb, kout = np.zeros((m, n)), np.zeros(m), np.zeros(m)
    stats[mt.FAILED_STEP] = -1
    j_out = 0
    for step in range(-1, n_steps):
        if step >= 0:
            t = t0 + step * h
            predict(lam, lam_last, lam_prev, step, predictor)
            if not lf2_step(model, variant, M, Minv, t, q, v, cv, h, tol, max_iter, lam, dq, dv, ws, stats, step):
                return
            if not accept_step(q, v, cq, cv, dq, dv, compensated, lam, lam_last, lam_prev, stats, step):
                return
        if step < 0 or (step + 1) % every == 0 or step + 1 == n_steps:
            tj = t0 + (step + 1) * h
            e = mech_point(model, tj, q, v, M, kK, kb, kout)
            if not record(j_out, tj, q, v, e, kout, out_t, out_q, out_v, out_E, out_k):
                fail(stats, max(step, 0), FAIL_NONFINITE)
                return
            j_out += 1
