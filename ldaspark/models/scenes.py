"""The paper's scenes (section 8) with its parameters and initial data, plus a holonomic
pendulum for section 5.1, a vertical rolling disk as a user-style example, and general scenes
(``GENERAL_SCENES``: rheonomic L and k, k nonlinear in v, b != 0, L not quadratic in v;
``NONIDEAL_SCENES``: a nonideal constraint of 3.3).

Each scene states only L and k (or M, U, K, b); the library derives the rest. Parameters and
initial data are exact sympy numbers so that the mpmath path carries full precision.
"""
from __future__ import annotations

import threading
from typing import Callable

import mpmath
import numpy as np
import sympy
from sympy import Rational as R

from ..core.errors import InputError
from ..core.system import LagrangianSystem
from .scene import Scene


def _number(x):
    """A scene parameter as a sympy number: text through the tableau entry parser ("1/2",
    "sqrt(2)"), never sympify of text (which evaluates it); a number must be finite and real."""
    from ..core.system import _finite_param
    return _finite_param(x, "of the scene")     # a finite real number, as the system's own parameters


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
    m, I, g, beta = map(_number, (m, I, g, beta))
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
    m, I, I_w, ell = map(_number, (m, I, I_w, ell))
    q, v = _syms(4)
    L = m * (v[0] ** 2 + v[1] ** 2) / 2 + I * v[2] ** 2 / 2 + R(3, 2) * I_w * v[3] ** 2 - 10 * sympy.sin(q[3])
    k = [v[0] - ell * sympy.cos(q[2]) * v[3], v[1] - ell * sympy.sin(q[2]) * v[3]]
    sysm = LagrangianSystem(L, k, q, v, name="robot")
    return Scene("robot", sysm, sympy.Integer(0), [0, 0, 0, 0], [1, 0, 0, 1],
                 "mobile robot with fixed orientation and a potential (8.3)",
                 params={"m": m, "I": I, "I_w": I_w, "ell": ell})


MP_CONSTRAINTS = ("printed", "nonholonomic")
#: the largest m of mp_particles: n = 2m + 1 = 1001, the largest model the compiled engine is measured on
MP_MAX_M = 500


def _is_int(x) -> bool:
    """An integer, not a bool (True is not 1)."""
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def mp_particles(m: int = 3, J: int = 9, j: int = 0, constraint: str = "printed") -> Scene:
    """8.4 McLachlan-Perlmutter particles, n = 2m+1: T = |v|^2/2,
    U = (|q|^2 + q_{m+2}^2 q_{m+3}^2 + sum_i q_{1+i}^2 q_{m+1+i}^2)/2. Initial condition j of J+1.

    ``constraint="printed"``: k = v1 + sum_{i=m+2}^{n} q_i v_i as printed in section 8.4. This
    constraint is integrable, k = d/dt (q1 + sum_{i>=m+2} q_i^2 / 2): the scene is holonomic.
    ``constraint="nonholonomic"``: k = v1 + sum_{i=m+2}^{n} q_{i-m} v_i, a non-integrable
    constraint generalizing the nonholonomic particle of 8.1 (v3 - q2 v1 = 0), which is what a
    chaotic *nonholonomic* test problem needs; we take the printed q_i to be a typo for q_{i-m}
    and measure both (scene names ``mp-particles`` and ``mp-particles-nh``)."""
    from ..core.validate import count
    # integers (no str, float or bool); m bounded: n = 2m + 1 symbols are built and derived
    # (m = 400 takes minutes, m = 10**9 exhausts the memory)
    m = count(m, "m of mp-particles (n = 2m + 1)", 2, MP_MAX_M)
    if constraint not in MP_CONSTRAINTS:
        raise InputError(f"constraint must be one of {MP_CONSTRAINTS}, got {constraint!r}")
    J = count(J, "J (the number of initial conditions less one)", 0, 10 ** 6)
    if not _is_int(j) or not (0 <= j <= J):
        raise InputError(f"initial condition index j = {str(j)[:40]} must be an integer in 0..{J}")
    j = int(j)
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


# --- general scenes: what the section 8 scenes do not exercise (t in L and k, k nonlinear in v,
# b != 0, L not quadratic in v, nonideal constraints of 3.3) ----------------------------------
def rheonomic_skate() -> Scene:
    """Skate (8.2) on a conveyor belt that moves along x with speed u(t) = (1 + sin t)/2, on a
    slope whose effective gravity g(t) = 1 + cos(t)/2 oscillates (a tilting table).

    The blade's velocity relative to the belt is along the blade: k = cos(q3) v2 - sin(q3)
    (v1 - u(t)), so k is rheonomic with affine part b(t, q) = sin(q3) u(t) != 0, and
    L = (v1^2 + v2^2 + v3^2)/2 - g(t) q1 depends on t (L_t != 0). Built from 8.2; no closed form."""
    q, v = _syms(3)
    t = sympy.Symbol("t")
    u = (1 + sympy.sin(t)) / 2
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - (1 + sympy.cos(t) / 2) * q[0]
    k = [sympy.cos(q[2]) * v[1] - sympy.sin(q[2]) * (v[0] - u)]
    sysm = LagrangianSystem(L, k, q, v, t=t, name="rheonomic-skate")
    q3 = R(1, 5)
    return Scene("rheonomic-skate", sysm, sympy.Integer(0), [0, 0, q3], [1, sympy.tan(q3) / 2, 1],
                 "skate on a moving belt and a tilting slope: rheonomic L and k, b(t, q) != 0")


