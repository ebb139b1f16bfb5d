"""Section 5 (and the anti-symmetries of 4.1) on the exact flow of ``exact_flow``: residuals of
(16), (18), (17), (19), (20a-b), the exact discrete Euler-Lagrange equations, the
anti-symmetries, and section 5.1 (holonomic: the exact forces vanish on tangent variations).

Every function returns plain floats (cached: arguments are hashable, offsets are tuples):
residuals relative to the size of the compared quantities, and the size of what a broken claim
would leave (the negative controls)."""
from __future__ import annotations

import functools

import mpmath
import numpy as np

from ...core.backend import Backend
from ...models.scenes import get_scene
from .exact_flow import (ExactFlow, f_minus_17, f_minus_17_other_inner, f_minus_20b_printed, f_plus_19,
                         f_plus_19_other_inner, fd_gradient)

DPS = 32          # working precision of the exact flow; finite differences at DPS + 20
STAGES = 10       # Gauss collocation nodes: |q - q_ref| ~ 4e-31 at h = 0.1 on the particle


def _nrm(x):
    return float(max((abs(v) for v in np.asarray(x).reshape(-1)), default=0))


@functools.lru_cache(maxsize=None)
def flow_for(scene_name: str, dps: int = DPS, stages: int = STAGES) -> ExactFlow:
    return ExactFlow(get_scene(scene_name).system, dps=dps, stages=stages)


def endpoints(scene_name, h="0.1", dps=DPS, stages=STAGES, offset=None):
    """(t0, q0, t1, q1): the scene's initial data and the exact flow after h; ``offset`` (a list)
    (a tuple) shifts q1 off the exact constraint manifold C_d (then k(t0, q0, v0) != 0 is a first integral)."""
    fl, (t0, q0, v0) = flow_for(scene_name, dps, stages), get_scene(scene_name).initial(dps)
    with mpmath.workdps(dps):
        h = mpmath.mpf(h)
        q1, _, _ = fl.ivp(t0, q0, v0, h)
        if offset is not None:
            q1 = q1 + np.array([mpmath.mpf(x) for x in offset], dtype=object)
        return t0, np.array(q0, dtype=object), t0 + h, q1


@functools.lru_cache(maxsize=64)
def exact_identities(scene_name, h="0.1", offset=None, dps=DPS, stages=STAGES):
    """(16), (18) with dL_d^E/dq by finite differences at dps + 20 digits; (17), (19) and the
    printed (20b) against (12a-b) by quadrature. Residuals relative to max(|p0|, |p1|, |grad|)."""
    fd_dps = dps + 20
    t0, q0, t1, q1 = endpoints(scene_name, h, fd_dps, stages, offset)
    fl = flow_for(scene_name, fd_dps, stages)
    with mpmath.workdps(fd_dps):
        r = fl.bvp(t0, q0, t1, q1)
        g0, g1 = fd_gradient(fl, r, t0, q0, t1, q1, delta=mpmath.mpf(10) ** -12)
        hh = t1 - t0
        scale = max(_nrm(r.p0), _nrm(r.p1), _nrm(g0), _nrm(g1))
        fscale = max(_nrm(r.f_d_minus), _nrm(r.f_d_plus), 1e-300)
        out = {
            "16": _nrm(g0 + r.p0 + r.f_d_minus) / scale,
            "18": _nrm(g1 - r.p1 + r.f_d_plus) / scale,
            "16-without-force": _nrm(g0 + r.p0) / scale,
            "18-without-force": _nrm(g1 - r.p1) / scale,
            "17": _nrm(f_minus_17(fl, r, hh) - r.f_d_minus) / fscale,
            "19": _nrm(f_plus_19(fl, r, hh) - r.f_d_plus) / fscale,
            # negative controls of (17), (19): the inner integral over the other part of
            # [t0, t1] (int_s^{t1} in (17), int_{t0}^s in (19)), each against the same side
            "17-other-inner": _nrm(f_minus_17_other_inner(fl, r, hh) - r.f_d_minus) / fscale,
            "19-other-inner": _nrm(f_plus_19_other_inner(fl, r, hh) - r.f_d_plus) / fscale,
            "20b-printed": _nrm(f_minus_20b_printed(fl, r, hh) - r.f_d_minus) / fscale,
            "20b-corrected": _nrm(-f_minus_20b_printed(fl, r, hh) - r.f_d_minus) / fscale,
            "f_d_minus": _nrm(r.f_d_minus), "f_d_plus": _nrm(r.f_d_plus),
            "k0": _nrm(r.k0), "bvp_residual": float(r.residual), "L_d": float(r.L_d),
            # 2.1: k is a first integral of (6)-(7): constant (= k0, not 0) along the flow off C_d
            "first_integral": max(_nrm(fl.system.constraint(fl.bk, r.T[i], r.Q[i], r.V[i]) - r.k0)
                                  for i in range(fl.s)),
        }
    return out


