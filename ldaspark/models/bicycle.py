"""The Whipple bicycle of the benchmark of Meijaard, Papadopoulos, Ruina and Schwab (2007).

Source: J. P. Meijaard, J. M. Papadopoulos, A. Ruina and A. L. Schwab, "Linearized dynamics
equations for the balance and steer of a bicycle: a benchmark and review", Proc. R. Soc. A 463
(2007) 1955-1982 (doi:10.1098/rspa.2007.1857). Parameters: its Table 1; geometry and axes: its
sections 2-3 (x forward, y to the right, z down, origin at the rear contact point in the upright
reference configuration, lean phi and steer delta positive to the right).

The model is written the way a user of ``sympy.physics.mechanics`` writes it (frames, points
with velocities by the two-point theorem, ``RigidBody`` objects) and converted by
``LagrangianSystem.from_mechanics``: four rigid bodies (rear wheel R, rear frame B with the rider,
front frame H with handlebar and fork, front wheel F), knife-edge wheels rolling without slip on
the flat ground z = 0, gravity g along +z. The kinetic energy is summed from the bodies as sums of
squares of velocity components (``_kinetic``) rather than by ``mechanics.Lagrangian``, whose
expanded T made sympy's second derivatives 4-8x slower. sin(lambda), cos(lambda) enter as
40-digit Floats (the model is Table 1 to 1e-40; exact sqrt(5) expressions cost a third more).
Building the system (sympy deriving (1)'s partials of a ~2000-operation Lagrangian) takes about
7-9 s CPU, the generic engine's first stage evaluation (lambdify) about 6 s more, then ~0.1 s CPU
per gauss-2 step (float64). The compiled engine (general form: the largest expression set the code
generator has met) needs 36 s CPU for code generation and numba on first use (cached on disk
afterwards), then 17 us CPU per gauss-2 step (1000 steps of h = 0.01: 0.017 s; energy spread 1.2e-11
relative, |k| <= 2.9e-15; measured on a loaded 2-core machine).

Coordinates (n = 8): rear contact point x, y; yaw psi; lean (roll) phi; pitch theta of the rear
frame (0 in the reference configuration); rear wheel angle theta_R (relative to the rear frame);
steer delta (about the steer axis, tilted back by lambda); front wheel angle theta_F (relative
to the front frame). Constraints (m = 5, all linear in the velocities, (1c)):

* the front wheel touches the ground: the holonomic constraint f(phi, theta, delta) = 0 (the
  height of the front contact point) in its velocity form f_q(q) v = 0, as in section 5.1 of
  Jay's paper (d/dt of the holonomic constraint);
* rolling without slip of the rear wheel: the velocity of the wheel's material point at the
  contact is zero in the two horizontal directions (2 constraints);
* the same for the front wheel (2 constraints).

Upright straight running at speed v0 (all angles 0, x' = v0, theta_R' = -v0 / r_R,
theta_F' = -v0 / r_F) is a steady motion for every v0; its lean-and-steer linearisation is the
benchmark's M q'' + v C1 q' + (g K0 + v^2 K2) q = 0 (eq. 5.3 of the benchmark), which
``ldaspark.models.bicycle_benchmark`` evaluates independently from the appendix formulas.

The scene ``bicycle`` starts at v0 = 5 m/s (inside the self-stable range 4.29 .. 6.02 m/s)
with a lean rate of 1/2 rad/s: the lean angle, the lean rate and the steer decay while the
energy (8) is conserved.
"""
from __future__ import annotations

import mpmath
import sympy
from sympy import Rational as R

from ..core.errors import InputError

#: Table 1 of the benchmark, exact (lengths in m, masses in kg, inertias in kg m^2, g in N/kg)
TABLE1 = {
    "w": R(102, 100), "c": R(8, 100), "lam": sympy.pi / 10, "g": R(981, 100),
    "rR": R(3, 10), "mR": R(2), "IRxx": R(603, 10000), "IRyy": R(12, 100),
    "xB": R(3, 10), "zB": R(-9, 10), "mB": R(85), "IBxx": R(92, 10), "IByy": R(11), "IBzz": R(28, 10),
    "IBxz": R(24, 10),
    "xH": R(9, 10), "zH": R(-7, 10), "mH": R(4), "IHxx": R(5892, 100000), "IHyy": R(6, 100),
    "IHzz": R(708, 100000), "IHxz": R(-756, 100000),
    "rF": R(35, 100), "mF": R(3), "IFxx": R(1405, 10000), "IFyy": R(28, 100),
}

