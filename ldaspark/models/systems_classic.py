"""Classic nonholonomic systems as named scenes: a benchmark set with closed forms and
first integrals, each with its source.

* ``chaplygin-sleigh``: the Chaplygin sleigh (Bloch, *Nonholonomic Mechanics and Control*, 1.7),
  closed form (speed ~ tanh, angular velocity ~ sech, the path in elementary functions);
* ``tilted-disk``: the rolling disk in Euler angles (Bloch 2003, chapter 1; O'Reilly 1996), energy, and the
  steady circular motions with their existence condition in closed form;
* ``chaplygin-sphere``: Chaplygin's ball (centre of mass at the geometric centre, unequal
  moments), first integrals energy, |M|^2 and (M, gamma) (Chaplygin 1903; Borisov-Mamaev 2002);
* ``suslov``: the Suslov problem (rigid body with omega_3 = 0 in the body frame; Suslov 1946,
  Fedorov-Jovanovic 2004), closed form of the body angular velocity;
* ``contact-oscillator``: x' + y z' = 0, harmonic potentials and epsilon x^2 z^2 / 2
  (McLachlan-Perlmutter 2006, 5.2; Modin-Verdier 2013), the y-energy (y^2 + y'^2)/2 an exact
  first integral;
* ``ball-turntable``, ``ball-turntable-rheonomic``: a homogeneous ball rolling on a turntable
  rotating with Omega (constant) or Omega(t) (rheonomic); the centre moves on a circle with
  angular velocity 2 Omega(t)/7 (Routh, Advanced Rigid Dynamics (1905) 243), and the full
  closed form below.

The rigid bodies are written with ``sympy.physics.mechanics`` (frames, points, ``RigidBody``,
``Lagrangian``) and turned into (1) by ``LagrangianSystem.from_mechanics``, as a user would; the
contact oscillator is written directly from L and k. Parameters are exact sympy numbers
(substituted, so that ``engine="auto"`` compiles every scene).

Each scene (a ``ClassicScene``) carries ``invariants`` (name -> sympy expression in t, q, v;
``invariant_values`` evaluates them along a trajectory), ``closed_forms`` (name -> (expression in
t, q, v, closed-form expression in t), e.g. the sleigh's speed) and ``source`` (the reference).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import sympy
from sympy import Rational as R

from ..core.errors import InputError
from .scene import Scene
from ..core.system import LagrangianSystem


@dataclass
class ClassicScene(Scene):
    """A ``Scene`` with first integrals, closed forms of derived quantities and its source."""

    invariants: dict = field(default_factory=dict)
    closed_forms: dict = field(default_factory=dict)
    source: str = ""
    _inv_fns: dict = field(default_factory=dict, repr=False)

    def _fn(self, key, exprs, mod):
        ck = (key, mod)
        if ck not in self._inv_fns:
            S = self.system
            self._inv_fns[ck] = sympy.lambdify([S.t] + S.q + S.v, exprs, modules=mod)
        return self._inv_fns[ck]

    def invariant_values(self, t, q, v) -> dict:
        """{name: array over the trajectory} of the first integrals at float64 (t (S,), q, v (S, n))."""
        names = list(self.invariants)
        f = self._fn("inv", [self.invariants[k] for k in names], "numpy")
        t = np.asarray(t, float)
        q, v = np.asarray(q, float), np.asarray(v, float)
        out = f(t, *q.T, *v.T)
        return {k: np.broadcast_to(np.asarray(x, float), t.shape).copy() for k, x in zip(names, out)}

    def closed_form_errors(self, t, q, v) -> dict:
        """{name: max |observed - closed form|} over the trajectory for each closed form."""
        names = list(self.closed_forms)
        obs = self._fn("cf_obs", [self.closed_forms[k][0] for k in names], "numpy")
        ts = sympy.Symbol("t_cf")
        S = self.system
        ex = [self.closed_forms[k][1].subs(S.t, ts) for k in names]
        key = ("cf_exact", "numpy")
        if key not in self._inv_fns:
            self._inv_fns[key] = sympy.lambdify([ts], ex, modules="numpy")
        t = np.asarray(t, float)
        q, v = np.asarray(q, float), np.asarray(v, float)
        o = obs(t, *q.T, *v.T)
        e = self._inv_fns[key](t)
        return {k: float(np.max(np.abs(np.broadcast_to(np.asarray(a, float), t.shape)
                                       - np.broadcast_to(np.asarray(b, float), t.shape))))
                for k, a, b in zip(names, o, e)}


def _num(x):
    """A scene parameter as a sympy number: text through the tableau entry parser ("1/2",
    "sqrt(2)"; ``system._param_value``), never sympify of text, which evaluates it as Python."""
    from ..core.system import _finite_param
    return _finite_param(x, "of the scene")     # a finite real number, as the system's own parameters


def _psi_along(system, ts, qe):
    """psi(t) of (1b) along a closed-form q(t) (sympy): d/dt grad_v L - grad_q L = -K^T psi,
    psi = -(K K^T)^-1 K r with r the left-hand side (K of full rank m, (4))."""
    S = system
    ve = [sympy.diff(x, ts) for x in qe]
    sub = dict(zip(S.q, qe)) | dict(zip(S.v, ve)) | {S.t: ts}
    Lv = S.L_v.subs(sub)
    r = Lv.diff(ts) - S.L_q.subs(sub)
    K = S.k_v.subs(sub)
    G = K * K.T
    # adjugate / determinant without simplification (inv() simplifies pivots: minutes for the ball)
    psi = -(G.adjugate(method="berkowitz") * (K * r)) / G.det(method="berkowitz")
    return ve, list(psi)


def _mech():
    from sympy.physics import mechanics as me
    return me


# --- Chaplygin sleigh ---------------------------------------------------------------------------
def chaplygin_sleigh(m=1, a=1, omega0=1) -> ClassicScene:
    """Chaplygin sleigh (Bloch, *Nonholonomic Mechanics and Control*, 2003, section 1.7): a rigid
    body in the plane on a knife edge at the contact point P = (x, y), its centre of mass at
    distance a ahead of P along the blade, heading theta; mass m, moment of inertia I about the
    centre of mass, here I = 3 m a^2, so that J = I + m a^2 = 4 m a^2. The knife edge allows no
    velocity of P across the blade: k = -sin(theta) x' + cos(theta) y' = 0.

    With the forward speed u = cos(theta) x' + sin(theta) y' and omega = theta', Bloch's reduced
    equations are u' = a omega^2, omega' = -(m a / J) u omega; energy E = (m u^2 + J omega^2)/2.
    From u(0) = 0, omega(0) = omega0 > 0: u = V tanh(kappa t), omega = omega0 sech(kappa t) with
    V = 2 a omega0, kappa = omega0 / 2; theta = 2 gd(kappa t) (gd(s) = atan(sinh s)), and the
    path x = 4 a (tanh^2(kappa t) - log cosh(kappa t)), y = 4 a (gd(kappa t) - sech tanh(kappa t))
    (integrating u (cos theta, sin theta) with cos(2 gd) = 1 - 2 tanh^2, sin(2 gd) = 2 tanh sech).
    Written with sympy.physics.mechanics."""
    me = _mech()
    m, a, omega0 = map(_num, (m, a, omega0))
    if not (m > 0 and a > 0 and omega0 > 0):
        raise InputError("chaplygin-sleigh needs m, a, omega0 > 0")
    I = 3 * m * a ** 2
    x, y, th = me.dynamicsymbols("x y theta")
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Axis", [th, N.z])
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)
    P.set_vel(N, x.diff(me.dynamicsymbols._t) * N.x + y.diff(me.dynamicsymbols._t) * N.y)
    G = P.locatenew("G", a * B.x)
    G.v2pt_theory(P, N, B)
    body = me.RigidBody("sleigh", G, B, m, (me.inertia(B, 0, 0, I), G))
    L = me.Lagrangian(N, body)
    k = P.vel(N).dot(B.y)
    S = LagrangianSystem.from_mechanics(L, q=[x, y, th], constraints=[k], name="chaplygin-sleigh")
    t = sympy.Symbol("t")
    kap = omega0 / 2
    V = 2 * a * omega0
    s = kap * t
    gd = sympy.atan(sympy.sinh(s))
    qe = [4 * a * (sympy.tanh(s) ** 2 - sympy.log(sympy.cosh(s))),
          4 * a * (gd - sympy.tanh(s) / sympy.cosh(s)), 2 * gd]
    ve, psi = _psi_along(S, t, qe)
    exact = {"t": t, "q": qe, "v": ve, "psi": psi}
    X, Y, TH = S.q
    VX, VY, VTH = S.v
    u = sympy.cos(TH) * VX + sympy.sin(TH) * VY
    J = I + m * a ** 2
    inv = {"energy": S.energy_expr}
    cf = {"u (speed ~ tanh)": (u, V * sympy.tanh(s)), "omega (~ sech)": (VTH, omega0 / sympy.cosh(s)),
          "theta = 2 gd": (TH, 2 * gd)}
    return ClassicScene("chaplygin-sleigh", S, sympy.Integer(0), [0, 0, 0], [0, 0, omega0],
                        "Chaplygin sleigh: closed form u ~ tanh, omega ~ sech (Bloch 1.7)", exact=exact,
                        params={"m": m, "a": a, "I": I, "J": J, "omega0": omega0}, invariants=inv,
                        closed_forms=cf, source="A. M. Bloch, Nonholonomic Mechanics and Control (2003), 1.7")


# --- tilted rolling disk -----------------------------------------------------------------------
def disk_steady_spin(theta0, Omega, r=1, g=1):
    """Spin rate phi' of the steady circular motion of the rolling disk (theta = theta0,
    psi' = Omega, phi' constant): the theta equation of motion at constant theta, psi', phi' reads
    5 r Omega^2 sin(theta0) cos(theta0) + 6 r Omega phi' cos(theta0) + 4 g sin(theta0) = 0, so
    phi' = -(4 g + 5 r Omega^2 cos(theta0)) sin(theta0) / (6 r Omega cos(theta0)) for Omega != 0,
    cos(theta0) != 0. Conversely, for given theta0 and spin phi', a steady yaw rate Omega exists iff
    (36 phi'^2 r^2 cos^2 - 80 g r sin^2 cos) >= 0, i.e. phi'^2 >= 20 g sin^2(theta0) / (9 r cos(theta0))
    for 0 < cos(theta0) (``disk_steady_exists``)."""
    theta0, Omega, r, g = map(_num, (theta0, Omega, r, g))
    return -(4 * g + 5 * r * Omega ** 2 * sympy.cos(theta0)) * sympy.sin(theta0) / (6 * r * Omega * sympy.cos(theta0))


def disk_steady_exists(theta0, spin, r=1, g=1) -> bool:
    """Existence condition of a steady circular motion with tilt theta0 (0 < cos theta0) and spin
    phi' = ``spin``: the discriminant of the quadratic in Omega is >= 0 (``disk_steady_spin``)."""
    theta0, spin, r, g = (float(_num(x)) for x in (theta0, spin, r, g))
    c, s = np.cos(theta0), np.sin(theta0)
    return bool(36 * spin ** 2 * r ** 2 * c ** 2 - 80 * g * r * s ** 2 * c >= 0)


def tilted_disk(m=1, r=1, g=1, theta0=sympy.pi / 6, Omega=1) -> ClassicScene:
    """Rolling disk in Euler angles (Bloch 2003, chapter 1; O'Reilly, Nonlinear Dynamics 10 (1996)
    287-305): uniform disk of mass m and radius r (moments m r^2/4 about a diameter, m r^2/2 about
    its axis) rolling without slipping on the horizontal plane under gravity g. q = (x, y, psi,
    theta, phi): the contact point, heading (yaw), tilt from the vertical and spin; the frames
    A = yaw psi about N.z, B = tilt theta about A.x, C = spin phi about B.y (the disk's axis), centre
    D = P + r B.z. Rolling: the material contact point of C has zero velocity, k = (x' - r cos(psi)
    phi', y' - r sin(psi) phi') (its vertical component vanishes identically). L = T - m g r
    cos(theta); the energy (8) is conserved.

    Initial data: the steady circular motion with tilt theta0 and yaw rate Omega (closed form:
    theta = theta0, psi = Omega t, phi = phi'_s t with phi'_s = ``disk_steady_spin``, and the contact
    point on the circle of radius r phi'_s / Omega). Written with sympy.physics.mechanics."""
    me = _mech()
    m, r, g, theta0, Omega = map(_num, (m, r, g, theta0, Omega))
    x, y, psi, th, ph = me.dynamicsymbols("x y psi theta phi")
    tt = me.dynamicsymbols._t
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [psi, N.z])
    B = A.orientnew("B", "Axis", [th, A.x])
    C = B.orientnew("C", "Axis", [ph, B.y])
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)
    P.set_vel(N, x.diff(tt) * N.x + y.diff(tt) * N.y)
    D = P.locatenew("D", r * B.z)
    D.v2pt_theory(P, N, B)
    disk = me.RigidBody("disk", D, C, m, (me.inertia(B, m * r ** 2 / 4, m * r ** 2 / 2, m * r ** 2 / 4), D))
    disk.potential_energy = m * g * r * sympy.cos(th)
    L = me.Lagrangian(N, disk)
    vc = D.vel(N) + C.ang_vel_in(N).cross(-r * B.z)
    cons = [sympy.simplify(vc.dot(N.x)), sympy.simplify(vc.dot(N.y))]
    S = LagrangianSystem.from_mechanics(L, q=[x, y, psi, th, ph], constraints=cons, name="tilted-disk")
    w = disk_steady_spin(theta0, Omega, r, g)
    t = sympy.Symbol("t")
    Rad = r * w / Omega
    qe = [Rad * sympy.sin(Omega * t), Rad * (1 - sympy.cos(Omega * t)), Omega * t, theta0, w * t]
    ve, psi_e = _psi_along(S, t, qe)
    exact = {"t": t, "q": qe, "v": ve, "psi": psi_e}
    TH = S.q[3]
    return ClassicScene("tilted-disk", S, sympy.Integer(0), [0, 0, 0, theta0, 0], [r * w, 0, Omega, 0, w],
                        "tilted rolling disk in Euler angles: steady circular motion (closed form), energy",
                        exact=exact, params={"m": m, "r": r, "g": g, "theta0": theta0, "Omega": Omega,
                                             "spin": w},
                        invariants={"energy": S.energy_expr}, closed_forms={"theta = theta0": (TH, theta0 + 0 * t)},
                        source="A. M. Bloch, Nonholonomic Mechanics and Control (2003), chapter 1; "
                               "O. M. O'Reilly, Nonlinear Dynamics 10 (1996) 287-305")


