"""numba types of the generated model functions: the contract between ``codegen`` (which emits
functions with exactly these signatures) and the kernels (which take them as first-class
function arguments, so that the kernels compile once for every system and stay cached).

Arrays are float64, C-contiguous; matrices are (rows, columns) in the paper's order:
K = k_v is (m, n), k_q is (m, n), L_vq[a, b] = d(grad_v L)_a / dq_b.
"""
import warnings

from numba import types
from numba.core.errors import NumbaExperimentalFeatureWarning

# first-class function arguments are how the kernels stay independent of the system
warnings.filterwarnings("ignore", category=NumbaExperimentalFeatureWarning)

f8 = types.float64
a1 = types.Array(f8, 1, "C")
a2 = types.Array(f8, 2, "C")
i8 = types.int64
b1 = types.boolean

# mechanical form L = 1/2 v^T M v - U(t, q), k = K(t, q) v + b(t, q)
U_SIG = f8(f8, a1)                                   # U_of(t, q)
VEC_SIG = types.void(f8, a1, a1)                     # grad_U(t, q, out), b_of(t, q, out)
MAT_SIG = types.void(f8, a1, a2)                     # hess_U(t, q, out), K_of(t, q, out)
MATX_SIG = types.void(f8, a1, a1, a2)                # kq_of(t, q, v, out), KTlam_q(t, q, lam, out)

# general L(t, q, v), k(t, q, v)
VAL_SIG = types.void(f8, a1, a1, a1, a1, a1, a2)     # point_val(t, q, v, L_v, L_q, k, k_v)
# point_jac(t, q, v, lam, L_vv, L_vq, L_qq, k_q, KTl_q, KTl_v), KTl = K^T lam
JAC_SIG = types.void(f8, a1, a1, a1, a2, a2, a2, a2, a2, a2)
E_SIG = f8(f8, a1, a1)                               # energy(t, q, v) = L_v v - L (8)
# the nonideal term N(t, q, v, psi) of 3.3 and its partials; for a system without N both write
# nothing and return False, and the model's flag has_N (last entry of GEN_MODEL) is False, so
# that one kernel signature serves ideal and nonideal systems
NI_SIG = b1(f8, a1, a1, a1, a1)                      # nonideal(t, q, v, psi, N)
NIJ_SIG = b1(f8, a1, a1, a1, a2, a2, a2)             # nonideal_jac(t, q, v, psi, N_q, N_v, N_psi)

U_FN, VEC_FN, MAT_FN, MATX_FN = (types.FunctionType(s) for s in (U_SIG, VEC_SIG, MAT_SIG, MATX_SIG))
VAL_FN, JAC_FN, E_FN, NI_FN, NIJ_FN = (types.FunctionType(s) for s in (VAL_SIG, JAC_SIG, E_SIG, NI_SIG, NIJ_SIG))

# the SPARK coefficients (21): c, A, A_hat, A_tilde, b, b_hat, b_tilde, omega
TABLEAU = (a1, a2, a2, a2, a1, a1, a1, a2)
# run arguments after the model and the tableau: t0, q0, v0, h, n_steps, every, compensated, tol,
# max_iter, predictor, out_t, out_q, out_v, out_E, out_k, stats
RUN = (f8, a1, a1, f8, i8, i8, b1, f8, i8, i8, a1, a2, a2, a1, a2, types.Array(i8, 1, "C"))
# stats entries (fast.STAT_NAMES) and failure codes of stats[FAILURE]
FAILED_STEP, FAILURE = 6, 7
# steps that needed the full-Newton fallback; iterations of the failed step (both phases)
FULL_NEWTON_STEPS, FAILED_ITERATIONS = 8, 9
FAIL_NEWTON, FAIL_SINGULAR, FAIL_NONFINITE = 1, 2, 3

# codegen's MODEL tuples: (n, functions...). The leading integer is n; it also keeps numba from
# trying to unify the function types into one (and warning at every call) when typing the tuple.
MECH_MODEL = types.Tuple((i8, VEC_FN, MAT_FN, MAT_FN, VEC_FN, MATX_FN, MATX_FN, U_FN))
GEN_MODEL = types.Tuple((i8, VAL_FN, JAC_FN, E_FN, NI_FN, NIJ_FN, b1))
TABLEAU_T = types.Tuple(TABLEAU)
STATS = types.Array(i8, 1, "C")
ODE_SIG = types.void(f8, a1, a1, a2, a1)             # ode_parts(t, q, v, S, r) of ``ode``