#: coordinate names, in the order of q (and v = q')
COORDS = ("x", "y", "psi", "phi", "theta", "theta_R", "delta", "theta_F")
LEAN, STEER = COORDS.index("phi"), COORDS.index("delta")


def parameters(**overrides) -> dict:
    """Table 1 with some entries replaced (exact sympy numbers; unknown names are an error)."""
    p = dict(TABLE1)
    for key, val in overrides.items():
        if key not in p:
            raise InputError(f"bicycle: unknown parameter {key!r} (Table 1: {', '.join(p)})")
        p[key] = _number(val)
    return p


def _number(x):
    """A user's number as an exact sympy number: text and floats through ``sympy.Rational``'s
    decimal / fraction parser ("0.08", "-2/25"; text is never sympified), sympy numbers and
    integers as they are."""
    if isinstance(x, (str, float)):
        try:
            return sympy.Rational(str(x))
        except (TypeError, ValueError):
            raise InputError(f"bicycle: {x!r} is not a decimal number or a fraction") from None
    if isinstance(x, (int, sympy.Basic)) and not isinstance(x, bool):
        return sympy.sympify(x)
    raise InputError(f"bicycle: {x!r} is not a number")


def whipple_model(p: dict | None = None):
    """The bicycle as ``sympy.physics.mechanics`` objects: (L, q, constraints, extras).

    L is the Lagrangian T - U in dynamicsymbols, q the 8 coordinates q(t), constraints the 5
    velocity constraints (front contact height differentiated in time, then rear and front
    rolling), extras a dict with the holonomic constraint ``f`` (dynamicsymbols) and the frames."""
    from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia
    p = parameters() if p is None else p
    t = dynamicsymbols._t
    q = dynamicsymbols(" ".join(COORDS))
    x, y, psi, phi, theta, thR, delta, thF = q
    lam = p["lam"]

    N = ReferenceFrame("N")                                   # ground: x forward, y right, z down
    Yw = N.orientnew("Yw", "Axis", [psi, N.z])                # yaw
    Ro = Yw.orientnew("Ro", "Axis", [phi, Yw.x])              # lean (roll), positive to the right
    B = Ro.orientnew("B", "Axis", [theta, Ro.y])              # rear frame (pitch)
    Rw = B.orientnew("Rw", "Axis", [thR, B.y])                # rear wheel
    # E: the rear frame turned by lambda about its y axis, so that E.z is the steer axis (pointing
    # down, tilted back by lambda); H: E turned by the steer angle about the steer axis
    E = Ro.orientnew("E", "Axis", [theta + lam, Ro.y])
    H = E.orientnew("H", "Axis", [delta, E.z])                # front frame, steer positive to the right
    Fw = H.orientnew("Fw", "Axis", [thF, H.y])                # front wheel
    # 40-digit Floats: exact algebraic numbers (sqrt(5)) cost 1/3 more to differentiate and to
    # print for lambdify (evalf in the ordering of every sum); the model is Table 1 to 1e-40
    cl, sl = sympy.cos(lam).evalf(40), sympy.sin(lam).evalf(40)

    def in_E(xb, zb):         # a vector given by its benchmark (B-frame) components x, z, in E components
        return (xb * cl - zb * sl) * H.x + (xb * sl + zb * cl) * H.z

    O = Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)                   # rear contact point
    P.set_vel(N, x.diff(t) * N.x + y.diff(t) * N.y)
    Rc = P.locatenew("Rc", -p["rR"] * Ro.z)                   # rear wheel centre (r_R above P, in the wheel plane)
    Bc = Rc.locatenew("Bc", p["xB"] * B.x + (p["zB"] + p["rR"]) * B.z)
    S0 = Rc.locatenew("S0", (p["w"] + p["c"]) * B.x + p["rR"] * B.z)   # steer axis meets the ground (reference)
    Hc = S0.locatenew("Hc", in_E(p["xH"] - p["w"] - p["c"], p["zH"]))
    Fc = S0.locatenew("Fc", in_E(-p["c"], -p["rF"]))          # front wheel centre: trail c behind S0
    Rc.v2pt_theory(P, N, Ro)
    Bc.v2pt_theory(Rc, N, B)
    S0.v2pt_theory(Rc, N, B)
    Hc.v2pt_theory(S0, N, H)
    Fc.v2pt_theory(S0, N, H)
    # front contact point: from the centre, r_F along the lowest direction in the wheel plane
    a = N.z.dot(H.y)
    down = (N.z - a * H.y) / sympy.sqrt(1 - a ** 2)
    Gf = Fc.locatenew("Gf", p["rF"] * down)
    f_hol = Fc.pos_from(O).dot(N.z) + p["rF"] * sympy.sqrt(1 - a ** 2)  # height of Gf: 0 on the ground

    def rot(Ixx, Iyy, Izz, Ixz):   # a B-frame inertia tensor in E (H) components: rotated by lambda about y
        I = sympy.Matrix([[Ixx, 0, Ixz], [0, Iyy, 0], [Ixz, 0, Izz]])
        Ry = sympy.Matrix([[cl, 0, -sl], [0, 1, 0], [sl, 0, cl]])    # rows: E.x, E.y, E.z in B components
        J = Ry * I * Ry.T
        return inertia(H, J[0, 0], J[1, 1], J[2, 2], J[0, 1], J[1, 2], J[0, 2])
    bodies = [
        # the wheels' inertia is axisymmetric about their axle: stated in the frame that carries
        # the axle (B, H), T does not contain the wheel angles (cos^2 + sin^2 is not simplified)
        RigidBody("R", Rc, Rw, p["mR"], (inertia(B, p["IRxx"], p["IRyy"], p["IRxx"]), Rc)),
        RigidBody("B", Bc, B, p["mB"], (inertia(B, p["IBxx"], p["IByy"], p["IBzz"], 0, 0, p["IBxz"]), Bc)),
        RigidBody("H", Hc, H, p["mH"], (rot(p["IHxx"], p["IHyy"], p["IHzz"], p["IHxz"]), Hc)),
        RigidBody("F", Fc, Fw, p["mF"], (inertia(H, p["IFxx"], p["IFyy"], p["IFxx"]), Fc)),
    ]
    carrier = {"R": B, "B": B, "H": H, "F": H}     # frame of each body's inertia components
    L = sum(_kinetic(body, N, Ro, carrier[body.name]) for body in bodies) \
        + p["g"] * sum(body.mass * body.masscenter.pos_from(O).dot(N.z) for body in bodies)   # z down: U = -g m z
    # rolling: the material point of each wheel at its contact point has zero horizontal velocity
    slip_R = Rc.vel(N) + Rw.ang_vel_in(N).cross(P.pos_from(Rc))
    slip_F = Fc.vel(N) + Fw.ang_vel_in(N).cross(Gf.pos_from(Fc))
    cons = [f_hol.diff(t),
            slip_R.dot(Yw.x), slip_R.dot(Yw.y),
            slip_F.dot(Yw.x), slip_F.dot(Yw.y)]
    return L, list(q), cons, {"f": f_hol, "N": N, "frames": (Yw, Ro, B, Rw, E, H, Fw)}