# --- rigid bodies in ZXZ Euler angles ------------------------------------------------------------
def _body_zxz(me, N, psi, th, ph):
    return N.orientnew("B", "Body", [psi, th, ph], "ZXZ")


def _ball_on_plane(me, m, r, inertia):
    """A ball of mass m and radius r with central principal moments ``inertia`` = (I1, I2, I3)
    on the horizontal plane, as Chaplygin's ball and the ball on a turntable share it: q = (x, y,
    psi, theta, phi), the centre G = (x, y, r) (height r: v_G = (x', y', 0)) and the ZXZ Euler
    angles of the body frame B in the space frame N; L = m |v_G|^2 / 2 + omega^T I omega / 2 (no
    potential). Returns (q, N, B, L, omega, v_contact) with v_contact = v_G + omega x (-r N.z), the
    velocity of the ball's material point at the contact (rolling on a fixed plane: its N.x and N.y
    components are k; on a moving plane, minus the plane's velocity there)."""
    x, y, psi, th, ph = me.dynamicsymbols("x y psi theta phi")
    tt = me.dynamicsymbols._t
    N = me.ReferenceFrame("N")
    B = _body_zxz(me, N, psi, th, ph)
    O = me.Point("O")
    O.set_vel(N, 0)
    G = O.locatenew("G", x * N.x + y * N.y + r * N.z)
    G.set_vel(N, x.diff(tt) * N.x + y.diff(tt) * N.y)
    ball = me.RigidBody("ball", G, B, m, (me.inertia(B, *inertia), G))
    L = me.Lagrangian(N, ball)
    w = B.ang_vel_in(N)
    return (x, y, psi, th, ph), N, B, L, w, G.vel(N) + w.cross(-r * N.z)


