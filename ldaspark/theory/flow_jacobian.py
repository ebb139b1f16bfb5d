"""The Jacobian of the SPARK step map (q0, v0) -> (q1, v1), for stability studies.

One step of (21) solves G(x; q0, v0) = 0 for x = (V_1..V_s, Lambda_1..Lambda_s, v1) (the
residual of ``SparkMethod.residual``: rows (21b) s n, (21d) n, (21e) (s-1) m, (21f) m), and
q1 = q0 + h sum_j b_j V_j (21c). By the implicit function theorem at the solution,

    dx/dz = -G_x^{-1} G_z,    z = (q0, v0),    dq1/dz = [I, 0] + h sum_j b_j dV_j/dz,

with G_x the Newton matrix of the step and G_z the partials at fixed x. The initial point
enters (21b, d) through p0 = grad_v L(t0, q0, v0) and through Q_i = q0 + h sum_j a_ij V_j,
q1 = q0 + h sum_j b_j V_j (dQ_i/dq0 = dq1/dq0 = I), so with P = grad_v L, F = grad_q L and
h R = -K^T Lambda (plus h N of 3.3):

    (21b)_i:  d/dq0 = L_vq(i) - h sum_j a^_ij L_qq(j) - sum_j a~_ij R_q(j) - L_vq(0),  d/dv0 = -L_vv(0)
    (21d):    d/dq0 = L_vq(1) - h sum_j b^_j  L_qq(j) - sum_j b~_j  R_q(j) - L_vq(0),  d/dv0 = -L_vv(0)
    (21e)_l:  d/dq0 = sum_j omega_lj k_q(j),                                            d/dv0 = 0
    (21f):    d/dq0 = k_q(1),                                                           d/dv0 = 0

where (i) is the stage point (T_i, Q_i, V_i, Lambda_i), (1) the end point (t1, q1, v1) and
(0) the initial one; L_vq = d(grad_v L)/dq, R_q = d(h R)/dq. ``how="difference"`` instead
differences the step map (central differences with step 10^(-dps/3) at ``dps`` digits, error
O(10^(-2 dps/3))): an independent check of the formulas above.

Restriction to chosen coordinates ("lean, steer and their rates on the constraint manifold"):
the perturbations of the initial point are the columns of a tangent basis B (2n x r): a chosen
coordinate q_i moves alone (dq = e_i), a chosen rate v_j moves with the ``dependent``
velocities (m of them, K restricted to them invertible) adjusted so that the linearised
constraint k_q dq + k_v dv = 0 holds; the other free velocities stay fixed. The restricted
Jacobian is S (d(q1, v1)/d(q0, v0)) B with S reading the same coordinates and rates at the end
of the step. When those coordinates and rates evolve as a closed system to first order (at a
relative equilibrium whose other coordinates are cyclic, as the bicycle's lean and steer about
upright straight running), its eigenvalues mu are those of exp(h A) of the linearised flow to
the method's local error: lambda = log(mu) / h converges to the eigenvalues of A with order 2s
for the s-stage Gauss methods (``eigenvalues``). A holonomic constraint given in its velocity
form (5.1) is not seen by B: perturb only coordinates on which it does not depend to first
order at the point (the bicycle's front contact height has zero lean and steer derivatives at
upright), or pass your own ``tangent``.
"""
from __future__ import annotations

from dataclasses import dataclass

import mpmath
import numpy as np

from ..core.errors import InputError


@dataclass
class FlowJacobian:
    """Result of ``flow_jacobian``: ``full`` = d(q1, v1)/d(q0, v0) (2n x 2n), ``J`` the
    restricted Jacobian S full B (r x r; ``full`` when no restriction), ``tangent`` B,
    ``select`` the indices into (q, v) read by S, ``h``, ``dps`` and the step's end point."""

    full: np.ndarray
    J: np.ndarray
    tangent: np.ndarray
    select: list
    h: object
    dps: int | None
    q1: np.ndarray
    v1: np.ndarray

    def multipliers(self) -> list:
        """Eigenvalues mu of J (complex; mpc at mpmath precision)."""
        if self.dps is None:
            return list(np.linalg.eigvals(np.asarray(self.J, dtype=float)).astype(complex))
        with mpmath.workdps(self.dps):
            ev = mpmath.eig(mpmath.matrix(self.J.tolist()), left=False, right=False)
            return [mpmath.mpc(e) for e in ev]

    def eigenvalues(self) -> list:
        """lambda = log(mu) / h (principal logarithm: needs |Im lambda| h < pi), sorted by
        (real, imaginary) part."""
        if self.dps is None:
            lam = [np.log(mu) / float(self.h) for mu in self.multipliers()]
            return sorted(lam, key=lambda z: (z.real, z.imag))
        with mpmath.workdps(self.dps):
            lam = [mpmath.log(mu) / mpmath.mpf(self.h) for mu in self.multipliers()]
            return sorted(lam, key=lambda z: (float(mpmath.re(z)), float(mpmath.im(z))))


