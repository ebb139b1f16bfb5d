"""The symmetry claims of section 4.1 under (23): L_d and f_d^{+/-} under exchange of the
endpoints, and time reversal of the IVP step, on the boundary-value solve of ``discrete``."""
from __future__ import annotations

import time

from ..core.backend import Backend
from ..core.spark import SparkMethod
from .discrete import (ENTRY_RANK_FACTOR, DiscreteBVP, _rank_info, _solve_and_differentiate, _svd, base_point,
                       discrete_lagrangian, entries_floor, entries_undecided, ivp_step)
from ..models import arguments


def check_symmetry(system, tableau, t0, q0, v0, h, dps=40):
    """The symmetry claims under (23), measured at one base point.

    With the forward BVP at (t0, q0, t1, q1) from one IVP step and the reversed BVP at
    (t1, q1, t0, q0): L_d(t1, q1, t0, q0) + L_d(t0, q0, t1, q1),
    f_d^+(t1, q1, t0, q0) + f_d^-(t0, q0, t1, q1), f_d^-(t1, q1, t0, q0) + f_d^+(t0, q0, t1, q1)
    and the IVP round trip ``|Phi_{-h}(Phi_h(y)) - y|``, each relative to the size of the
    compared quantities. For a rank-deficient J the f_d comparisons are restricted to
    directions in which the BVP stays solvable.

    Parameters
    ----------
    system : LagrangianSystem, Scene or str
        The system (1); a Scene or a scene name also gives the initial data (q0, v0 None).
    tableau : SparkTableau
        The SPARK method (21).
    t0 : float
        Initial time.
    q0, v0 : array_like or None
        The base point, consistent: k(t0, q0, v0) = 0 to the working precision (refused with
        ``InconsistentInitialDataError`` otherwise: the step ends on k = 0, so the round trip and
        the reversed BVP cannot return to data off it); None with a scene.
    h : float
        Step size.
    dps : int, optional
        Working digits (default 40).

    Returns
    -------
    dict
        ``symmetry-Ld``, ``symmetry-fd-plus``, ``symmetry-fd-minus``, ``symmetry-Phi``
        (relative residuals: at the precision floor for a symmetric method), ``wellposed``,
        ``rank_at_entries_precision`` (True: a singular value of J that the uncertainty of the
        tableau's entries can move to zero was taken as zero, ``entries_undecided`` its numbers).

    Examples
    --------
    >>> import ldaspark
    >>> sc = ldaspark.get_scene("skate")
    >>> r = ldaspark.check_symmetry(sc.system, ldaspark.gauss(2), sc.t0, sc.q0, sc.v0, 0.1, dps=30)
    >>> bool(r["symmetry-Ld"] < 1e-25 and r["symmetry-Phi"] < 1e-25)
    True
    """
    from ..core import validate
    system, tableau, t0, q0, v0 = arguments.theory_args(system, tableau, t0, q0, v0, h, dps, "check_symmetry",
                                                         consistent=True)
    t_start = time.time()
    bk = Backend(dps)
    with bk.context():
        t0_, q0_, v0_ = bk.scalar(t0), bk.array(q0), bk.array(v0)
        t1, q1, xg = base_point(system, tableau, t0_, q0_, v0_, h, dps)
        bvp = DiscreteBVP(system, tableau, dps)
        # entries known to their digits (float64, decimals): a singular value of J that they can move
        # to zero is zero here (float64 gauss-2 on mp-particles at dps 50: the exact method's zero
        # sigma at 4.8e-22 sigma_max, above 10^-25, solved ungauged: L_d "not symmetric" by 1.3e-3)
        undecided, entries = None, 0.0
        if entries_floor(tableau) > 0:
            J = bvp.evaluate(t0_, q0_, t1, q1, xg)[1]
            sig, r0 = _rank_info(bk, J, dps)[:2]
            undecided = entries_undecided(system, tableau, t0_, q0_, v0_, h, dps, [x / sig[0] for x in sig], r0)
            if undecided is not None:
                entries = undecided["bound"] * (1 + 1e-6) / ENTRY_RANK_FACTOR

        def solve(ta, qa, tb, qb, x, ref=None):
            if not entries:
                return discrete_lagrangian(system, tableau, ta, qa, tb, qb, dps=dps, x_guess=x, gauge_ref=ref)
            return _solve_and_differentiate(bvp, ta, qa, tb, qb, x, gauge_ref=ref, entries=entries)
        fwd = solve(t0_, q0_, t1, q1, xg)
        V, Lam, v1, v0x = bvp.unpack(fwd.x)
        # adjoint stage values under (23): V_i -> V_{s+1-i}, Psi_i -> Psi_{s+1-i} (Lambda flips sign)
        xr = bvp.pack(V[::-1], -Lam[::-1], v0x, v1)
        rev = solve(t1, q1, t0_, q0_, xr, xr)
        sL = abs(fwd.L_d + rev.L_d) / max(abs(fwd.L_d), 1e-300)
        (P0, dim0), (P1, dim1) = _tangent_projector(fwd, 0), _tangent_projector(rev, 0)
        # f_d^+(rev) pairs with variations of fwd q0 = rev q1; f_d^-(rev) with fwd q1 = rev q0
        a, b = P0.dot(fwd.f_d_minus + rev.f_d_plus), P1.dot(fwd.f_d_plus + rev.f_d_minus)
        norms_p = (bk.norm_inf(P0.dot(fwd.f_d_minus)), bk.norm_inf(P0.dot(rev.f_d_plus)))
        norms_m = (bk.norm_inf(P1.dot(fwd.f_d_plus)), bk.norm_inf(P1.dot(rev.f_d_minus)))
        # relative to the covectors involved (p0 may vanish: a scene at rest)
        sc = max(max(norms_p), max(norms_m), bk.norm_inf(fwd.p0), bk.norm_inf(fwd.p1),
                 bk.norm_inf(fwd.f_d_minus), bk.norm_inf(fwd.f_d_plus), 1e-300)
        sfp = bk.norm_inf(a) / sc
        sfm = bk.norm_inf(b) / sc
        # the unrestricted covectors, to show the restriction matters
        sc_full = max(bk.norm_inf(fwd.f_d_minus), bk.norm_inf(fwd.f_d_plus), bk.norm_inf(fwd.p0),
                      1e-300)                 # a scene at rest: all of them zero
        full_p = bk.norm_inf(fwd.f_d_minus + rev.f_d_plus) / sc_full
        full_m = bk.norm_inf(fwd.f_d_plus + rev.f_d_minus) / sc_full
        # Phi_{-h} o Phi_h
        meth = SparkMethod(system, tableau, dps=dps, newton="full")
        hh = bk.scalar(h)
        r1 = ivp_step(meth, t0_, q0_, v0_, hh)          # the base point's step (memoized in the ledger)
        r2 = meth.step(r1.t1, r1.q1, r1.v1, -hh)
        sc_y = max(bk.norm_inf(q0_), bk.norm_inf(v0_), 1.0)
        sPhi = max(bk.norm_inf(r2.q1 - q0_), bk.norm_inf(r2.v1 - v0_)) / sc_y
    return {"symmetry-Ld": float(sL), "symmetry-fd-plus": float(sfp), "symmetry-fd-minus": float(sfm),
            "symmetry-Phi": float(sPhi), "wellposed": fwd.wellposed,
            "tangent_dim": (dim0, dim1),
            "fd_restricted_norm": (float(bk.norm_inf(P0.dot(fwd.f_d_minus))), float(bk.norm_inf(P1.dot(fwd.f_d_plus)))),
            "fd_plus_identity_norms": tuple(float(x) for x in norms_p),
            "fd_minus_identity_norms": tuple(float(x) for x in norms_m),
            "symmetry-fd-unrestricted": (float(full_p), float(full_m)),
            "rank_deficiency": fwd.rank_deficiency, "dps": dps, "seconds": time.time() - t_start,
            "rank_at_entries_precision": undecided is not None,
            **({"entries_undecided": undecided} if undecided is not None else {})}