def chaplygin_sphere(m=1, r=1, I1=1, I2=R(3, 2), I3=2) -> ClassicScene:
    """Chaplygin's ball (S. A. Chaplygin, "On a ball's rolling on a horizontal plane", Mat.
    Sbornik 24 (1903); Borisov-Mamaev, Regul. Chaotic Dyn. 7 (2002) 177-200): a ball of radius r
    and mass m, centre of mass at its geometric centre, unequal principal moments I1, I2, I3,
    rolling without slipping on the plane. q = (x, y, psi, theta, phi): the centre and the ZXZ
    Euler angles of the body frame B. Rolling: v_centre = omega x (r N.z), i.e.
    k = (x' - r omega_y, y' + r omega_x) with omega in the space frame. L = m |v|^2 / 2 +
    omega^T I omega / 2 (no potential: the centre stays at height r).

    First integrals: the energy; the angular momentum about the contact point
    M = I omega + m r^2 (omega - (omega . gamma) gamma) (gamma the vertical in the body frame) is
    constant in space (the contact force passes through the contact point), so |M|^2 and
    (M, gamma) are invariants. Written with sympy.physics.mechanics."""
    me = _mech()
    m, r, I1, I2, I3 = map(_num, (m, r, I1, I2, I3))
    (x, y, psi, th, ph), N, B, L, w, vc = _ball_on_plane(me, m, r, (I1, I2, I3))
    cons = [vc.dot(N.x), vc.dot(N.y)]
    S = LagrangianSystem.from_mechanics(L, q=[x, y, psi, th, ph], constraints=cons, name="chaplygin-sphere")
    wb = [w.dot(B.x), w.dot(B.y), w.dot(B.z)]
    gam = [N.z.dot(B.x), N.z.dot(B.y), N.z.dot(B.z)]
    wg = sum(a * b for a, b in zip(wb, gam))
    Ms = [Ii * wi + m * r ** 2 * (wi - wg * gi) for Ii, wi, gi in zip((I1, I2, I3), wb, gam)]
    Mg = sum(a * b for a, b in zip(Ms, gam))
    M2 = sum(a ** 2 for a in Ms)
    sub = _symbol_map(S, [x, y, psi, th, ph])
    inv = {"energy": S.energy_expr, "|M|^2": _to_sym(M2, sub), "(M, gamma)": _to_sym(Mg, sub)}
    q0 = [0, 0, 0, 1, 0]
    v0 = _consistent_v(S, q0, [R(1, 2), R(-3, 10), 1])
    return ClassicScene("chaplygin-sphere", S, sympy.Integer(0), q0, v0,
                        "Chaplygin sphere (rolling ball, unequal moments): energy, |M|^2, (M, gamma)",
                        params={"m": m, "r": r, "I": (I1, I2, I3)}, invariants=inv,
                        source="S. A. Chaplygin, Mat. Sbornik 24 (1903); A. V. Borisov, I. S. Mamaev, "
                               "Regul. Chaotic Dyn. 7 (2002) 177-200")


