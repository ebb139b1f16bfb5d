"""Small fixed systems and a tableau that exercise what the paper's scenes do not: explicit time in
L and k, gyroscopic (q-v coupling) terms, a constraint nonlinear in v with K = k_v depending on
(t, q, v), b(t, q) != 0, and a SPARK tableau with A_hat != A_tilde, b_tilde != b_hat and an omega
that is not b_j c_j^(i-1). Used by test_equations_21, test_time_dependence and
test_nonlinear_constraint (independent sympy derivations live in those tests, not here); and
``theorem1_tol``, the derived tolerance of every Theorem 1 check of the verification suite."""
from __future__ import annotations

from fractions import Fraction as Fr

import mpmath
import sympy

from ldaspark.analysis.discrete import theorem1_residual_bound
from ldaspark.core.system import LagrangianSystem
from ldaspark.core.tableau_file import from_json_dict


def theorem1_tol(r):
    """What the residual of Theorem 1 can carry when the identities hold exactly:
    ``ldaspark.analysis.discrete.theorem1_residual_bound`` (10 fd_error + 1e3 cond(J) 10^-dps_fd),
    the ledger's threshold too. Measured on the default cases of test_theorem1,
    test_time_dependence, test_nonlinear_constraint and test_general_systems (mpmath only, no
    BLAS): residuals 0 .. 1.4e-40 against bounds 6.5e-52 .. 8.4e-26, at most 0.22 of the bound
    (Lobatto IIIA-B 2 on the skate, 1.6e-52 of 7.3e-52). TOL_THEOREM1 (1e-20, the ledger's
    earlier threshold) passed tableau coefficients correct to 20 digits only (planted in
    SparkTableau.arrays: residuals 1.9e-23 .. 9.2e-26 at dps_fd 60); this bound does not."""
    return theorem1_residual_bound(r)


T = sympy.Symbol("t")
Q = sympy.symbols("x y z")
V = sympy.symbols("u w r")


def rheonomic_system():
    """Theorem 1's general setting (the assumption (2) not needed):
    L(t, q, v) = |v|^2/2 + u^4/12 + (1 + sin t)/4 (x w - y u) - (1 + t/5)(x^2 + y^2)/2 - z^2/4
    (non-quadratic in v, gyroscopic, L_t != 0 and grad^2_tv L != 0),
    k(t, q, v) = r - (y + t/4) u - w^3/10 - sin(t)/5
    (nonlinear in v, K = k_v = (-(y + t/4), -3 w^2/10, 1) depends on t, q, v; k_t != 0)."""
    x, y, z = Q
    u, w, r = V
    L = (u ** 2 + w ** 2 + r ** 2) / 2 + u ** 4 / 12 + (1 + sympy.sin(T)) / 4 * (x * w - y * u) \
        - (1 + T / 5) * (x ** 2 + y ** 2) / 2 - z ** 2 / 4
    k = [r - (y + T / 4) * u - w ** 3 / 10 - sympy.sin(T) / 5]
    return LagrangianSystem(L, k, list(Q), list(V), t=T, name="rheonomic-general")


def rheonomic_initial(dps=None):
    """Consistent (t0, q0, v0) for ``rheonomic_system``: t0 = 3/10, q0 = (1, 1/2, 0),
    (u0, w0) = (1/2, 1) and r0 solved from k = 0."""
    t0, q0, u0, w0 = sympy.Rational(3, 10), [1, sympy.Rational(1, 2), 0], sympy.Rational(1, 2), 1
    r0 = (q0[1] + t0 / 4) * u0 + sympy.Integer(w0) ** 3 / 10 + sympy.sin(t0) / 5
    vals = [t0, q0, [u0, w0, r0]]
    return _convert(vals, dps)


def nonlinear_constraint_system():
    """Autonomous, k quadratic in v: L = |v|^2/2 + u^4/12 - (x^2 + y^2)/2,
    k = r - y u - (u^2 + w^2)/4, K = (-y - u/2, -w/2, 1): K at V_j differs from K at v0."""
    x, y, z = Q
    u, w, r = V
    L = (u ** 2 + w ** 2 + r ** 2) / 2 + u ** 4 / 12 - (x ** 2 + y ** 2) / 2
    k = [r - y * u - (u ** 2 + w ** 2) / 4]
    return LagrangianSystem(L, k, list(Q), list(V), t=T, name="nonlinear-constraint")


def nonlinear_initial(dps=None):
    q0, u0, w0 = [1, sympy.Rational(1, 2), 0], sympy.Rational(1, 2), 1
    r0 = q0[1] * u0 + (u0 ** 2 + w0 ** 2) / sympy.Integer(4)
    return _convert([sympy.Integer(0), q0, [u0, w0, r0]], dps)


def _convert(vals, dps):
    t0, q0, v0 = vals
    if dps is None:
        return float(t0), [float(x) for x in q0], [float(x) for x in v0]
    with mpmath.workdps(dps):
        cv = lambda e: mpmath.mpf(str(sympy.N(sympy.sympify(e), dps + 10)))
        return cv(t0), [cv(x) for x in q0], [cv(x) for x in v0]


def general_tableau():
    """An exact 2-stage SPARK tableau satisfying (22) with nothing else special: A arbitrary,
    c = A 1 != b, A_hat from (22b), A_tilde != A_hat, b_tilde != b_hat = b, omega = (1/3, 2/3)."""
    A = [[Fr(1, 4), Fr(-1, 20)], [Fr(3, 4), Fr(1, 4)]]
    b = [Fr(3, 5), Fr(2, 5)]
    Ah = [[b[i] * (b[j] - A[i][j]) / b[j] for i in range(2)] for j in range(2)]   # (22b) solved
    At = [[Fr(1, 3), Fr(1, 10)], [Fr(2, 5), Fr(1, 5)]]
    bt = [Fr(9, 20), Fr(11, 20)]
    d = {"c": [sum(r) for r in A], "A": A, "A_hat": Ah, "A_tilde": At, "b": b, "b_hat": b,
         "b_tilde": bt, "omega": [[Fr(1, 3), Fr(2, 3)]]}
    d = {k: [[str(x) for x in r] if isinstance(r, list) else str(r) for r in v] for k, v in d.items()}
    return from_json_dict(d, name="general-2")
