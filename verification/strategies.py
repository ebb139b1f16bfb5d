"""Hypothesis strategies for random systems (1) and random SPARK tableaux satisfying (22).

Systems (``general_systems``): n <= 5 coordinates, m <= 2 < n constraints, with

* L(t, q, v) = 1/2 v^T M v + alpha |v|^4 / 4 + beta exp(v_1 / 2) + gamma q_a v_b
  + tau cos(t) q_c v_d + sigma t q_1^2 / 2 - U(q): not quadratic in v (quartic and exp terms),
  gyroscopic q-v coupling (gamma), explicit time in grad_v L (tau) and in L (sigma);
  M = diag(1..2) + small symmetric part, alpha, beta >= 0: L_vv is positive definite near the
  base point (checked through the saddle matrix (4) at the base point);
* k_r(t, q, v) = v_{p_r} + kappa_r q_e v_f + nu_r v_g^2 + b_r(t, q), b_r = beta_r sin(t + q_h)
  + rho_r: rheonomic, nonlinear in v, affine part b(t, q) != 0; the pivot columns p_r are
  distinct, so K = k_v has full row rank near the base point;
* a base point (t0, q0, v0) with v0 projected onto k(t0, q0, v0) = 0 by Newton on the KKT
  system at ``dps`` digits (``LagrangianSystem.project_velocity``).

Coefficients are small rationals, so everything is exact until the numeric evaluation, and
the sympy expressions stay small (derivation and lambdify well under a second for n = 3).

Tableaux (``spark_tableaux``): random A near a base collocation matrix (Gauss s = 1, 2 and
Lobatto IIIA s = 3, all rational), random nonzero b, b_hat = b_tilde = b, A_hat from (22b)
(a_hat_ij = b_j (b_i - a_ji) / b_i), random A_tilde and omega; ``symmetric=True`` draws s <= 2
tableaux satisfying (23) (omega = b), and ``builtin_tableaux`` samples the built-in families.
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import sympy
from hypothesis import assume, strategies as st

from ldaspark.core.backend import Backend
from ldaspark.core.errors import LdasparkError
from ldaspark.core.families import get_method
from ldaspark.core.system import LagrangianSystem
from ldaspark.core.tableau_file import from_json_dict


def small(lo="-1/5", hi="1/5", den=20):
    return st.fractions(min_value=Fraction(lo), max_value=Fraction(hi), max_denominator=den)


def _R(x):
    return sympy.Rational(x.numerator, x.denominator)


@dataclass
class GeneralCase:
    """A random system with a consistent base point (mpf values at ``dps`` digits)."""

    system: LagrangianSystem
    t0: object
    q0: list
    v0: list
    dps: int
    description: str

    def __repr__(self):   # hypothesis prints failing examples with this
        return f"GeneralCase({self.description})"


@st.composite
def general_systems(draw, n_range=(2, 3), m_max=2, dps=60, m_min=1):
    """A random rheonomic system with a constraint nonlinear in v and b != 0 (module docstring);
    ``m_min`` forces several constraints (hypothesis draws the smallest m first)."""
    n = draw(st.integers(*n_range))
    m = draw(st.integers(min(m_min, n - 1), min(m_max, n - 1)))
    q = list(sympy.symbols(f"q1:{n + 1}"))
    v = list(sympy.symbols(f"v1:{n + 1}"))
    t = sympy.Symbol("t")
    idx = st.integers(0, n - 1)
    vv = sympy.Matrix(v)
    M = sympy.diag(*[1 + _R(draw(small("0", "1", 4))) for _ in range(n)])
    i, j = draw(idx), draw(idx)
    if i != j:
        c = _R(draw(small("-1/5", "1/5", 10)))
        M[i, j] += c
        M[j, i] += c
    # lower bounds away from 0: even the simplest example drawn is non-quadratic and rheonomic
    alpha, beta = _R(draw(small("1/20", "1/5"))), _R(draw(small("1/20", "1/5")))
    gamma = _R(draw(small("-1/2", "1/2")))
    tau, sigma = _R(draw(small("1/10", "1/2"))), _R(draw(small("1/10", "1/2")))
    a, b_, c_, d_ = (draw(idx) for _ in range(4))
    w = [1 + _R(draw(small("0", "1", 4))) for _ in range(n)]
    U = sum(w[k] * q[k] ** 2 for k in range(n)) / 2 + _R(draw(small())) * q[0] ** 3 / 3
    L = ((vv.T * M * vv)[0, 0] / 2 + alpha * (vv.T * vv)[0, 0] ** 2 / 4 + beta * sympy.exp(v[0] / 2)
         + gamma * q[a] * v[b_] + tau * sympy.cos(t) * q[c_] * v[d_] + sigma * t * q[0] ** 2 / 2 - U)
    pivots = draw(st.permutations(range(n)))[:m]
    k = []
    for r in range(m):
        e, f, g, hh = (draw(idx) for _ in range(4))
        kappa, nu = _R(draw(small("-1/2", "1/2"))), _R(draw(small("1/20", "1/2")))
        beta_r, rho_r = _R(draw(small("1/20", "1/2"))), _R(draw(small()))
        k.append(v[pivots[r]] + kappa * q[e] * v[f] + nu * v[g] ** 2 + beta_r * sympy.sin(t + q[hh]) + rho_r)
    system = LagrangianSystem(L, k, q, v, t=t, name=f"random-n{n}-m{m}")
    t0 = _R(draw(small("0", "1/2", 10)))
    q0 = [_R(draw(small("-1/2", "1/2", 10))) for _ in range(n)]
    v0 = [_R(draw(small("-1/2", "1/2", 10))) for _ in range(n)]
    bk = Backend(dps)
    try:
        with bk.context():
            t0m, q0m = bk.scalar(t0), bk.array(q0)
            v0m = system.project_velocity(bk, t0m, q0m, bk.array(v0))
            system.check_saddle(bk, t0m, q0m, v0m, rcond=1e-6)
            assume(bk.norm_inf(v0m) < 3)              # stay near the drawn point (Newton may wander)
    except LdasparkError:
        assume(False)
    desc = f"n={n}, m={m}, L={L}, k={k}, t0={t0}, q0={q0}, v0~{[float(x) for x in v0m]}"
    return GeneralCase(system, t0m, list(q0m), list(v0m), dps, desc)


# --- tableaux ------------------------------------------------------------------------------------
_F = Fraction
BASE_A = {1: [[_F(1, 2)]],
          2: [[_F(1, 4), _F(1, 4)], [_F(3, 4), _F(1, 4)]],                       # near Gauss 2
          3: [[_F(0), _F(0), _F(0)], [_F(5, 24), _F(1, 3), _F(-1, 24)], [_F(1, 6), _F(2, 3), _F(1, 6)]]}  # IIIA 3
BASE_B = {1: [_F(1)], 2: [_F(1, 2), _F(1, 2)], 3: [_F(1, 6), _F(2, 3), _F(1, 6)]}


def _tableau(A, b, At, omega, name):
    s = len(b)
    Ah = [[b[j] * (b[i] - A[j][i]) / b[i] for j in range(s)] for i in range(s)]   # (22b) with b_hat = b
    c = [sum(r) for r in A]
    d = {"c": c, "A": A, "A_hat": Ah, "A_tilde": At, "b": b, "b_hat": b, "b_tilde": b}
    if s > 1:
        d["omega"] = omega
    d = {k: [[str(x) for x in r] if isinstance(r, list) else str(r) for r in v] for k, v in d.items()}
    return from_json_dict(d, name=name)


@st.composite
def spark_tableaux(draw, s_values=(1, 2, 3), symmetric=False):
    """A random tableau satisfying (22) (see module docstring); with ``symmetric`` also (23)."""
    if symmetric:
        s = draw(st.sampled_from([x for x in s_values if x <= 2]))
        if s == 1:   # (23b) with s = 1: a_11 = b_1 / 2 (the midpoint rule); A_tilde likewise
            return _tableau([[_F(1, 2)]], [_F(1)], [[_F(1, 2)]], [], "random-sym-1")
        mats = []
        for _ in range(2):   # around [[1/4, 0], [1/2, 1/4]] (c = 1/4, 3/4): nonsingular at zero perturbation
            a11, a12 = _F(1, 4) + draw(small("-1/10", "1/10")), draw(small("-1/10", "1/10"))
            mats.append([[a11, a12], [_F(1, 2) - a12, _F(1, 2) - a11]])      # (23b): a_{3-i,3-j} + a_ij = 1/2
        half = [_F(1, 2), _F(1, 2)]
        return _tableau(mats[0], half, mats[1], [half], "random-sym-2")
    s = draw(st.sampled_from(list(s_values)))
    A = [[BASE_A[s][i][j] + draw(small("-1/10", "1/10", 50)) for j in range(s)] for i in range(s)]
    b = [BASE_B[s][i] + draw(small("-1/20", "1/20", 50)) for i in range(s)]
    assume(all(x != 0 for x in b) and sum(b) != 0)
    At = [[_F(1, 2 * s) + draw(small("-3/10", "3/10", 50)) for _ in range(s)] for _ in range(s)]
    c = [sum(r) for r in A]
    omega = [[b[j] * c[j] ** i + draw(small("-1/10", "1/10", 20)) for j in range(s)] for i in range(s - 1)]
    return _tableau(A, b, At, omega, f"random-{s}")


def builtin_tableaux(max_s=3):
    """A built-in method satisfying (22) (exact coefficients)."""
    names = [f"gauss-{s}" for s in range(1, max_s + 1)]
    names += [f"lobatto-iiia-iiib-{s}" for s in range(2, max_s + 1)]
    names += [f"lobatto-iiia-iiib-iiid-{s}" for s in range(2, max_s + 1)]
    return st.sampled_from(names).map(lambda nm: get_method(nm, exact=True))