def suslov(I1=2, I2=1, I3=3, I13=1, omega1_0=1) -> ClassicScene:
    """The Suslov problem (G. K. Suslov, Theoretical Mechanics (1946); Fedorov,
    Jovanovic, J. Nonlinear Sci. 14 (2004) 341-381): a rigid body about a fixed point, no
    potential, with the body-frame angular velocity component omega_3 = 0 (a nonholonomic
    constraint of the body: in ZXZ Euler angles k = psi' cos(theta) + phi'). Inertia in the
    body frame [[I1, 0, I13], [0, I2, 0], [I13, 0, I3]].

    The Euler-Poincare-Suslov equations M' = M x omega + lambda e3, M = I omega, with omega_3 = 0
    read I1 omega_1' = -I13 omega_1 omega_2, I2 omega_2' = I13 omega_1^2; with the energy
    E = (I1 omega_1^2 + I2 omega_2^2) / 2 and omega(0) = (w1, 0, 0):
    omega_2 = W tanh(kappa t), omega_1 = w1 sech(kappa t), W = w1 sqrt(I1 / I2), kappa = I13 W / I1
    (the body tends to a rotation about its second axis). Written with sympy.physics.mechanics."""
    me = _mech()
    I1, I2, I3, I13, w1 = map(_num, (I1, I2, I3, I13, omega1_0))
    psi, th, ph = me.dynamicsymbols("psi theta phi")
    N = me.ReferenceFrame("N")
    B = _body_zxz(me, N, psi, th, ph)
    O = me.Point("O")
    O.set_vel(N, 0)
    body = me.RigidBody("body", O, B, 1, (me.inertia(B, I1, I2, I3, 0, 0, I13), O))
    L = me.Lagrangian(N, body)
    w = B.ang_vel_in(N)
    k = w.dot(B.z)
    S = LagrangianSystem.from_mechanics(L, q=[psi, th, ph], constraints=[k], name="suslov")
    sub = _symbol_map(S, [psi, th, ph])
    wb = [_to_sym(w.dot(B.x), sub), _to_sym(w.dot(B.y), sub)]
    t = sympy.Symbol("t")
    W = w1 * sympy.sqrt(I1 / I2)
    kap = I13 * W / I1
    q0 = [0, 1, 0]
    # omega_1 = psi' sin(theta) sin(phi) + theta' cos(phi) = theta' at psi = phi = 0; omega_2 = psi' sin(theta) cos(phi)
    v0 = [0, w1, 0]
    cf = {"omega_1 (~ sech)": (wb[0], w1 / sympy.cosh(kap * t)), "omega_2 (~ tanh)": (wb[1], W * sympy.tanh(kap * t))}
    return ClassicScene("suslov", S, sympy.Integer(0), q0, v0,
                        "Suslov problem (omega_3 = 0): closed form omega_1 ~ sech, omega_2 ~ tanh; energy",
                        params={"I": [[I1, 0, I13], [0, I2, 0], [I13, 0, I3]], "omega1_0": w1},
                        invariants={"energy": S.energy_expr}, closed_forms=cf,
                        source="G. K. Suslov (1946); Y. N. Fedorov, B. Jovanovic, J. Nonlinear Sci. 14 (2004) 341-381")


