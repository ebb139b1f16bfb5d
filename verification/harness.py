"""The differential harness: random systems with every term of (1) nonzero, and the tolerance at
which two paths that solve the same equations (21a-f) must agree.

A ``HarnessCase`` extends a ``verification.strategies.general_systems`` draw (L with explicit t,
L_vt != 0 through tau cos(t) q_c v_d, L_qv != 0 through gamma q_a v_b, L not quadratic in v;
k nonlinear in v with b(t, q) != 0) by

* a symbolic parameter P (``LagrangianSystem(..., params=[P])``, value drawn) in a term
  P q_a^2 v_b v_c / 4 with b != c: the mass matrix L_vv is non-diagonal and depends on q;
* a nonideal term (section 3.3) N_i(t, q, v) = -(d_i + e_i sin t) v_i + f_i cos(2 t) q_j with
  explicit t (so that a stage evaluated at the wrong time T_i = t0 + c_i h differs);
* an initial time t0 in [1/4, 3/4] (never 0: a clock restarted at 0 differs), v0 projected onto
  k(t0, q0, v) = 0 at ``DPS`` digits, and the run's step h, step count, chunk size and
  ``save_every``.

``mechanical_cases`` draws systems in the mechanical form of section 7 (M non-diagonal, constant
as that form requires, U(q), K(q), b(q) != 0) for the kernels that need it (the block and sparse linear
solvers). ``agreement_tol`` states the tolerance of a pair (docs/verification.md,
"The differential harness").
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from fractions import Fraction

import mpmath
import numpy as np
import sympy
from hypothesis import assume, strategies as st

from ldaspark.core.backend import Backend
from ldaspark.core.errors import LdasparkError
from ldaspark.core.system import LagrangianSystem
from verification.strategies import _R, general_systems, small

#: digits of the mpmath reference path and of the projection of v0
DPS = 30
EPS = float(np.finfo(float).eps)
#: the Newton stopping rule of every float64 engine: |dx| <= 10 eps (|x| + |v|) (core/spark.py
#: ``SparkMethod.tol``; compiled/runner.py uses the same default); the iterate then differs from
#: the root by at most this (contraction < 1/2 when it stops)
NEWTON_TOL = 10 * EPS
#: the hypothesis seed every harness test uses, so that all of them draw the same systems (each
#: system derived and compiled once per session: ``_extended`` is cached by the drawn numbers)
SEED = 20261205
METHODS = ("gauss-2", "lobatto-iiia-iiib-2", "gauss-1")


@dataclass
class HarnessCase:
    """A system with every term of (1) nonzero and one run's data (float64 and mpf start)."""

    system: LagrangianSystem
    params: dict
    t0: float
    q0: list
    v0: list
    q0_mp: list
    v0_mp: list
    method: str
    h: float
    n_steps: int
    chunk: int
    every: int
    cond: float
    description: str
    extra: dict = field(default_factory=dict)

    def __repr__(self):
        return f"HarnessCase({self.description})"

    def kw(self, **over):
        """The keyword arguments of ``ldaspark.integrate`` for this run (``over`` replaces)."""
        kw = dict(t_span=(self.t0, self.t0 + self.n_steps * self.h), q0=self.q0, v0=self.v0, h=self.h,
                  params=self.params)
        kw.update(over)
        return kw

    def run(self, **over):
        import ldaspark
        return ldaspark.integrate(self.system, self.method, **self.kw(**over))

    def tol(self, steps=None, factor=1.0):
        return agreement_tol(self.n_steps if steps is None else steps, self.cond, self.scale, factor)

    @property
    def scale(self):
        return 1.0 + max(max(abs(x) for x in self.q0), max(abs(x) for x in self.v0))


def agreement_tol(steps: int, cond: float, scale: float = 1.0, factor: float = 1.0) -> float:
    """The tolerance of two paths solving (21) for ``steps`` steps from the same start.

    Each path stops Newton when |dx| <= NEWTON_TOL (|x| + |v|), so its step differs from the root
    of (21) by at most NEWTON_TOL scale, plus the round-off of evaluating the residual, which the
    Newton matrix amplifies by at most its condition number ``cond`` (that of the saddle matrix
    (4) at the start; the Newton matrix is I + O(h) times it). Two paths: twice that. The flow
    over t <= 1 with these coefficients amplifies a local difference by at most e (Lipschitz
    constant < 1 of the drawn systems: |coefficients| <= 1, |q|, |v| < 3), and the local
    differences add over ``steps``:

        tol = 2 e steps NEWTON_TOL cond scale factor.

    ``factor`` for pairs that restart the predictor (chunks, resumed runs): the Newton iterates
    then stop at another point inside the same ball, no larger bound."""
    return 2 * math.e * steps * NEWTON_TOL * max(cond, 1.0) * scale * factor