def _index(names, system, what):
    out = []
    syms = system.q if what == "q" else system.v
    for x in names:
        if isinstance(x, (int, np.integer)) and not isinstance(x, bool):
            if not 0 <= int(x) < system.n:
                raise InputError(f"flow_jacobian: index {x} out of range 0..{system.n - 1}")
            out.append(int(x))
            continue
        labels = [str(s) for s in syms]
        plain = [str(s) for s in system.q]          # a rate may be named after its coordinate
        if str(x) in labels:
            out.append(labels.index(str(x)))
        elif what == "v" and str(x) in plain:
            out.append(plain.index(str(x)))
        else:
            raise InputError(f"flow_jacobian: {x!r} is not one of the {'coordinates' if what == 'q' else 'velocities'} "
                             f"{', '.join(labels)}")
    return out


def flow_jacobian(system, method, q0, v0, h, *, t0=0, dps=None, coords=None, rates=None, dependent=None,
                  tangent=None, select=None, params=None, how="ift", tol=None):
    """The Jacobian of one SPARK step at (t0, q0, v0), optionally restricted (module docstring).

    ``system``: LagrangianSystem, Scene or scene name (q0, v0 None: the scene's initial data);
    ``method``: SPARK method name or tableau;
    ``dps``: None (float64) or mpmath digits; ``coords``/``rates``: coordinates and velocities
    (indices or names; a rate may be named after its coordinate) spanning the restriction;
    ``dependent``: the m velocities solved from the linearised constraint (default: chosen by
    column-pivoted QR of K among the velocities not in ``rates``); ``tangent``/``select``: an
    explicit basis B (2n x r) and read-out indices into (q, v) instead; ``how``: "ift" (implicit
    function theorem, default) or "difference" (central differences; needs ``dps``).
    Returns a ``FlowJacobian``."""
    from ..core.families import get_method
    from ..models.scenes import Scene, get_scene
    from ..core.spark import SparkMethod
    from ..core.tableau import SparkTableau
    if isinstance(system, str):
        system = get_scene(system)
    if isinstance(system, Scene):
        if q0 is None or v0 is None:       # a scene's own initial data (at the working precision)
            t0, q_s, v_s = system.initial(dps)
            q0 = q_s if q0 is None else q0
            v0 = v_s if v0 is None else v0
        system = system.system
    if q0 is None or v0 is None:
        raise InputError("flow_jacobian: give q0 and v0 (or a Scene / scene name for its initial data)")
    if params:
        system = system.with_params(params)
    tab = method if isinstance(method, SparkTableau) else get_method(method)
    if how not in ("ift", "difference"):
        raise InputError(f"flow_jacobian: how must be 'ift' or 'difference', got {how!r}")
    if how == "difference" and dps is None:
        raise InputError("flow_jacobian: how='difference' needs dps (differencing in float64 loses half the digits)")
    sm = SparkMethod(system, tab, dps=dps, tol=tol, newton="full")
    bk = sm.backend
    n = system.n
    with bk.context():
        t0_, h_ = bk.scalar(t0), bk.scalar(h)
        q0_, v0_ = bk.array(q0), bk.array(v0)
        if q0_.shape != (n,) or v0_.shape != (n,):
            raise InputError(f"flow_jacobian: q0 and v0 need {n} entries")
        if how == "ift":
            full, q1, v1 = _ift(sm, t0_, q0_, v0_, h_)
        else:
            full, q1, v1 = _difference(sm, t0_, q0_, v0_, h_)
        B, S = _restriction(system, bk, t0_, q0_, v0_, coords, rates, dependent, tangent, select)
        if B is None:
            return FlowJacobian(full, full, None, list(range(2 * n)), h_, dps, q1, v1)
        J = full[S, :].dot(B)
    return FlowJacobian(full, J, B, S, h_, dps, q1, v1)


def _step(sm, t0, q0, v0, h):
    r = sm.step(t0, q0, v0, h)
    return r