# --- contact oscillator ---------------------------------------------------------------------------
def contact_oscillator(epsilon=R(3, 10), z0=R(1, 2)) -> ClassicScene:
    """Contact oscillator (McLachlan-Perlmutter, J. Nonlinear Sci. 16 (2006) 283-328, example 5.2;
    Modin-Verdier, arXiv:1212.6618): harmonic oscillators x, y, z coupled by the constraint
    x' + y z' = 0 (the gear ratio between x and z set by y) and, for epsilon != 0, by the
    nonlinear potential term epsilon x^2 z^2 / 2: L = |v|^2/2 - (x^2 + y^2 + z^2 + epsilon x^2 z^2)/2,
    k = x' + y z' (the energy and codistribution of odelab's ``ContactOscillator``, whose tests
    take epsilon = 0.3). Since k_v = (1, 0, y) has no y-component and the potential separates in
    y, the y-equation is y'' = -y: the y-energy (y^2 + y'^2)/2 is an exact first integral,
    besides the energy (8). Initial data as odelab's ``initial_cos``: H0 = 3/2, H_y = 1/2, z' = 0,
    q0 = (sqrt((2 H0 - z0^2 - 1) / (1 + epsilon z0^2)), 1, z0), v0 = 0."""
    epsilon, z0 = _num(epsilon), _num(z0)
    q = list(sympy.symbols("x y z"))
    v = list(sympy.symbols("vx vy vz"))
    x, y, z = q
    L = sum(a ** 2 for a in v) / 2 - (x ** 2 + y ** 2 + z ** 2 + epsilon * x ** 2 * z ** 2) / 2
    k = [v[0] + q[1] * v[2]]
    S = LagrangianSystem(L, k, q, v, name="contact-oscillator")
    inv = {"energy": S.energy_expr, "y-energy": (q[1] ** 2 + v[1] ** 2) / 2}
    H0 = R(3, 2)
    x0 = sympy.sqrt((2 * H0 - z0 ** 2 - 1) / (1 + epsilon * z0 ** 2))
    return ClassicScene("contact-oscillator", S, sympy.Integer(0), [x0, 1, z0], [0, 0, 0],
                        "contact oscillator x' + y z' = 0 (McLachlan-Perlmutter 5.2): energy and the exact"
                        " y-energy (y^2 + y'^2)/2", params={"epsilon": epsilon, "z0": z0},
                        invariants=inv, source="R. McLachlan, M. Perlmutter, J. Nonlinear Sci. 16 (2006) 283-328, "
                                                "5.2; K. Modin, O. Verdier, arXiv:1212.6618")


