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
from ..models import arguments


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
            raise InputError(f"flow_jacobian: {str(x)[:40]!r} is not one of the {'coordinates' if what == 'q' else 'velocities'} "
                             f"{', '.join(labels)}")
    if len(set(out)) != len(out):
        raise InputError(f"flow_jacobian: the {'coordinates' if what == 'q' else 'velocities'} {list(names)} "
                         "name one of them twice")
    return out


def flow_jacobian(system, method, q0, v0, h, *, t0=None, dps=None, coords=None, rates=None, dependent=None,
                  tangent=None, select=None, params=None, how="ift", tol=None):
    """The Jacobian of one SPARK step map (q0, v0) -> (q1, v1), optionally restricted.

    By the implicit function theorem on (21) (module docstring), or by central differences at
    high precision; restricted to chosen coordinates and rates on the constraint manifold.

    Parameters
    ----------
    system : LagrangianSystem, Scene or str
        The system; a Scene or scene name also gives the initial data.
    method : str or SparkTableau
        A SPARK method name or tableau.
    q0, v0 : array_like or None
        The initial point (None: the scene's initial data).
    h : float
        The step size (nonzero).
    t0 : float, optional
        Initial time (default: the scene's t0 for a scene, else 0); a t0 given with a scene's
        initial data is used, never replaced by the scene's.
    dps : int, optional
        None (float64) or mpmath digits.
    coords, rates : list of int or str, optional
        Coordinates and velocities (indices or names; a rate may be named after its
        coordinate) spanning the restriction.
    dependent : list of int or str, optional
        The m velocities solved from the linearised constraint (default: chosen by
        column-pivoted QR of K among the velocities not in ``rates``).
    tangent : array_like, optional
        An explicit basis B (2n x r) instead of ``coords``/``rates``.
    select : list of int, optional
        Read-out indices into (q, v), with ``tangent``.
    params : dict, optional
        Parameter values of a parameterised system.
    how : {"ift", "difference"}, optional
        Implicit function theorem (default) or central differences (needs ``dps``).
    tol : float, optional
        Newton tolerance of the step.

    Returns
    -------
    FlowJacobian
        ``full`` (2n x 2n), the restricted ``J``, ``tangent``, ``select``, the end point;
        ``multipliers()`` gives the eigenvalues of J.

    Raises
    ------
    InputError
        For invalid arguments.

    Examples
    --------
    >>> import ldaspark
    >>> fj = ldaspark.flow_jacobian("skate", "gauss-2", None, None, 0.1)
    >>> fj.full.shape
    (6, 6)
    """
    from ..core import validate as V
    from ..core.spark import SparkMethod
    dps = V.check_dps(dps)
    V.check_choice(how, "flow_jacobian: how", ("ift", "difference"))
    V.check_newton_options(tol, 1, what="flow_jacobian: tol")
    V.check_tol_resolvable(tol, dps, what="flow_jacobian: tol")
    if t0 is not None:
        V.real_number(t0, "flow_jacobian: t0")
    system, scene = arguments.as_system(system, "flow_jacobian: system")
    t0, q0, v0 = V.point(system, 0 if scene is None and t0 is None else t0, q0, v0, "flow_jacobian: ", scene, dps)
    V.real_number(h, "flow_jacobian: h", nonzero=True)
    V.step_advances(t0, h, 1, dps, what="flow_jacobian: h")
    if params is not None:
        if not isinstance(params, dict):
            raise InputError(f"flow_jacobian: params must be a dict, got {V._describe(params)}")
        for key, val in params.items():
            V.param_value(key, val)
    if params:
        system = system.with_params(params)
    tab = arguments.as_tableau(method, "flow_jacobian: method")
    if how == "difference" and dps is None:
        raise InputError("flow_jacobian: how='difference' needs dps (differencing in float64 loses half the digits)")
    n = system.n
    if tangent is not None:
        if coords is not None or rates is not None or dependent is not None:
            raise InputError("flow_jacobian: give tangent and select, or coords / rates / dependent, not both")
        tangent = _check_tangent(tangent, n, dps)
        select = V.index_list(select, 2 * n, "flow_jacobian: select") if select is not None else None
    elif select is not None:
        raise InputError("flow_jacobian: select is read with tangent (for coordinates use coords= / rates=)")
    for nm, val in (("coords", coords), ("rates", rates), ("dependent", dependent)):
        if val is not None and (isinstance(val, (str, bytes, dict)) or not hasattr(val, "__iter__")):
            raise InputError(f"flow_jacobian: {nm} must be a list of indices or names, got {V._describe(val)}")
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
        _finite(full, t0)
        B, S = _restriction(system, bk, t0_, q0_, v0_, coords, rates, dependent, tangent, select)
        if B is None:
            return FlowJacobian(full, full, None, list(range(2 * n)), h_, dps, q1, v1)
        J = full[S, :].dot(B)
    return FlowJacobian(full, J, B, S, h_, dps, q1, v1)