def constant_speed() -> Scene:
    """Isokinetic particle (Gaussian thermostat of Evans and Hoover; a constraint nonlinear in v of
    the Appell-Hamel kind): L = |v|^2/2 - U(q), U = (q1^2 + 2 q2^2 + q3^2)/2 + q1 q3^2/2,
    k = (|v|^2 - 1)/2. By Chetaev's rule (9c) K = k_v = v^T, so (1b) reads
    v' = -grad U - psi v with psi = -v . grad U: the speed stays 1 and E (8) is not conserved."""
    q, v = _syms(3)
    U = (q[0] ** 2 + 2 * q[1] ** 2 + q[2] ** 2) / 2 + q[0] * q[2] ** 2 / 2
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - U
    k = [(v[0] ** 2 + v[1] ** 2 + v[2] ** 2 - 1) / 2]
    sysm = LagrangianSystem(L, k, q, v, name="constant-speed")
    return Scene("constant-speed", sysm, sympy.Integer(0), [1, 0, R(1, 2)], [0, R(3, 5), R(4, 5)],
                 "isokinetic particle: constraint |v| = 1, nonlinear in v")


def relativistic(B=R(1, 2)) -> Scene:
    """Relativistic charged particle (c = m = 1) with the constraint of 8.1, in the potential of
    8.1 and a constant magnetic field B along q3: L = -sqrt(1 - |v|^2) + B (q1 v2 - q2 v1)/2
    - (q1^2 + q2^2), k = v3 - q2 v1. L is not quadratic in v (L_vv depends on v) and has a
    gyroscopic q-v coupling; L and k are autonomous and k is linear in v, so E (8) =
    1/sqrt(1 - |v|^2) + q1^2 + q2^2 is conserved (2.2)."""
    q, v = _syms(3)
    B = _number(B)
    L = (-sympy.sqrt(1 - v[0] ** 2 - v[1] ** 2 - v[2] ** 2) + B * (q[0] * v[1] - q[1] * v[0]) / 2
         - (q[0] ** 2 + q[1] ** 2))
    k = [v[2] - q[1] * v[0]]
    sysm = LagrangianSystem(L, k, q, v, name="relativistic")
    return Scene("relativistic", sysm, sympy.Integer(0), [R(1, 2), 0, 0], [0, R(1, 2), 0],
                 "relativistic particle in a potential and a magnetic field, constraint of 8.1",
                 params={"B": B})


def turntable(Omega=R(1, 2)) -> Scene:
    """Vertical rolling disk (the ``rolling-disk`` scene) on a turntable rotating with angular
    speed Omega about the origin: the contact point moves with the table, velocity
    Omega (-y, x), so k = (vx - cos(phi) vtheta + Omega y, vy - sin(phi) vtheta - Omega x): affine
    in v with b(q) = Omega (y, -x) != 0 (autonomous; energy is not conserved, 2.2)."""
    x, y, th, ph = sympy.symbols("x y theta phi")
    vx, vy, vth, vph = sympy.symbols("vx vy vtheta vphi")
    Om = _number(Omega)
    L = (vx ** 2 + vy ** 2) / 2 + vth ** 2 / 4 + vph ** 2 / 8
    k = [vx - sympy.cos(ph) * vth + Om * y, vy - sympy.sin(ph) * vth - Om * x]
    sysm = LagrangianSystem(L, k, [x, y, th, ph], [vx, vy, vth, vph], name="turntable")
    return Scene("turntable", sysm, sympy.Integer(0), [1, 0, 0, 0], [1, Om, 1, R(1, 2)],
                 "rolling disk on a turntable: affine constraint, b(q) != 0", params={"Omega": Om})