def _exactify(x):
    """A solved velocity as an exact rational when it is one to 30 digits (the model carries
    sin(lambda), cos(lambda) as 40-digit Floats), else the 40-digit Float."""
    x = sympy.sympify(x)
    if x.is_Rational:
        return x
    xf = sympy.Float(x, 40)
    r = sympy.Rational(str(xf)).limit_denominator(10 ** 6)
    return r if abs(sympy.Float(r, 40) - xf) <= sympy.Float("1e-30") * (1 + abs(xf)) else xf


def _kinetic(body, N, frame, inertia_frame):
    """T = m |v|^2 / 2 + omega . I . omega / 2 of a ``RigidBody``, kept as a sum of squares of
    velocity components (v in ``frame`` components, omega and I in ``inertia_frame``'s): the
    derivatives L_q, L_qq, ... of (1) then stay products of small factors. ``Lagrangian(N,
    *bodies)`` gives the same T expanded (10^4 operations, 57 000 with velocities from
    ``pos_from(O).dt(N)``); forming its second derivatives took 30-80 s against ~10 s CPU here."""
    v = body.masscenter.vel(N).to_matrix(frame)
    w = body.frame.ang_vel_in(N).to_matrix(inertia_frame)
    I = body.central_inertia.to_matrix(inertia_frame)
    return body.mass * (v.T * v)[0, 0] / 2 + (w.T * I * w)[0, 0] / 2