def _finite(full, t0):
    """No NaN, infinity or complex entry is returned as a Jacobian."""
    ok = all((mpmath.isfinite(x) and isinstance(x, mpmath.mpf)) if isinstance(x, (mpmath.mpf, mpmath.mpc))
             else isinstance(x, (int, float, np.integer, np.floating)) and np.isfinite(x)
             for x in np.asarray(full).reshape(-1))
    if not ok:
        from ..core.errors import NonFiniteError
        raise NonFiniteError("flow_jacobian: the Jacobian of the step is not finite (L or k evaluated outside "
                             "its domain, or the step's Newton matrix is singular)", step=0, time=float(t0))


def _check_tangent(tangent, n, dps):
    """B (2n x r): a matrix of finite real numbers with 1 <= r <= 2n columns."""
    from ..core import validate as V
    try:
        B = np.asarray(tangent, dtype=object)
    except (ValueError, TypeError):
        B = None
    if B is None or B.ndim != 2 or B.shape[0] != 2 * n or not 1 <= B.shape[1] <= 2 * n:
        raise InputError(f"flow_jacobian: tangent must be a 2n x r matrix (2n = {2 * n}, 1 <= r <= 2n), "
                         f"got {V._describe(tangent)}")
    for i, e in enumerate(B.reshape(-1)):
        if isinstance(e, str):
            raise InputError(f"flow_jacobian: tangent entry {i} must be a number, got {V._describe(e)}")
        V.real_number(e, f"flow_jacobian: tangent entry {i}")
    # a basis: dependent columns gave a zero / repeated column of J and a spurious multiplier
    # (as coords=['x', 'x'] would, which is refused); decided in float64, dependent to its
    # resolution (sigma_min <= 2n eps sigma_max), so an exact basis is never refused
    sig = np.linalg.svd(np.array([[float(x) for x in row] for row in B]), compute_uv=False)
    if sig[0] == 0 or sig[-1] <= 2 * n * np.finfo(float).eps * sig[0]:
        raise InputError(f"flow_jacobian: the columns of tangent must be linearly independent (a basis of "
                         f"{B.shape[1]} directions), got singular values {', '.join(f'{x:.2g}' for x in sig)}")
    return tangent


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
        return B, list(select)
    if coords is None and rates is None:
        if dependent is not None:       # would be ignored: the full Jacobian has no dependent rates
            raise InputError("flow_jacobian: dependent is read with coords / rates (the velocities solved "
                             "from k = 0 along them); without them the full Jacobian is returned")
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
    # the dependent rates are solved from k_q dq + K_dep dv_dep = -K_free dv_free: K_dep must be
    # invertible (decided as _choose_dependent decides), else the solve below failed as a "Newton
    # matrix" error about a matrix the caller never chose
    if np.linalg.matrix_rank(np.array([[float(x) for x in row] for row in np.asarray(Kd)])) < m:
        names = [str(system.v[j]) for j in dep]
        raise InputError(f"flow_jacobian: the dependent velocities {names} cannot be solved from the linearised "
                         f"constraint: their block of K = dk/dv is singular at (t0, q0, v0); choose others")
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
    if len(others) < m:       # no dependent= can help: it must be disjoint from the rates
        raise InputError(f"flow_jacobian: K has no invertible m x m block outside the chosen rates: {len(rates)} rates "
                         f"leave {len(others)} velocities for the m = {m} dependent ones; give at most n - m = "
                         f"{K.shape[1] - m} rates")
    _, _, piv = scipy.linalg.qr(K[:, others], pivoting=True)
    dep = sorted(others[p] for p in piv[:m])
    if np.linalg.matrix_rank(K[:, dep]) < m:
        raise InputError("flow_jacobian: K has no invertible m x m block outside the chosen rates; give dependent=")
    return dep
