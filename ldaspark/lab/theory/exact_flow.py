"""The exact discrete quantities of section 5, from an independent high-precision solution of (1).

The exact flow between (t0, q0) and (t1, q1) is the solution of the underlying ODE (3a-b)
(equivalently the forced Lagrangian system (6)-(7), f_L = -K^T Psi(t, q, v)) with q(t0) = q0,
q(t1) = q1: a boundary-value problem, solved by shooting on v0. The trajectory for a given v0
is one step of the s-stage Gauss collocation method (order 2s at t1, stage order s; s = 24 by
default, the checks of ``section5`` use 10 at h = 0.1: 4e-31 against mpmath's Taylor solver) on
y = (q, v), y' = (v, a(t, q, v)). With the accelerations a_j = a(T_j, Q_j, V_j) at the nodes as
unknowns, the stage equations and the shooting condition q(t1) = q1 are solved together by
Newton at ``dps`` digits:

    V_i = v0 + h sum_j a_ij a_j,   Q_i = q0 + h c_i v0 + h^2 sum_j (A^2)_ij a_j,
    0 = a_i - a(T_i, Q_i, V_i),    q1 = q0 + h v0 + h^2 sum_j (b^T A)_j a_j,   unknowns a_1..a_s, v0.

(a, psi) = (dv/dt, Psi) come from the saddle system (4) with right-hand side (3a-b); their
partials from differentiating (4): d(a, psi)/dy = S^{-1} (dr/dy - dS/dy (a, psi)) (sympy
derivatives of S and r). This is independent of the SPARK code (no tableau of section 7, no
(21)); only ``LagrangianSystem`` is shared.

Off the exact constraint manifold C_d the boundary-value solution has k(t0, q0, v0) != 0; k is
then a first integral of (3a-b) (constant, not zero) and the solution is that of the forced
system (6), for which the derivation of section 5 holds verbatim. On C_d (q1 reached from
consistent data) it is the solution of (1).

Computed (``ExactBVPResult``): L_d^E = h sum b_i L(T_i, Q_i, V_i); p0, p1; Psi at the nodes;
the sensitivities dQ_i/dq0, dQ_i/dq1, dV_i/dq0, dV_i/dq1 by implicit differentiation; the
exact discrete forces in the forms of section 5:

* (12a)/(12b): f_d^{E-T} = -int Psi^T K d_q0 q dt,  f_d^{E+T} = -int Psi^T K d_q1 q dt;
* (17): f_d^{E-T} = int_{t0}^{t1} (int_{t0}^{s} Psi^T K dt) d_q0 v(s) ds;
* (19): f_d^{E+T} = -int_{t0}^{t1} (int_{s}^{t1} Psi^T K dt) d_q1 v(s) ds;

outer integrals by the Gauss weights b, inner integrals int_{t0}^{T_i} by the collocation
matrix A (exact for polynomials of degree < s).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import mpmath
import numpy as np
import sympy

from ...core.backend import Backend, SingularMatrixError
from ...core.errors import LdasparkError
from ...core.families import gauss
from ...core.system import LagrangianSystem

DEFAULT_STAGES = 24
#: the reference flow's own bound on s (above the 20 a SPARK tableau may have by default: the
#: default of 24 stages was refused by that limit), still bounding the work of one construction
MAX_STAGES = 48


class ExactFlowError(LdasparkError):
    """The high-precision boundary-value solve of (3a-b) failed."""


@dataclass
class ExactBVPResult:
    """Exact discrete quantities at (t0, q0, t1, q1); arrays of mpf."""

    L_d: object
    p0: np.ndarray
    p1: np.ndarray
    v0: np.ndarray
    v1: np.ndarray
    T: list
    Q: np.ndarray            # (s, n) q at the nodes
    V: np.ndarray            # (s, n) v at the nodes
    Psi: np.ndarray          # (s, m)
    PsiK: np.ndarray         # (s, n): Psi_i^T K_i (row covectors)
    dQ_dq0: np.ndarray       # (s, n, n)
    dQ_dq1: np.ndarray
    dV_dq0: np.ndarray
    dV_dq1: np.ndarray
    f_d_minus: np.ndarray    # (12a)
    f_d_plus: np.ndarray     # (12b)
    k0: np.ndarray           # k(t0, q0, v0): zero on C_d, a first integral off it
    iterations: int
    residual: float
    x: np.ndarray
    extra: dict = field(default_factory=dict)


class ExactFlow:
    """Gauss collocation with ``stages`` nodes of the underlying ODE (3a-b) at ``dps`` digits."""

    def __init__(self, system: LagrangianSystem, dps: int = 40, stages: int = DEFAULT_STAGES):
        self.system = system
        self.dps = dps
        self.s = stages
        self.bk = Backend(dps)
        tab = gauss(stages, max_stages=MAX_STAGES).arrays(dps)
        self.c, self.A, self.b = tab.c, tab.A, tab.b
        with mpmath.workdps(dps):
            self.A2 = self.A.dot(self.A)
            self.bA = self.b.dot(self.A)
        self._v0 = None
        self.n, self.m = system.n, system.m
        self._build_saddle_derivatives()

    # --- (3a-b) and its partials -------------------------------------------------------------
    def _build_saddle_derivatives(self):
        """Lambdify S (4), r (3a-b right side) and their partials in y = (q, v)."""
        S = self.system
        n, m = self.n, self.m
        Ssym = sympy.zeros(n + m, n + m)
        Ssym[:n, :n] = S.L_vv
        Ssym[:n, n:] = S.k_v.T
        Ssym[n:, :n] = S.k_v
        vv = sympy.Matrix(S.v)
        r = sympy.Matrix.vstack(-S.L_vt - S.L_vq * vv + S.L_q, -S.k_t - S.k_q * vv)
        y = list(S.q) + list(S.v)
        dS = [Ssym.diff(x) for x in y]
        dr = [r.diff(x) for x in y]
        args = [S.t] + list(S.q) + list(S.v)
        self._f = sympy.lambdify(args, [Ssym.tolist(), r.tolist(), [d.tolist() for d in dS],
                                        [d.tolist() for d in dr]], modules="mpmath", cse=True)
        self._Lfn = sympy.lambdify(args, S.L, modules="mpmath")
        self._Kfn = sympy.lambdify(args, S.k_v.tolist(), modules="mpmath")

    def rhs(self, t, q, v, jacobian=True):
        """(a, psi) of (3a-b) at (t, q, v) and, if asked, (da/dq, da/dv) (each n x n)."""
        n = self.n
        Sm, r, dS, dr = self._f(t, *q, *v)
        Sm = _mp(Sm)
        r = _mp(r)[:, 0]
        try:
            fac = self.bk.factor(Sm)
        except SingularMatrixError as exc:
            raise ExactFlowError(f"saddle matrix (4) singular at t = {float(t):.6g}: {exc}") from None
        z = self.bk.solve_factored(fac, r)
        if not jacobian:
            return z[:n], z[n:], None, None
        cols = []
        for j in range(2 * n):
            rhs = _mp(dr[j])[:, 0] - _mp(dS[j]).dot(z)
            cols.append(self.bk.solve_factored(fac, rhs)[:n])
        D = np.array(cols, dtype=object).T              # (n, 2n): d a / d y
        return z[:n], z[n:], D[:, :n], D[:, n:]

    # --- the collocation/shooting system in the unknowns (a_1..a_s, v0) ----------------------
    # With the accelerations a_j at the nodes as unknowns, V_i = v0 + h sum_j a_ij a_j and
    # Q_i = q0 + h c_i v0 + h^2 sum_j (A^2)_ij a_j; the Jacobian then costs s^2 n^2 (no triple
    # sum over the nodes), which matters in mpmath.
    def _nodes(self, t0, q0, h, acc, v0):
        T = [t0 + ci * h for ci in self.c]
        V = v0 + self.A.dot(acc) * h
        Q = q0 + np.outer(self.c, v0) * h + self.A2.dot(acc) * (h * h)
        return T, Q, V

    def _residual(self, t0, q0, t1, q1, x, h, shooting, jacobian):
        """Rows G1_i = a_i - a(T_i, Q_i, V_i) (s n), and with ``shooting`` the row
        G2 = v0 + h sum_j (b A)_j a_j - (q1 - q0)/h (n) for q(t1) = q1; x = [a | v0] or [a]."""
        s, n = self.s, self.n
        acc = x[:s * n].reshape(s, n)
        v0 = x[s * n:] if shooting else self._v0
        T, Q, V = self._nodes(t0, q0, h, acc, v0)
        ev = [self.rhs(T[i], Q[i], V[i], jacobian) for i in range(s)]
        G = (acc - np.array([e[0] for e in ev], dtype=object)).reshape(-1)
        if shooting:
            G = np.concatenate([G, v0 + self.bA.dot(acc) * h - (q1 - q0) / h])
        data = (T, Q, V, acc, v0, ev)
        if not jacobian:
            return G, None, data
        N = len(x)
        aq = np.array([e[2] for e in ev], dtype=object)
        av = np.array([e[3] for e in ev], dtype=object)
        blocks = -(self.A[:, :, None, None] * av[:, None, :, :]) * h \
            - (self.A2[:, :, None, None] * aq[:, None, :, :]) * (h * h)
        for i in range(s):
            for a_ in range(n):
                blocks[i, i, a_, a_] += 1
        J = self.bk.zeros((N, N))
        J[:s * n, :s * n] = blocks.transpose(0, 2, 1, 3).reshape(s * n, s * n)
        if shooting:
            for i in range(s):
                J[i * n:(i + 1) * n, s * n:] = -av[i] - aq[i] * (self.c[i] * h)
                for a_ in range(n):
                    J[s * n + a_, i * n + a_] = self.bA[i] * h
            for a_ in range(n):
                J[s * n + a_, s * n + a_] = 1
        return G, J, data + (aq, av)

    def _newton(self, t0, q0, t1, q1, x, h, shooting, max_iter):
        """Simplified Newton (one LU, refreshed when the contraction is slow)."""
        bk = self.bk
        fac = None
        prev = None
        for it in range(1, max_iter + 1):
            G, J, _ = self._residual(t0, q0, t1, q1, x, h, shooting, fac is None)
            if fac is None:
                try:
                    fac = bk.factor(J)
                except SingularMatrixError as exc:
                    raise ExactFlowError(f"exact-flow Newton matrix singular: {exc}") from None
            d = bk.solve_factored(fac, -G)
            x = x + d
            dn = bk.norm_inf(d)
            if dn <= 10 * bk.eps * (1 + bk.norm_inf(x)):
                return x, it
            if prev is not None and dn > 0.3 * prev:
                fac = None
            prev = dn
        raise ExactFlowError(f"exact-flow Newton did not converge in {max_iter} iterations")

    def ivp(self, t0, q0, v0, h, max_iter=60):
        """Exact flow from (t0, q0, v0) over [t0, t0 + h]: (q1, v1, nodes dict)."""
        bk = self.bk
        with bk.context():
            t0, h = bk.scalar(t0), bk.scalar(h)
            q0, v0 = bk.array(q0), bk.array(v0)
            self._v0 = v0
            x, _ = self._newton(t0, q0, None, None, bk.zeros(self.s * self.n), h, False, max_iter)
            _, _, (T, Q, V, acc, _, ev) = self._residual(t0, q0, None, None, x, h, False, False)
            q1 = q0 + v0 * h + self.bA.dot(acc) * (h * h)
            v1 = v0 + self.b.dot(acc) * h
            return q1, v1, {"T": T, "Q": Q, "V": V, "a": acc,
                            "Psi": np.array([e[1] for e in ev], dtype=object).reshape(self.s, self.m)}

    def bvp(self, t0, q0, t1, q1, x_guess=None, max_iter=60, sensitivities=True):
        """Shooting on v0: the collocation stages and q(t1) = q1 solved together.
        Returns ``ExactBVPResult`` (sensitivities by implicit differentiation)."""
        bk = self.bk
        s, n = self.s, self.n
        with bk.context():
            t0, t1 = bk.scalar(t0), bk.scalar(t1)
            q0, q1 = bk.array(q0), bk.array(q1)
            h = t1 - t0
            x = (np.concatenate([bk.zeros(s * n), (q1 - q0) / h]) if x_guess is None
                 else bk.array(x_guess))
            x, it = self._newton(t0, q0, t1, q1, x, h, True, max_iter)
            G, J, data = self._residual(t0, q0, t1, q1, x, h, True, True)
            return self._result(t0, q0, t1, q1, x, G, J, data, it, sensitivities)

    def _result(self, t0, q0, t1, q1, x, G, J, data, it, sensitivities):
        bk, s, n, m = self.bk, self.s, self.n, self.m
        h = t1 - t0
        T, Q, V, acc, v0, ev, aq, av = data
        v1 = v0 + self.b.dot(acc) * h
        Psi = np.array([e[1] for e in ev], dtype=object).reshape(s, m)
        Ks = [_mp(self._Kfn(T[i], *Q[i], *V[i])).reshape(m, n) for i in range(s)]
        PsiK = np.array([Psi[i].dot(Ks[i]) for i in range(s)], dtype=object)
        L_d = h * sum(self.b[i] * self._Lfn(T[i], *Q[i], *V[i]) for i in range(s))
        res = ExactBVPResult(L_d=L_d, p0=self.system.momentum(bk, t0, q0, v0),
                             p1=self.system.momentum(bk, t1, q1, v1), v0=v0.copy(), v1=v1, T=T, Q=Q,
                             V=V, Psi=Psi, PsiK=PsiK, dQ_dq0=None, dQ_dq1=None, dV_dq0=None,
                             dV_dq1=None, f_d_minus=None, f_d_plus=None,
                             k0=self.system.constraint(bk, t0, q0, v0), iterations=it,
                             residual=bk.norm_inf(G), x=x.copy())
        fac = bk.factor(J)
        res.extra["fac"] = fac
        if not sensitivities:
            return res
        # -dG/dq0: G1_i has -a_q(i) (dQ_i/dq0 = I at fixed unknowns), the shooting row +1/h;
        # -dG/dq1: the shooting row -1/h
        N = (s + 1) * n
        dx = bk.zeros((N, 2 * n))
        for col in range(2 * n):
            rhs = bk.zeros(N)
            a_ = col % n
            if col < n:
                for i in range(s):
                    rhs[i * n:(i + 1) * n] = aq[i][:, a_]
                rhs[s * n + a_] = -1 / h
            else:
                rhs[s * n + a_] = 1 / h
            dx[:, col] = bk.solve_factored(fac, rhs)
        res.extra["dx_dq"] = dx
        da = dx[:s * n].reshape(s, n, 2 * n)
        dv0 = dx[s * n:]                                         # (n, 2n)
        dV = np.array([dv0 + sum((da[j] * self.A[i, j] for j in range(s)), bk.zeros((n, 2 * n))) * h
                       for i in range(s)], dtype=object)
        eye = np.concatenate([np.eye(n, dtype=object), bk.zeros((n, n))], axis=1)
        dQ = np.array([eye + dv0 * (self.c[i] * h)
                       + sum((da[j] * self.A2[i, j] for j in range(s)), bk.zeros((n, 2 * n))) * (h * h)
                       for i in range(s)], dtype=object)
        res.dV_dq0, res.dV_dq1 = dV[:, :, :n], dV[:, :, n:]
        res.dQ_dq0, res.dQ_dq1 = dQ[:, :, :n], dQ[:, :, n:]
        res.f_d_minus = -self.quad([PsiK[i].dot(res.dQ_dq0[i]) for i in range(s)], h)     # (12a)
        res.f_d_plus = -self.quad([PsiK[i].dot(res.dQ_dq1[i]) for i in range(s)], h)      # (12b)
        return res

    def resolve(self, t0, q0, t1, q1, x_pred, fac, max_iter=60):
        """Simplified Newton with the LU ``fac`` of a nearby solve (finite differences): L_d^E."""
        bk = self.bk
        x = x_pred.copy()
        h = t1 - t0
        for _ in range(max_iter):
            G, _, _ = self._residual(t0, q0, t1, q1, x, h, True, False)
            d = bk.solve_factored(fac, -G)
            x = x + d
            if bk.norm_inf(d) <= 10 * bk.eps * (1 + bk.norm_inf(x)):
                return self.action(t0, q0, t1, x)
        raise ExactFlowError("simplified Newton of the exact BVP did not converge")

    def action(self, t0, q0, t1, x):
        """L_d^E = int L dt by the Gauss weights, from packed unknowns [a | v0]."""
        s, n = self.s, self.n
        h = t1 - t0
        T, Q, V = self._nodes(t0, q0, h, x[:s * n].reshape(s, n), x[s * n:])
        return h * sum(self.b[i] * self._Lfn(T[i], *Q[i], *V[i]) for i in range(s))

    # --- quadrature ----------------------------------------------------------------------------
    def quad(self, vals, h):
        """int_{t0}^{t1} g dt from g at the nodes (Gauss weights)."""
        return sum((vals[i] * self.b[i] for i in range(self.s)), vals[0] * 0) * h

    def cumulative(self, vals, h):
        """int_{t0}^{T_i} g dt at every node (collocation matrix A), list of s values."""
        return [sum((vals[j] * self.A[i, j] for j in range(self.s)), vals[0] * 0) * h for i in range(self.s)]


# --- the integral forms of section 5 -----------------------------------------------------------
def f_minus_17(flow: ExactFlow, r: ExactBVPResult, h):
    """(17): f_d^{E-T} = int_{t0}^{t1} (int_{t0}^{s} Psi^T K dt) d_q0 v(s) ds."""
    inner = flow.cumulative(list(r.PsiK), h)
    return flow.quad([inner[i].dot(r.dV_dq0[i]) for i in range(flow.s)], h)


def f_plus_19(flow: ExactFlow, r: ExactBVPResult, h):
    """(19): f_d^{E+T} = -int_{t0}^{t1} (int_{s}^{t1} Psi^T K dt) d_q1 v(s) ds."""
    inner = flow.cumulative(list(r.PsiK), h)
    total = flow.quad(list(r.PsiK), h)
    return -flow.quad([(total - inner[i]).dot(r.dV_dq1[i]) for i in range(flow.s)], h)


def f_minus_17_other_inner(flow: ExactFlow, r: ExactBVPResult, h):
    """(17) with the inner integral int_s^{t1} Psi^T K dt in place of int_{t0}^s: a wrong formula,
    the negative control of (17) (it differs from f_d^{E-} by -(T + 2 f_d^{E-}), T = int_{t0}^{t1} Psi^T K,
    since int d_q0 v = -1)."""
    inner = flow.cumulative(list(r.PsiK), h)
    total = flow.quad(list(r.PsiK), h)
    return flow.quad([(total - inner[i]).dot(r.dV_dq0[i]) for i in range(flow.s)], h)


def f_plus_19_other_inner(flow: ExactFlow, r: ExactBVPResult, h):
    """(19) with the inner integral int_{t0}^s Psi^T K dt in place of int_s^{t1}: a wrong formula,
    the negative control of (19)."""
    inner = flow.cumulative(list(r.PsiK), h)
    return -flow.quad([inner[i].dot(r.dV_dq1[i]) for i in range(flow.s)], h)


def f_minus_20b_printed(flow: ExactFlow, r: ExactBVPResult, h):
    """(20b) as printed: int_{t_k}^{t_{k+1}} (int_{s}^{t_k} Psi^T K dt) d_{q_k} v(s) ds, i.e. (17) with
    the inner limits reversed: the negative of (17) (a sign slip in the transcription or the paper)."""
    inner = flow.cumulative(list(r.PsiK), h)
    return flow.quad([(-inner[i]).dot(r.dV_dq0[i]) for i in range(flow.s)], h)


def fd_gradient(flow: ExactFlow, r: ExactBVPResult, t0, q0, t1, q1, delta=None):
    """(dL_d^E/dq0, dL_d^E/dq1) by central differences of the boundary-value solve (each
    perturbed solve by simplified Newton from a first-order predictor), Richardson-extrapolated
    over delta and delta/2 (error O(delta^4)). Run ``flow`` at >= 20 digits more than the
    comparison needs."""
    bk = flow.bk
    n = flow.n
    with bk.context():
        delta = delta if delta is not None else mpmath.mpf(10) ** (-(flow.dps // 4))
        t0, t1 = bk.scalar(t0), bk.scalar(t1)
        q0, q1 = bk.array(q0), bk.array(q1)
        fac, dxdq = r.extra["fac"], r.extra["dx_dq"]
        out = []
        for k in range(2 * n):
            def L_at(eps):
                qa, qb = q0.copy(), q1.copy()
                (qa if k < n else qb)[k % n] += eps
                return flow.resolve(t0, qa, t1, qb, r.x + dxdq[:, k] * eps, fac)
            D = [(L_at(d) - L_at(-d)) / (2 * d) for d in (delta, delta / 2)]
            out.append((4 * D[1] - D[0]) / 3)
        g = np.array(out, dtype=object)
        return g[:n], g[n:]


def _mp(x):
    a = np.array(x, dtype=object)
    flat = a.reshape(-1)
    for i, e in enumerate(flat):
        if not isinstance(e, mpmath.mpf):
            flat[i] = mpmath.mpf(e)
    return a