def _ift(sm, t0, q0, v0, h):
    """d(q1, v1)/d(q0, v0) by the implicit function theorem (module docstring)."""
    system, bk, tab = sm.system, sm.backend, sm.tab
    s, n, m = sm.s, sm.n, sm.m
    r = _step(sm, t0, q0, v0, h)
    x = r.x
    p0 = system.momentum(bk, t0, q0, v0)
    _, Gx, (T, Q, q1) = sm.residual(t0, q0, p0, h, x, jacobian=True)
    V, Lam, v1 = sm.unpack(x)
    st = [system.stage(bk, T[i], Q[i], V[i], Lam[i], True, h=h) for i in range(s)]
    fin = system.stage(bk, t0 + h, q1, v1, bk.zeros(m), True)
    ini = system.stage(bk, t0, q0, v0, bk.zeros(m), True)
    Gz = bk.zeros((sm.size, 2 * n))
    Lqq = [e.L_qq for e in st]
    Rq = [e.R_q for e in st]
    for i in range(s):
        blk = st[i].L_vq - ini.L_vq
        for j in range(s):
            if tab.A_hat[i, j]:
                blk = blk - Lqq[j] * (tab.A_hat[i, j] * h)
            if tab.A_tilde[i, j]:
                blk = blk - Rq[j] * tab.A_tilde[i, j]
        Gz[i * n:(i + 1) * n, :n] = blk
        Gz[i * n:(i + 1) * n, n:] = -ini.L_vv
    r_d, r_e, r_f = s * n, s * n + n, s * n + n + (s - 1) * m
    blk = fin.L_vq - ini.L_vq
    for j in range(s):
        if tab.b_hat[j]:
            blk = blk - Lqq[j] * (tab.b_hat[j] * h)
        if tab.b_tilde[j]:
            blk = blk - Rq[j] * tab.b_tilde[j]
    Gz[r_d:r_e, :n] = blk
    Gz[r_d:r_e, n:] = -ini.L_vv
    for l in range(s - 1):
        blk = bk.zeros((m, n))
        for j in range(s):
            if tab.omega[l, j]:
                blk = blk + st[j].k_q * tab.omega[l, j]
        Gz[r_e + l * m:r_e + (l + 1) * m, :n] = blk
    Gz[r_f:, :n] = fin.k_q
    dx = -bk.solve(Gx, Gz)                       # (size, 2n)
    dV = dx[:s * n].reshape(s, n, 2 * n)
    dv1 = dx[s * n + s * m:]
    dq1 = tab.b.dot(dV.reshape(s, n * 2 * n)).reshape(n, 2 * n) * h
    for i in range(n):
        dq1[i, i] = dq1[i, i] + 1
    return np.concatenate([dq1, dv1]), r.q1, r.v1


def _difference(sm, t0, q0, v0, h):
    """d(q1, v1)/d(q0, v0) by central differences of the step map at the working precision
    (step 10^(-dps/3): truncation O(10^(-2 dps/3)), round-off O(10^(-2 dps/3)) after the
    division; the Newton tolerance is the working precision). The perturbed initial points
    need not satisfy k = 0: the step map is defined on all of (q0, v0) space."""
    n = sm.n
    d = mpmath.mpf(10) ** (-(sm.dps // 3))
    cols = []
    r0 = _step(sm, t0, q0, v0, h)
    for k in range(2 * n):
        outs = []
        for sgn in (1, -1):
            q, v = q0.copy(), v0.copy()
            if k < n:
                q[k] = q[k] + sgn * d
            else:
                v[k - n] = v[k - n] + sgn * d
            r = _step(sm, t0, q, v, h)
            outs.append(np.concatenate([r.q1, r.v1]))
        cols.append((outs[0] - outs[1]) / (2 * d))
    full = np.array(cols, dtype=object).T
    return full, r0.q1, r0.v1


def _restriction(system, bk, t0, q0, v0, coords, rates, dependent, tangent, select):
    """(B, S): the tangent basis and the read-out indices (module docstring), or (None, None)."""
    n, m = system.n, system.m
    if tangent is not None:
        B = np.asarray(tangent, dtype=object if bk.is_mp else float)
        if B.ndim != 2 or B.shape[0] != 2 * n:
            raise InputError(f"flow_jacobian: tangent must be a 2n x r matrix (2n = {2 * n})")
        if select is None or len(select) != B.shape[1]:
            raise InputError("flow_jacobian: give select (r indices into (q, v)) with tangent")
        return B, [int(i) for i in select]
    if coords is None and rates is None:
        return None, None
    ci = _index(coords or [], system, "q")
    ri = _index(rates or [], system, "v")
    st = system.stage(bk, t0, q0, v0, bk.zeros(m), True)
    kq, kv = st.k_q, st.k_v
    if dependent is None:
        dep = _choose_dependent(kv, ri, m)
    else:
        dep = _index(dependent, system, "v")
    if len(dep) != m or set(dep) & set(ri):
        raise InputError(f"flow_jacobian: need m = {m} dependent velocities disjoint from the rates, got {dep}")
    Kd = kv[:, dep]
    r = len(ci) + len(ri)
    B = bk.zeros((2 * n, r))
    for col, i in enumerate(ci):
        B[i, col] = 1
        corr = bk.solve(Kd, -kq[:, i])           # k_q e_i + K_dep dv_dep = 0
        for a, j in enumerate(dep):
            B[n + j, col] = corr[a]
    for col, j in enumerate(ri, start=len(ci)):
        B[n + j, col] = 1
        corr = bk.solve(Kd, -kv[:, j])
        for a, jj in enumerate(dep):
            B[n + jj, col] = corr[a]
    return B, ci + [n + j for j in ri]


def _choose_dependent(kv, rates, m):
    """m velocity indices outside ``rates`` whose columns of K are best conditioned (QR with
    column pivoting in float64)."""
    import scipy.linalg
    K = np.array([[float(x) for x in row] for row in np.asarray(kv)])
    others = [j for j in range(K.shape[1]) if j not in rates]
    _, _, piv = scipy.linalg.qr(K[:, others], pivoting=True)
    dep = sorted(others[p] for p in piv[:m])
    if np.linalg.matrix_rank(K[:, dep]) < m:
        raise InputError("flow_jacobian: K has no invertible m x m block outside the chosen rates; give dependent=")
    return dep