@functools.lru_cache(maxsize=16)
def exact_del(scene_name, h="0.1", dps=DPS, stages=STAGES):
    """The exact discrete Euler-Lagrange equations at t_1 of an exact trajectory t_0, t_1, t_2:
    D4 L^E(t0,q0,t1,q1) + D2 L^E(t1,q1,t2,q2) + f^{E+}(t0..) + f^{E-}(t1..) = 0 with the forces in
    the forms (20a) (= (19) on [t0, t1]) and (20b) corrected (= (17) on [t1, t2]); the printed
    (20b) and the force-free sum as controls."""
    fd_dps = dps + 20
    fl, (t0, q0, v0) = flow_for(scene_name, fd_dps, stages), get_scene(scene_name).initial(fd_dps)
    with mpmath.workdps(fd_dps):
        hh = mpmath.mpf(h)
        q1, v1, _ = fl.ivp(t0, q0, v0, hh)
        q2, _, _ = fl.ivp(t0 + hh, q1, v1, hh)
        q0 = np.array(q0, dtype=object)
        ra = fl.bvp(t0, q0, t0 + hh, q1)
        rb = fl.bvp(t0 + hh, q1, t0 + 2 * hh, q2)
        _, d4 = fd_gradient(fl, ra, t0, q0, t0 + hh, q1, delta=mpmath.mpf(10) ** -12)
        d2, _ = fd_gradient(fl, rb, t0 + hh, q1, t0 + 2 * hh, q2, delta=mpmath.mpf(10) ** -12)
        f20a = f_plus_19(fl, ra, hh)
        f20b_printed = f_minus_20b_printed(fl, rb, hh)
        scale = max(_nrm(ra.p1), _nrm(d4), _nrm(d2))
        return {"del": _nrm(d4 + d2 + f20a - f20b_printed) / scale,        # corrected (20b) = -printed
                "del-printed-20b": _nrm(d4 + d2 + f20a + f20b_printed) / scale,
                "del-without-forces": _nrm(d4 + d2) / scale,
                "momentum-continuity": _nrm(ra.p1 - rb.p0) / scale}


@functools.lru_cache(maxsize=16)
def antisymmetry(scene_name, h="0.1", offset=None, dps=DPS, stages=STAGES):
    """Section 4.1: L^E(t1,q1,t0,q0) = -L^E(t0,q0,t1,q1), f^{E+}(rev) = -f^{E-}, f^{E-}(rev) = -f^{E+};
    control: the wrong pairing f^{E+}(rev) + f^{E+}."""
    t0, q0, t1, q1 = endpoints(scene_name, h, dps, stages, offset)
    fl = flow_for(scene_name, dps, stages)
    with mpmath.workdps(dps):
        fw = fl.bvp(t0, q0, t1, q1)
        rv = fl.bvp(t1, q1, t0, q0)
        fs = max(_nrm(fw.f_d_minus), _nrm(fw.f_d_plus))
        return {"L": float(abs(fw.L_d + rv.L_d) / abs(fw.L_d)),
                "f_plus": _nrm(rv.f_d_plus + fw.f_d_minus) / fs,
                "f_minus": _nrm(rv.f_d_minus + fw.f_d_plus) / fs,
                "wrong-pairing": _nrm(rv.f_d_plus + fw.f_d_plus) / fs,
                "v0-rev-is-v1": _nrm(rv.v0 - fw.v1)}


@functools.lru_cache(maxsize=16)
def holonomic_exact(scene_name="pendulum", h="0.1", offset=None, dps=DPS, stages=STAGES):
    """Section 5.1: f^{E+-} restricted to variations tangent to the constraint (K dq = 0 at the
    endpoint) vanish; the full covectors (normal reactions) do not. On a nonholonomic scene the
    same restriction does not vanish (control)."""
    t0, q0, t1, q1 = endpoints(scene_name, h, dps, stages, offset)
    fl = flow_for(scene_name, dps, stages)
    S = fl.system
    bk = Backend(dps)
    with mpmath.workdps(dps):
        r = fl.bvp(t0, q0, t1, q1)

        def proj(t, q, v):
            K = np.array(S.saddle_matrix(bk, t, q, v)[S.n:, :S.n], dtype=object)
            KK = mpmath.matrix(K.dot(K.T).tolist())
            return np.eye(S.n, dtype=object) - K.T.dot(np.array(mpmath.inverse(KK).tolist(), dtype=object)).dot(K)
        tm = _nrm(proj(t0, q0, r.v0).dot(r.f_d_minus))
        tp = _nrm(proj(t1, q1, r.v1).dot(r.f_d_plus))
        return {"tangential": max(tm, tp), "full": max(_nrm(r.f_d_minus), _nrm(r.f_d_plus)),
                "k0": _nrm(r.k0)}


@functools.lru_cache(maxsize=16)
def reference_accuracy(scene_name="particle", h="0.1", dps=DPS, stages=STAGES):
    """The exact flow against an independent reference: mpmath's Taylor ODE solver on (3a-b)
    (``ODEReference``) for the IVP, and the BVP's v0 against the consistent v0 it came from."""
    from .orders import ODEReference
    sc = get_scene(scene_name)
    fl = flow_for(scene_name, dps, stages)
    with mpmath.workdps(dps):
        t0, q0, v0 = sc.initial(dps)
        hh = mpmath.mpf(h)
        q1, v1, _ = fl.ivp(t0, q0, v0, hh)
        qr, vr, _ = ODEReference(sc.system, t0, q0, v0, dps=dps)(t0 + hh)
        r = fl.bvp(t0, q0, t0 + hh, q1)
        return {"ivp": max(_nrm(q1 - qr), _nrm(v1 - vr)), "bvp_v0": _nrm(r.v0 - np.array(v0, dtype=object)),
                "k0": _nrm(r.k0)}