# --- ball on a turntable ---------------------------------------------------------------------------
def ball_turntable(Omega=1, eps=0, rho=1, r=1, m=1) -> ClassicScene:
    """Homogeneous ball (mass m, radius r, moment I = 2 m r^2 / 5) rolling without slipping on a
    turntable that rotates about the vertical through the origin with angular velocity
    Omega(t) = Omega (1 + eps sin t) (eps = 0: the classic problem, Routh, Advanced Rigid Dynamics
    (1905) 243). q = (x, y, psi, theta, phi): the centre and the
    ZXZ Euler angles. The material contact point moves with the table:
    v_centre + omega x (-r N.z) = Omega(t) N.z x (x, y, 0), i.e.
    k = (x' - r omega_y + Omega(t) y, y' + r omega_x - Omega(t) x): affine, b != 0, and for
    eps != 0 rheonomic (k_t != 0).

    Closed form: Newton-Euler give a_c = kappa d/dt (Omega(t) N.z x x_c) with kappa = I / (I + m r^2)
    = 2/7, so from v_c(0) = kappa Omega(0) N.z x x_c(0) the centre moves on the circle of radius rho
    with angle beta = (2/7) Theta(t), Theta = integral of Omega (angular velocity 2 Omega(t)/7).
    The angular velocity is then omega = (5/7) (Omega(t) rho / r) e_rho; with the body's 3-axis
    at the fixed tilt theta0, cot(theta0) = -2 r / (5 rho) (so that omega_z = 0), the Euler
    angles are psi = beta + pi/2, theta = theta0, phi = (5 rho / (7 r sin theta0)) Theta(t)."""
    me = _mech()
    Omega, eps, rho, r, m = map(_num, (Omega, eps, rho, r, m))
    tt = me.dynamicsymbols._t
    Om_t = Omega * (1 + eps * sympy.sin(tt))
    Ib = 2 * m * r ** 2 / 5
    (x, y, psi, th, ph), N, B, L, w, vc_plane = _ball_on_plane(me, m, r, (Ib, Ib, Ib))
    table = Om_t * N.z.cross(x * N.x + y * N.y)
    vc = vc_plane - table
    cons = [vc.dot(N.x), vc.dot(N.y)]
    name = "ball-turntable" if eps == 0 else "ball-turntable-rheonomic"
    S = LagrangianSystem.from_mechanics(L, q=[x, y, psi, th, ph], constraints=cons, name=name)
    t = sympy.Symbol("t")
    Theta = Omega * (t + eps * (1 - sympy.cos(t)))
    theta0 = sympy.pi / 2 + sympy.atan(2 * r / (5 * rho))          # cot(theta0) = -2 r / (5 rho)
    beta = R(2, 7) * Theta
    phidot_coef = 5 * rho / (7 * r * sympy.sin(theta0))
    qe = [rho * sympy.cos(beta), rho * sympy.sin(beta), beta + sympy.pi / 2, theta0, phidot_coef * Theta]
    ve, psi_e = _psi_along(S, t, qe)
    exact = {"t": t, "q": qe, "v": ve, "psi": psi_e}
    sub = _symbol_map(S, [x, y, psi, th, ph])
    wz = _to_sym(w.dot(N.z), sub)
    X, Y = S.q[:2]
    cf = {"centre radius": (sympy.sqrt(X ** 2 + Y ** 2), rho + 0 * t),
          "centre angle (2/7) Theta(t)": (sympy.atan2(Y, X), sympy.atan2(sympy.sin(beta), sympy.cos(beta)))}
    q0 = [q.subs(t, 0) for q in qe]
    v0 = [x_.subs(t, 0) for x_ in ve]
    return ClassicScene(name, S, sympy.Integer(0), q0, v0,
                        "homogeneous ball on a turntable " + ("(constant Omega)" if eps == 0 else
                                                              "with Omega(t) = Omega (1 + eps sin t) (rheonomic)")
                        + ": centre on a circle at 2 Omega(t)/7 (closed form)", exact=exact,
                        params={"Omega": Omega, "eps": eps, "rho": rho, "r": r, "m": m},
                        invariants={"omega_z (vertical spin)": wz}, closed_forms=cf,
                        source="E. J. Routh, Advanced Rigid Dynamics (1905), 243")


