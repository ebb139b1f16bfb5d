"""Rolling bodies written the way Kane and Levinson (and PyDy's examples) write them: fewer
generalized speeds than coordinates, the rolling condition built into the kinematic differential
equations q' = W(q) u + w(q). ``LagrangianSystem.from_mechanics`` reads them as they are and
derives the velocity constraints k = N(q)^T (q' - w) = 0 from the kinematics (N spanning the left
null space of W; ``core.mechanics._minimal_speeds``).

* ``rolling_disc()``: a thin disc rolling on the plane N.x-N.y; 5 coordinates (yaw q1, lean q2,
  spin q3 as sympy's test_kane5 orients them; q4, q5 the contact point, which advances with the
  contact: q4' = r q3' A.x . N.x, ...), 3 speeds (the disc's angular velocity in the lean frame
  A), gravity as a load. (1) gets the 2 rows of the rolling condition.
* ``chaplygin_ball()``: a ball of radius r with its mass centre at its centre and three different
  principal moments, rolling on the plane; 6 coordinates (a quaternion e0..e3 and the centre's x,
  y), 5 speeds (the body-frame angular velocity from ``kinematic_equations(..., 'quaternion')``
  and x', y' as dependent speeds with the rolling condition among the velocity constraints).
  (1) gets the quaternion's unit norm in velocity form, e . e' = 0, as the kinematic row.

Each returns ``(kane, info)``: the KanesMethod after ``kanes_equations()`` (its mass_matrix_full
and forcing_full are sympy's own equations of motion, the reference of the tests) and a dict with
the coordinates ``q``, speeds ``u`` (independent first), the kinematic equations ``kd``, the
velocity constraints ``fnh`` (in u), and parameter values ``params`` (floats)."""
from __future__ import annotations


def rolling_disc():
    import sympy
    import sympy.physics.mechanics as me
    t = me.dynamicsymbols._t
    q1, q2, q3, q4, q5 = me.dynamicsymbols("q1:6")
    u1, u2, u3 = me.dynamicsymbols("u1:4")
    g, r, m = sympy.symbols("g r m")
    N, A, D = me.ReferenceFrame("N"), me.ReferenceFrame("A"), me.ReferenceFrame("D")
    A.orient_body_fixed(N, (q1, q2, 0), "zxy")
    D.orient_axis(A, A.y, q3)
    O = me.Point("O")
    O.set_vel(N, 0)
    C = O.locatenew("C", q4 * N.x + q5 * N.y)          # the contact point
    G = C.locatenew("G", r * A.z)
    w = D.ang_vel_in(N)
    kd_w = [u1 - w.dot(A.x), u2 - w.dot(A.y), u3 - w.dot(A.z)]
    qd = sympy.solve(kd_w, [q1.diff(t), q2.diff(t), q3.diff(t)], dict=True)[0]
    spin = qd[q3.diff(t)]                                # q3' in the speeds
    kd = kd_w + [q4.diff(t) - r * spin * A.x.dot(N.x), q5.diff(t) - r * spin * A.x.dot(N.y)]
    D.set_ang_vel(N, u1 * A.x + u2 * A.y + u3 * A.z)
    C.set_vel(N, r * spin * A.x)                         # the contact advances with the rolling
    G.set_vel(N, (u1 * A.x + u2 * A.y + u3 * A.z).cross(r * A.z))
    disc = me.RigidBody("disc", G, D, m, (m * r ** 2 / 4 * me.inertia(D, 1, 2, 1), G))
    kane = me.KanesMethod(N, [q1, q2, q3, q4, q5], [u1, u2, u3], kd, bodies=[disc],
                          forcelist=[(G, -m * g * N.z)])
    kane.kanes_equations()
    return kane, {"q": [q1, q2, q3, q4, q5], "u": [u1, u2, u3], "kd": kd, "fnh": [],
                  "params": {"g": 9.81, "r": 0.26, "m": 3.43}}


def chaplygin_ball():
    import sympy
    import sympy.physics.mechanics as me
    t = me.dynamicsymbols._t
    e = list(me.dynamicsymbols("e0:4"))
    x, y = me.dynamicsymbols("x y")
    u = list(me.dynamicsymbols("u1:6"))
    r, m, g, i1, i2, i3 = sympy.symbols("r m g I1 I2 I3")
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    B.orient_quaternion(N, e)
    kd = list(me.kinematic_equations(u[:3], e, "quaternion")) + [x.diff(t) - u[3], y.diff(t) - u[4]]
    B.set_ang_vel(N, u[0] * B.x + u[1] * B.y + u[2] * B.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    G = O.locatenew("G", x * N.x + y * N.y + r * N.z)
    G.set_vel(N, u[3] * N.x + u[4] * N.y)
    ball = me.RigidBody("ball", G, B, m, (me.inertia(B, i1, i2, i3), G))
    vc = G.vel(N) + B.ang_vel_in(N).cross(-r * N.z)      # the material point at the contact
    fnh = [vc.dot(N.x), vc.dot(N.y)]
    kane = me.KanesMethod(N, e + [x, y], u[:3], kd, u_dependent=u[3:], velocity_constraints=fnh,
                          bodies=[ball], forcelist=[(G, -m * g * N.z)])
    kane.kanes_equations()
    return kane, {"q": e + [x, y], "u": u, "kd": kd, "fnh": fnh,
                  "params": {"g": 9.81, "r": 0.3, "m": 2.0, "I1": 0.07, "I2": 0.09, "I3": 0.11}}
