"""Section 7 for mechanical L = v^T M v / 2 - U(q) and affine k = K(q) v + b(q): the printed
q1 / v1 / Psi_1 systems of Euler I (7.1), Euler II (7.2) and the SPARK midpoint rule (7.3),
solved independently (``mpmath.findroot`` on the printed equations), against one SPARK step
(21) with the corresponding tableau; and the linear implicitness of Euler I (K, b constant)
and Euler II: a single Newton iteration on (21) lands on the solution.
"""
from __future__ import annotations

import mpmath
import numpy as np
import sympy

from ...core.backend import Backend
from ...core.spark import SparkMethod
from ...core.system import LagrangianSystem

DPS = 40


def affine_system(constant_K: bool) -> tuple[LagrangianSystem, list, list]:
    """Test systems of the form of section 7, with consistent data (q0, v0):
    constant K, b: M = diag(1, 2, 3), U = cos q1 + q2^4/4 + q1 q3, K = (1, -1, 2), b = 1/2;
    otherwise K(q) = (-q2, 0, 1), b(q) = q1/4 (the nonholonomic particle made affine), M = diag(1, 1, 2)."""
    q = list(sympy.symbols("q1:4"))
    R = sympy.Rational
    if constant_K:
        M = sympy.diag(1, 2, 3)
        U = sympy.cos(q[0]) + q[1] ** 4 / 4 + q[0] * q[2]
        K = sympy.Matrix([[1, -1, 2]])
        b = sympy.Matrix([R(1, 2)])
        q0, v0 = [R(3, 10), R(-1, 5), R(1, 10)], [R(1, 2), 1, 0]
    else:
        M = sympy.diag(1, 1, 2)
        U = q[0] ** 2 + q[1] ** 2 + sympy.cos(q[2])
        K = sympy.Matrix([[-q[1], 0, 1]])
        b = sympy.Matrix([q[0] / 4])
        q0, v0 = [1, R(1, 5), 0], [0, 1, R(-1, 4)]
    sysm = LagrangianSystem.mechanical_form(M, U, K, b, q=q, name="affine-const-K" if constant_K else "affine-K(q)")
    return sysm, q0, v0


def _mech_fns(sysm):
    mech = sysm.mechanical
    q = sysm.q
    grad = sympy.Matrix([sympy.diff(mech["U"], x) for x in q])
    f = sympy.lambdify(q, [mech["M"].tolist(), grad.tolist(), mech["K"].tolist(), mech["b"].tolist()], "mpmath")

    def at(qv):
        M, g, K, b = f(*qv)
        cv = lambda a: np.array(mpmath.matrix(a).tolist(), dtype=object)
        return cv(M), cv(g)[:, 0], cv(K), cv(b)[:, 0]
    return at


def printed_residual(kind, sysm, q0, v0, h, q1, v1, Psi1):
    """Residual rows of the printed system of 7.1 ('euler-i'), 7.2 ('euler-ii'), 7.3 ('midpoint')."""
    at = _mech_fns(sysm)
    M, _, _, _ = at(q0)
    if kind == "euler-i":
        r1 = q1 - q0 - v1 * h
        _, g, K, _ = at(q0)
    elif kind == "euler-ii":
        r1 = q1 - q0 - v0 * h
        _, g, K, _ = at(q1)
    else:
        r1 = q1 - q0 - (v0 + v1) * (h / 2)
        _, g, K, _ = at((q0 + q1) / 2)
    r2 = M.dot(v1) - M.dot(v0) + g * h + K.T.dot(Psi1) * h
    _, _, K1, b1 = at(q1)
    r3 = K1.dot(v1) + b1
    return np.concatenate([r1, r2, r3])


def solve_printed(kind, sysm, q0, v0, h, dps=DPS):
    """The printed system solved on its own (findroot from (q0 + h v0, v0, 0))."""
    n, m = sysm.n, sysm.m
    with mpmath.workdps(dps):
        def F(*z):
            z = np.array(z, dtype=object)
            return list(printed_residual(kind, sysm, q0, v0, h, z[:n], z[n:2 * n], z[2 * n:]))
        z0 = list(q0 + v0 * h) + list(v0) + [mpmath.mpf(0)] * m
        z = np.array(list(mpmath.findroot(F, z0, tol=mpmath.mpf(10) ** (-2 * dps + 10))), dtype=object)
        return z[:n], z[n:2 * n], z[2 * n:]


def spark_step(sysm, tab, q0, v0, h, dps=DPS):
    meth = SparkMethod(sysm, tab, dps=dps)
    with meth.backend.context():
        return meth.step(mpmath.mpf(0), meth.backend.array(q0), meth.backend.array(v0), mpmath.mpf(h))


def reduction(kind, tab, constant_K=False, h="1/10", dps=DPS):
    """SPARK step vs the printed system of ``kind``: max differences of q1, v1, Psi_1 and the
    stage-velocity statement (V_1 = v_1 for Euler I, V_1 = v_0 for Euler II, V_1 = (v0 + v1)/2 and
    Q_1 = (q0 + q1)/2 for the midpoint rule)."""
    sysm, q0, v0 = affine_system(constant_K)
    bk = Backend(dps)
    with bk.context():
        h = mpmath.mpf(sympy.Rational(h).p) / sympy.Rational(h).q
        q0, v0 = bk.array(q0), bk.array(v0)
        r = spark_step(sysm, tab, q0, v0, h, dps)
        pq, pv, pp = solve_printed(kind, sysm, q0, v0, h, dps)
        nrm = bk.norm_inf
        out = {"q1": nrm(r.q1 - pq), "v1": nrm(r.v1 - pv), "Psi1": nrm(r.Psi[0] - pp),
               "printed_residual": nrm(printed_residual(kind, sysm, q0, v0, h, r.q1, r.v1, r.Psi[0]))}
        out["diff"] = max(out["q1"], out["v1"], out["Psi1"])
        V1 = r.V[0]
        if kind == "euler-i":
            out["stage"] = nrm(V1 - r.v1)
        elif kind == "euler-ii":
            out["stage"] = nrm(V1 - v0)
        else:
            out["stage"] = max(nrm(V1 - (v0 + r.v1) / 2), nrm(r.Q[0] - (q0 + r.q1) / 2))
    return out


def one_newton_iteration(tab, constant_K, guess="generic", h="1/10", dps=DPS):
    """|G(x1)| / |G(x0)| after ONE Newton iteration on (21) from x0: 'generic' (V, Lambda, v1 away
    from the solution) or 'default' (V_i = v1 = v0, Psi = 0, the integrator's own start)."""
    sysm, q0, v0 = affine_system(constant_K)
    meth = SparkMethod(sysm, tab, dps=dps)
    bk = meth.backend
    with bk.context():
        h = mpmath.mpf(sympy.Rational(h).p) / sympy.Rational(h).q
        q0, v0 = bk.array(q0), bk.array(v0)
        p0 = sysm.momentum(bk, 0, q0, v0)
        x0 = meth.initial_guess(v0)
        if guess == "generic":
            x0 = x0 + np.array([mpmath.mpf(k % 3 + 1) / 3 for k in range(len(x0))], dtype=object)
        G0, J, _ = meth.residual(mpmath.mpf(0), q0, p0, h, x0)
        x1 = x0 + bk.solve(J, -G0)
        G1, _, _ = meth.residual(mpmath.mpf(0), q0, p0, h, x1, jacobian=False)
        return {"after_one": bk.norm_inf(G1), "before": bk.norm_inf(G0)}