def _tangent_projector(res, which):
    """Orthogonal projector onto the pure-q0 (which=0) or pure-q1 (which=1) variations tangent
    to the discrete constraint manifold C_d, where v0 stays consistent, k(t0, q0, v0) = 0 (the
    IVP's assumption; off C_d the forward and the reversed BVP differ, so (23) cannot hold there).
    Well-posed J: null space of d k(t0, q0, v0(q0, q1)) / dq. Deficient J: null space of
    W^T dG/dq (first-order solvability; the gauge pin keeps v0 consistent)."""
    g = res.extra["gauge"]
    bk = Backend(res.dps)
    if g is None:
        M = res.extra["dk0_dq"][which]
    else:
        M = g.W_left.T.dot(res.extra["dG_dq"][which])
    n = M.shape[1]
    # pad to at least square: the full right singular basis (a deficient J at a large h can give
    # more conditions than coordinates)
    Mp = bk.zeros((max(n, M.shape[0]), n))
    Mp[:M.shape[0]] = M
    U, sig, Vh = _svd(bk, Mp)
    k = sum(1 for x in sig if float(x) > 1e-8 * max(float(sig[0]), 1e-300))
    Nt = Vh[k:, :]                            # orthonormal basis of the tangent directions
    return Nt.T.dot(Nt), Nt.shape[0]