def saddle_cond(system, t0, q0, v0, params) -> float:
    """The 2-norm condition number of the saddle matrix (4) at the start, in float64."""
    sysp = system.with_params(params) if params else system
    bk = Backend(None)
    S = sysp.saddle_matrix(bk, float(t0), bk.array(q0), bk.array(v0))
    return float(np.linalg.cond(np.asarray(S, float)))


P = sympy.Symbol("P")


@functools.lru_cache(maxsize=64)
def _extended(L, k, q, v, t, extra_L, nonideal):
    """The drawn system with the parameter term and the nonideal term (cached by the sympy
    expressions, which hash by value: every test that draws the same numbers shares the system,
    its derivation and its compiled model)."""
    return LagrangianSystem(L + extra_L, list(k), list(q), list(v), t=t, name="harness", params=[P],
                            nonideal=list(nonideal))


@st.composite
def harness_cases(draw, n_range=(2, 3), methods=METHODS):
    """A HarnessCase (module docstring)."""
    base = draw(general_systems(n_range=n_range, m_max=2, dps=DPS))
    sysb = base.system
    n = sysb.n
    q, v, t = sysb.q, sysb.v, sysb.t
    a = draw(st.integers(0, n - 1))
    b_ = draw(st.integers(0, n - 1))
    c_ = (b_ + 1 + draw(st.integers(0, n - 2))) % n           # c != b: a non-diagonal L_vv entry
    extra_L = P * q[a] ** 2 * v[b_] * v[c_] / 4
    N = []
    for i in range(n):
        d_, e_ = _R(draw(small("1/20", "1/5"))), _R(draw(small("1/20", "1/5")))
        f_, j = _R(draw(small("1/20", "1/5"))), draw(st.integers(0, n - 1))
        N.append(-(d_ + e_ * sympy.sin(t)) * v[i] + f_ * sympy.cos(2 * t) * q[j])
    pval = float(_R(draw(small("1/10", "1/2", 10))))
    system = _extended(sysb.L, tuple(sysb.k), tuple(q), tuple(v), t, extra_L, tuple(N))
    t0r = sympy.Rational(draw(st.sampled_from([1, 3, 4, 5, 6])), 8)       # binary: float64 and mpf alike
    method = draw(st.sampled_from(methods))
    h = draw(st.sampled_from([1 / 16, 1 / 20, 1 / 25]))
    n_steps = draw(st.integers(6, 9))
    chunk = draw(st.integers(2, 4))
    every = draw(st.integers(2, 3))
    bk = Backend(DPS)
    try:
        with bk.context():
            sysp = system.with_params({P: pval})
            t0m, q0m = bk.scalar(t0r), bk.array(base.q0)
            v0m = sysp.project_velocity(bk, t0m, q0m, bk.array(base.v0))
            sysp.check_saddle(bk, t0m, q0m, v0m, rcond=1e-6)
            assume(bk.norm_inf(v0m) < 3)
            q0f, v0f = [float(x) for x in q0m], [float(x) for x in v0m]
    except LdasparkError:
        assume(False)
    t0 = float(t0r)
    cond = saddle_cond(system, t0, q0f, v0f, {"P": pval})
    desc = (f"n={n}, m={sysb.m}, L={system.L}, k={list(system.k)}, N={list(system.N)}, P={pval}, t0={t0}, "
            f"q0={q0f}, v0={v0f}, {method}, h={h}, N_steps={n_steps}, chunk={chunk}, every={every}")
    return HarnessCase(system, {"P": pval}, t0, q0f, v0f, list(q0m), list(v0m), method, h, n_steps, chunk,
                       every, cond, desc)


# --- mechanical form (section 7) -----------------------------------------------------------------
@functools.lru_cache(maxsize=32)
def _mechanical(M, U, K, b, q, v):
    return LagrangianSystem.mechanical_form(sympy.Matrix(M), U, sympy.Matrix(K), sympy.Matrix(b), q=list(q),
                                            v=list(v), name="harness-mechanical")