# --- helpers -----------------------------------------------------------------------------------------
def _symbol_map(S, qs):
    """dynamicsymbols q(t), q'(t) -> the system's plain symbols (as from_mechanics names them)."""
    from sympy.physics.mechanics import dynamicsymbols
    tt = dynamicsymbols._t
    sub = {}
    for qd, qsym, vsym in zip(qs, S.q, S.v):
        sub[qd.diff(tt)] = vsym
    sub2 = dict(zip(qs, S.q))
    return sub, sub2


def _to_sym(expr, sub):
    d, q = sub
    return sympy.sympify(expr).subs(d).subs(q)


def _consistent_v(S, q0, free):
    """Velocities with k(q0, v) = 0 for the rolling bodies: the Euler-angle rates ``free`` and
    (x', y') solved from the two rolling constraints."""
    vs = S.v
    sub = dict(zip(S.q, q0)) | dict(zip(vs[2:], free)) | {S.t: 0}
    sol = sympy.solve([sympy.sympify(e).subs(sub) for e in S.k], vs[:2], dict=True)[0]
    return [sympy.simplify(sol[vs[0]]), sympy.simplify(sol[vs[1]])] + list(free)


CLASSIC_SCENES = ("chaplygin-sleigh", "tilted-disk", "chaplygin-sphere", "suslov", "contact-oscillator",
                  "ball-turntable", "ball-turntable-rheonomic")