#: free velocities of the upright state (the bicycle has 3 degrees of freedom in velocity) and
#: the m = 5 dependent ones, solved from k = 0
FREE_V = ("phi", "delta", "theta_R")
DEPENDENT_V = ("x", "y", "psi", "theta", "theta_F")


class Bicycle:
    """The built model: ``system`` (LagrangianSystem, n = 8, m = 5), ``f`` the holonomic
    front-contact constraint f(q) = 0 (plain symbols; its velocity form is k[0]) and ``params``
    (Table 1 with the overrides). Building derives the system once (7-9 s CPU, module docstring)."""

    def __init__(self, **overrides):
        from sympy.physics.mechanics import dynamicsymbols
        from ..core.mechanics import _to_symbols
        from ..core.system import LagrangianSystem
        self.params = parameters(**overrides)
        L, q, cons, extra = whipple_model(self.params)
        name = "bicycle" if not overrides else "bicycle(" + ", ".join(f"{k}={v}" for k, v in overrides.items()) + ")"
        self.system = LagrangianSystem.from_mechanics(L, q=q, constraints=cons, name=name)
        (f,), _, _ = _to_symbols([extra["f"]], q, dynamicsymbols._t)
        self.f = f
        self.q, self.v = self.system.q, self.system.v
        self.i_free = [COORDS.index(c) for c in FREE_V]
        self.i_dep = [COORDS.index(c) for c in DEPENDENT_V]

    def upright(self, speed, lean_rate=0, steer_rate=0):
        """Exact (sympy) consistent initial data at the upright reference configuration (q = 0):
        rear wheel rate -speed / r_R, the given lean and steer rates, the 5 dependent velocities
        solved from k(q, v) = 0. With zero lean and steer rates this is upright straight running
        at forward speed ``speed`` (x' = speed)."""
        q0 = [sympy.Integer(0)] * 8
        free = {COORDS.index("phi"): _number(lean_rate), COORDS.index("delta"): _number(steer_rate),
                COORDS.index("theta_R"): -_number(speed) / self.params["rR"]}
        # k = K(q) v is linear in v: K at q = 0 evaluated at 50 digits, K_dep v_dep = -K_free v_free
        with mpmath.workdps(50):
            K = self.system.k_v.subs(dict(zip(self.q, q0)))
            Km = mpmath.matrix([[mpmath.mpf(str(sympy.N(K[i, j], 60))) for j in range(8)] for i in range(5)])
            rhs = mpmath.matrix([-sum(Km[i, j] * mpmath.mpf(str(sympy.N(val, 60))) for j, val in free.items())
                                 for i in range(5)])
            dep = mpmath.lu_solve(mpmath.matrix([[Km[i, j] for j in self.i_dep] for i in range(5)]), rhs)
            v0 = [free.get(j) for j in range(8)]
            for a, j in enumerate(self.i_dep):
                v0[j] = sympy.Float(mpmath.nstr(dep[a], 45), 45)
        return q0, [_exactify(x) for x in v0]

    def scene(self, speed=5, lean_rate=R(1, 2)):
        from .scene import Scene
        q0, v0 = self.upright(speed, lean_rate)
        return Scene("bicycle", self.system, sympy.Integer(0), q0, v0,
                     f"Whipple bicycle, benchmark of Meijaard et al. (2007), upright at {speed} m/s, lean rate {lean_rate} rad/s",
                     params={"speed": speed, "lean_rate": lean_rate})


_BUILT: dict = {}


def build(**overrides) -> Bicycle:
    """The model with Table 1 (and ``overrides``), built once per process."""
    key = tuple(sorted((k, str(v)) for k, v in overrides.items()))
    if key not in _BUILT:
        _BUILT[key] = Bicycle(**overrides)
    return _BUILT[key]


def bicycle(speed=5, lean_rate=R(1, 2)):
    """Scene ``bicycle``: the benchmark bicycle at ``speed`` m/s from the upright reference
    configuration with lean rate ``lean_rate`` (self-stable at 5 m/s: lean and steer decay)."""
    return build().scene(speed, lean_rate)