@st.composite
def mechanical_cases(draw, n_range=(3, 4)):
    """L = 1/2 v^T M v - U(q), k = K(q) v + b(q) with M = D + mu (E_bc + E_cb) (non-diagonal; the
    mechanical form of the kernels needs M constant), U quadratic + cubic, K = pivot rows + kappa q_e
    e_f, b = beta sin(q_h) + rho != 0; v0 projected onto k = 0."""
    n = draw(st.integers(*n_range))
    m = draw(st.integers(1, 2))
    q = tuple(sympy.symbols(f"q1:{n + 1}"))
    v = tuple(sympy.symbols(f"v1:{n + 1}"))
    idx = st.integers(0, n - 1)
    M = sympy.zeros(n, n)
    for i in range(n):
        M[i, i] = 1 + _R(draw(small("0", "1", 4)))
    b_ = draw(idx)
    c_ = (b_ + 1 + draw(st.integers(0, n - 2))) % n
    mu = _R(draw(small("1/20", "1/5")))
    M[b_, c_] += mu
    M[c_, b_] += mu
    U = sum((1 + _R(draw(small("0", "1", 4)))) * x ** 2 for x in q) / 2 + _R(draw(small())) * q[0] ** 3 / 3
    pivots = draw(st.permutations(range(n)))[:m]
    K = sympy.zeros(m, n)
    bvec = sympy.zeros(m, 1)
    for r in range(m):
        K[r, pivots[r]] = 1
        e, f = draw(idx), draw(idx)
        K[r, f] += _R(draw(small("-1/2", "1/2"))) * q[e]
        bvec[r] = _R(draw(small("1/20", "1/2"))) * sympy.sin(q[draw(idx)]) + _R(draw(small()))
    system = _mechanical(sympy.ImmutableMatrix(M), U, sympy.ImmutableMatrix(K), sympy.ImmutableMatrix(bvec), q, v)
    q0 = [float(_R(draw(small("-1/2", "1/2", 10)))) for _ in range(n)]
    v0 = [float(_R(draw(small("-1/2", "1/2", 10)))) for _ in range(n)]
    bk = Backend(None)
    try:
        v0 = [float(x) for x in system.project_velocity(bk, 0.0, bk.array(q0), bk.array(v0))]
        system.check_saddle(bk, 0.0, bk.array(q0), bk.array(v0), rcond=1e-6)
    except LdasparkError:
        assume(False)
    assume(max(abs(x) for x in v0) < 3)
    t0 = draw(st.sampled_from([0.25, 0.375, 0.5, 0.625]))
    method = draw(st.sampled_from(METHODS))
    h = draw(st.sampled_from([1 / 16, 1 / 20]))
    n_steps = draw(st.integers(5, 8))
    cond = saddle_cond(system, t0, q0, v0, None)
    desc = f"n={n}, m={m}, M={M.tolist()}, U={U}, K={K.tolist()}, b={list(bvec)}, q0={q0}, v0={v0}, {method}, h={h}"
    return HarnessCase(system, None, t0, q0, v0, q0, v0, method, h, n_steps, 2, 2, cond, desc)


def consistent_neighbour(case: HarnessCase, shift: float):
    """(q0', v0'): q0 moved by ``shift`` in its first component, v0 projected onto k = 0 there
    (a second ensemble member with different consistent initial data)."""
    sysp = case.system.with_params(case.params) if case.params else case.system
    bk = Backend(None)
    q1 = list(case.q0)
    q1[0] += shift
    v1 = sysp.project_velocity(bk, float(case.t0), bk.array(q1), bk.array(case.v0))
    return q1, [float(x) for x in v1]


def max_diff(a, b) -> float:
    """max |a - b| over float arrays (mpf arrays converted)."""
    fa = np.asarray(np.asarray(a, dtype=object).astype(float), float)
    fb = np.asarray(np.asarray(b, dtype=object).astype(float), float)
    assert fa.shape == fb.shape, (fa.shape, fb.shape)
    return float(np.max(np.abs(fa - fb), initial=0.0))


def trajectory_diff(r1, r2) -> float:
    """max over t, q, v, energy (8) and k (1c) of two Results on the same grid."""
    return max(max_diff(getattr(r1, nm), getattr(r2, nm)) for nm in ("t", "q", "v", "energy", "constraint"))


def mp_to_float(x):
    with mpmath.workdps(DPS):
        return float(x)


__all__ = ["DPS", "HarnessCase", "SEED", "agreement_tol", "consistent_neighbour", "harness_cases",
           "max_diff", "mechanical_cases", "trajectory_diff", "Fraction"]
