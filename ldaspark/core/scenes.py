"""The paper's scenes (section 8) with its parameters and initial data, plus a holonomic
pendulum for section 5.1 and a vertical rolling disk as a user-style example.

Each scene states only L and k (or M, U, K, b); the library derives the rest. Parameters and
initial data are exact sympy numbers so that the mpmath path carries full precision.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import mpmath
import numpy as np
import sympy
from sympy import Rational as R

from .errors import InputError
from .system import LagrangianSystem


@dataclass
class Scene:
    """A system with initial data. ``exact`` (optional) maps t (sympy symbol) to sympy
    expressions for q(t), v(t), psi(t)."""

    name: str
    system: LagrangianSystem
    t0: object
    q0: list
    v0: list
    description: str = ""
    exact: dict | None = None
    params: dict = field(default_factory=dict)
    _exact_fns: dict = field(default_factory=dict, repr=False)

    def initial(self, dps=None):
        """(t0, q0, v0) as floats (dps None) or mpf at dps digits."""
        if dps is None:
            return float(self.t0), [float(x) for x in self.q0], [float(x) for x in self.v0]
        with mpmath.workdps(dps):
            cv = lambda e: mpmath.mpf(str(sympy.N(e, dps + 10)))
            return cv(self.t0), [cv(x) for x in self.q0], [cv(x) for x in self.v0]

    def exact_solution(self, t, dps=None):
        """(q(t), v(t), psi(t)) of the closed-form solution, at float64 or dps digits."""
        if self.exact is None:
            raise InputError(f"scene {self.name} has no closed-form solution")
        mod = "mpmath" if dps is not None else "math"
        if mod not in self._exact_fns:
            ts = self.exact["t"]
            self._exact_fns[mod] = sympy.lambdify([ts], [self.exact["q"], self.exact["v"], self.exact["psi"]],
                                                  modules=mod)
        f = self._exact_fns[mod]
        if dps is None:
            q, v, p = f(float(t))
            return np.array(q, float), np.array(v, float), np.array(p, float)
        with mpmath.workdps(dps):
            q, v, p = f(mpmath.mpf(t) if not isinstance(t, str) else mpmath.mpf(t))
            return (np.array([mpmath.mpf(x) for x in q], dtype=object),
                    np.array([mpmath.mpf(x) for x in v], dtype=object),
                    np.array([mpmath.mpf(x) for x in p], dtype=object))


def _syms(n):
    return list(sympy.symbols(f"q1:{n + 1}")), list(sympy.symbols(f"v1:{n + 1}"))


def particle() -> Scene:
    """8.1 nonholonomic particle: L = |v|^2/2 - (q1^2 + q2^2), k = v3 - q2 v1."""
    q, v = _syms(3)
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - (q[0] ** 2 + q[1] ** 2)
    k = [v[2] - q[1] * v[0]]
    sysm = LagrangianSystem(L, k, q, v, name="particle")
    return Scene("particle", sysm, sympy.Integer(0), [1, 0, 0], [0, 1, 0],
                 "nonholonomic particle (8.1), E conserved")


def skate(m=1, I=1, g=1, beta=sympy.pi / 2) -> Scene:
    """8.2 skate on an inclined plane: T = m(v1^2+v2^2)/2 + I v3^2/2, U = m g q1 sin(beta),
    k = cos(q3) v2 - sin(q3) v1. Closed-form solution derived below (q3 = w t)."""
    m, I, g, beta = map(sympy.sympify, (m, I, g, beta))
    q, v = _syms(3)
    L = m * (v[0] ** 2 + v[1] ** 2) / 2 + I * v[2] ** 2 / 2 - m * g * q[0] * sympy.sin(beta)
    k = [sympy.cos(q[2]) * v[1] - sympy.sin(q[2]) * v[0]]
    sysm = LagrangianSystem(L, k, q, v, name="skate")
    q0, v0 = [0, 0, 0], [0, 0, 1]
    # Exact solution for q0 = 0, v0 = (0, 0, w): q3 = w t; the speed u along the blade obeys
    # u' = -g sin(beta) cos(w t), u(0) = 0; (v1, v2) = u (cos q3, sin q3);
    t = sympy.Symbol("t")
    w = sympy.Integer(v0[2])
    G = g * sympy.sin(beta)
    u = -G / w * sympy.sin(w * t)
    v1e, v2e = u * sympy.cos(w * t), u * sympy.sin(w * t)
    q1e = sympy.integrate(v1e, (t, 0, t))
    q2e = sympy.integrate(v2e, (t, 0, t))
    # psi from the normal component of (1b): m v1' = -m G + sin(q3) psi, m v2' = -cos(q3) psi
    psi = sympy.simplify(m * G * sympy.sin(w * t) + sympy.sin(w * t) * m * sympy.diff(v1e, t)
                         - sympy.cos(w * t) * m * sympy.diff(v2e, t))
    exact = {"t": t, "q": [sympy.simplify(q1e), sympy.simplify(q2e), w * t],
             "v": [sympy.simplify(v1e), sympy.simplify(v2e), w], "psi": [psi]}
    return Scene("skate", sysm, sympy.Integer(0), q0, v0, "skate on an inclined plane (8.2)",
                 exact=exact, params={"m": m, "I": I, "g": g, "beta": beta})


def robot(m=1, I=1, I_w=1, ell=1) -> Scene:
    """8.3 mobile robot with fixed orientation: T = m(v1^2+v2^2)/2 + I v3^2/2 + 3 I_w v4^2/2,
    U = 10 sin(q4), k = (v1 - l cos(q3) v4, v2 - l sin(q3) v4)."""
    m, I, I_w, ell = map(sympy.sympify, (m, I, I_w, ell))
    q, v = _syms(4)
    L = m * (v[0] ** 2 + v[1] ** 2) / 2 + I * v[2] ** 2 / 2 + R(3, 2) * I_w * v[3] ** 2 - 10 * sympy.sin(q[3])
    k = [v[0] - ell * sympy.cos(q[2]) * v[3], v[1] - ell * sympy.sin(q[2]) * v[3]]
    sysm = LagrangianSystem(L, k, q, v, name="robot")
    return Scene("robot", sysm, sympy.Integer(0), [0, 0, 0, 0], [1, 0, 0, 1],
                 "mobile robot with fixed orientation and a potential (8.3)",
                 params={"m": m, "I": I, "I_w": I_w, "ell": ell})


MP_CONSTRAINTS = ("printed", "nonholonomic")


def mp_particles(m: int = 3, J: int = 9, j: int = 0, constraint: str = "printed") -> Scene:
    """8.4 McLachlan-Perlmutter particles, n = 2m+1: T = |v|^2/2,
    U = (|q|^2 + q_{m+2}^2 q_{m+3}^2 + sum_i q_{1+i}^2 q_{m+1+i}^2)/2. Initial condition j of J+1.

    ``constraint="printed"``: k = v1 + sum_{i=m+2}^{n} q_i v_i as printed in section 8.4. This
    constraint is integrable, k = d/dt (q1 + sum_{i>=m+2} q_i^2 / 2): the scene is holonomic.
    ``constraint="nonholonomic"``: k = v1 + sum_{i=m+2}^{n} q_{i-m} v_i, a non-integrable
    constraint generalizing the nonholonomic particle of 8.1 (v3 - q2 v1 = 0), which is what a
    chaotic *nonholonomic* test problem needs; we take the printed q_i to be a typo for q_{i-m}
    and measure both (scene names ``mp-particles`` and ``mp-particles-nh``)."""
    if m < 2:
        raise InputError("mp-particles needs m >= 2")
    if constraint not in MP_CONSTRAINTS:
        raise InputError(f"constraint must be one of {MP_CONSTRAINTS}, got {constraint!r}")
    if not (0 <= j <= J):
        raise InputError(f"initial condition index j = {j} must be in 0..{J}")
    n = 2 * m + 1
    q, v = _syms(n)
    # paper indices are 1-based: q_i -> q[i-1]
    U = (sum(x ** 2 for x in q) + q[m + 1] ** 2 * q[m + 2] ** 2
         + sum(q[i] ** 2 * q[m + i] ** 2 for i in range(1, m + 1))) / 2
    L = sum(x ** 2 for x in v) / 2 - U
    shift = 0 if constraint == "printed" else m
    k = [v[0] + sum(q[i - 1 - shift] * v[i - 1] for i in range(m + 2, n + 1))]
    name = "mp-particles" if constraint == "printed" else "mp-particles-nh"
    sysm = LagrangianSystem(L, k, q, v, name=name, mechanical=None)
    sysm.mechanical = {"M": sympy.eye(n), "U": U,
                       "K": sympy.Matrix([k]).jacobian(v), "b": sympy.zeros(1, 1)}
    alpha = sympy.cos(j * sympy.pi / (2 * J))
    beta = sympy.sin(j * sympy.pi / (2 * J))
    if m == 3:
        q0 = [alpha, R(6, 10), R(4, 10), R(2, 10), 1, 1, 1]
    else:  # same pattern for other m: decreasing middle block, ones at the end
        q0 = [alpha] + [R(2 * (m - i), 10) for i in range(m)] + [1] * m
    v0 = [0, beta] + [0] * (n - 2)
    return Scene(name, sysm, sympy.Integer(0), q0, v0,
                 f"McLachlan-Perlmutter particles (8.4), m = {m}, {constraint} constraint, "
                 f"initial condition j = {j} of J+1 = {J + 1}",
                 params={"m": m, "J": J, "j": j, "constraint": constraint})


def pendulum() -> Scene:
    """Holonomic check (5.1): planar pendulum, g(q) = (q1^2 + q2^2 - 1)/2 written as the velocity
    constraint k = g_q v = q1 v1 + q2 v2; L = |v|^2/2 - q2."""
    q, v = _syms(2)
    L = (v[0] ** 2 + v[1] ** 2) / 2 - q[1]
    k = [q[0] * v[0] + q[1] * v[1]]
    sysm = LagrangianSystem(L, k, q, v, name="pendulum")
    return Scene("pendulum", sysm, sympy.Integer(0), [1, 0], [0, R(1, 2)],
                 "planar pendulum with holonomic constraint as velocity constraint (5.1)")


def rolling_disk() -> Scene:
    """Vertical rolling disk (unit mass and radius): q = (x, y, theta, phi),
    L = (x'^2 + y'^2)/2 + theta'^2/4 + phi'^2/8, k = (x' - cos(phi) theta', y' - sin(phi) theta')."""
    x, y, th, ph = sympy.symbols("x y theta phi")
    vx, vy, vth, vph = sympy.symbols("vx vy vtheta vphi")
    L = (vx ** 2 + vy ** 2) / 2 + vth ** 2 / 4 + vph ** 2 / 8
    k = [vx - sympy.cos(ph) * vth, vy - sympy.sin(ph) * vth]
    sysm = LagrangianSystem(L, k, [x, y, th, ph], [vx, vy, vth, vph], name="rolling-disk")
    return Scene("rolling-disk", sysm, sympy.Integer(0), [0, 0, 0, 0], [1, 0, 1, R(1, 2)],
                 "vertical rolling disk")


SCENES: dict[str, Callable[..., Scene]] = {
    "particle": particle,
    "skate": skate,
    "robot": robot,
    "mp-particles": mp_particles,
    "mp-particles-nh": lambda **kw: mp_particles(constraint="nonholonomic", **kw),
    "pendulum": pendulum,
    "rolling-disk": rolling_disk,
}

PAPER_SCENES = ("particle", "skate", "robot", "mp-particles")


def get_scene(name: str, ic: int | None = None) -> Scene:
    """Scene by name; ``ic`` selects the initial condition j of mp-particles."""
    if name not in SCENES:
        raise InputError(f"unknown scene {name!r}; choose from {', '.join(SCENES)}")
    if name in ("mp-particles", "mp-particles-nh"):
        return SCENES[name](j=ic or 0)
    if ic not in (None, 0):
        raise InputError(f"--ic applies only to mp-particles, not {name}")
    return SCENES[name]()