def friction_skate(mu=R(1, 2), eps=R(1, 10)) -> Scene:
    """Skate (8.2) with sliding friction along the blade proportional to the normal reaction
    |psi| (nonideal constraint, 3.3; dry friction as in [3, Example 3.2.6]):
    N = -mu |psi|_eps sgn_eps(u) e, e = (cos q3, sin q3, 0) the blade, u = e . v the sliding speed.
    Coulomb's |psi| and sgn(u) are not differentiable, and SPARK order claims need smooth data:
    we smooth both, |psi|_eps = sqrt(psi^2 + eps^2), sgn_eps(u) = u / sqrt(u^2 + eps^2).
    N_psi != 0 and K N_psi = 0 (friction acts along the blade), so (4) with K^T - N_psi holds."""
    q, v = _syms(3)
    mu, eps = _number(mu), _number(eps)
    psi = sympy.Symbol("psi1")
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - q[0]
    k = [sympy.cos(q[2]) * v[1] - sympy.sin(q[2]) * v[0]]
    u = sympy.cos(q[2]) * v[0] + sympy.sin(q[2]) * v[1]
    f = -mu * sympy.sqrt(psi ** 2 + eps ** 2) * u / sympy.sqrt(u ** 2 + eps ** 2)
    N = [f * sympy.cos(q[2]), f * sympy.sin(q[2]), 0]
    sysm = LagrangianSystem(L, k, q, v, name="friction-skate", nonideal=N, psi=[psi])
    return Scene("friction-skate", sysm, sympy.Integer(0), [0, 0, 0], [0, 0, 1],
                 "skate with smoothed sliding friction mu |psi| along the blade (nonideal, 3.3)",
                 params={"mu": mu, "eps": eps})


SCENES: dict[str, Callable[..., Scene]] = {
    "particle": particle,
    "skate": skate,
    "robot": robot,
    "mp-particles": mp_particles,
    "mp-particles-nh": lambda **kw: mp_particles(constraint="nonholonomic", **kw),
    "pendulum": pendulum,
    "rolling-disk": rolling_disk,
    "rheonomic-skate": rheonomic_skate,
    "constant-speed": constant_speed,
    "relativistic": relativistic,
    "turntable": turntable,
    "friction-skate": friction_skate,
    "bicycle": lambda **kw: __import__("ldaspark.models.bicycle", fromlist=["bicycle"]).bicycle(**kw),
}

# classic nonholonomic systems, built in ldaspark.models.systems_classic (imported at
# first build: it subclasses Scene from this module)
def _classic(builder, **fixed):
    def build(**kw):
        from . import systems_classic
        return getattr(systems_classic, builder)(**{**fixed, **kw})
    build.__doc__ = f"ldaspark.models.systems_classic.{builder}"
    return build


SCENES.update({
    "chaplygin-sleigh": _classic("chaplygin_sleigh"),
    "tilted-disk": _classic("tilted_disk"),
    "chaplygin-sphere": _classic("chaplygin_sphere"),
    "suslov": _classic("suslov"),
    "contact-oscillator": _classic("contact_oscillator"),
    "ball-turntable": _classic("ball_turntable"),
    "ball-turntable-rheonomic": _classic("ball_turntable", eps=R(1, 2)),
})

PAPER_SCENES = ("particle", "skate", "robot", "mp-particles")
# ideal general scenes (Theorem 1 applies) and the nonideal one (3.3)
GENERAL_SCENES = ("rheonomic-skate", "constant-speed", "relativistic", "turntable")
NONIDEAL_SCENES = ("friction-skate",)


_BUILT: dict = {}
_BUILT_LOCK = threading.Lock()


def get_scene(name: str, ic: int | None = None) -> Scene:
    """A scene of section 8 (or a general or classic scene) by name.

    Built once per process and shared: building a scene derives its closed-form solution and
    system with sympy, and a shared scene also shares its system's compiled functions. Scenes
    and systems are not modified after construction.

    Parameters
    ----------
    name : str
        One of ``ldaspark.models.scenes.SCENES`` (``particle``, ``skate``, ``robot``,
        ``mp-particles``, ``mp-particles-nh``, ``pendulum``, ``rolling-disk``, the general and
        classic scenes, ``bicycle``).
    ic : int, optional
        The initial condition j of ``mp-particles`` / ``mp-particles-nh`` (default 0).

    Returns
    -------
    Scene
        ``system`` (a `LagrangianSystem`), initial data ``t0, q0, v0`` and, where known, the
        exact solution.

    Raises
    ------
    InputError
        For an unknown name, or ``ic`` on a scene that has one initial condition.

    Examples
    --------
    >>> import ldaspark
    >>> sc = ldaspark.get_scene("skate")
    >>> sc.name, len(sc.q0), len(sc.system.k)
    ('skate', 3, 1)
    """
    from ..core.validate import _describe, count
    if not isinstance(name, str):
        raise InputError(f"scene must be a scene name (a string), got {_describe(name)}")
    if name not in SCENES:
        raise InputError(f"unknown scene {name[:60]!r}; choose from {', '.join(SCENES)}")
    if ic is not None:
        ic = count(ic, "ic (the initial condition index)", 0, 10 ** 6)    # no bool, float or text
    mp = name in ("mp-particles", "mp-particles-nh")
    if not mp and ic not in (None, 0):
        raise InputError(f"--ic applies only to mp-particles and mp-particles-nh, not {name}")
    build = (lambda: SCENES[name](j=ic or 0)) if mp else SCENES[name]
    key = (name, ic or 0, SCENES[name])      # a replaced builder (SCENES is public) builds anew
    with _BUILT_LOCK:
        sc = _BUILT.get(key)
        if sc is None:
            sc = _BUILT[key] = build()
    return sc
