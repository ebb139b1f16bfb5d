"""Adapter from ``sympy.physics.mechanics`` models to the system (1).

``from_mechanics(model, ...)`` accepts what sympy users pass:

* a ``KanesMethod(N, q_ind, u_ind, kd_eqs, u_dependent=..., velocity_constraints=..., bodies=...,
  forcelist=...)``: the generalized speeds u are mapped to q' by solving the kinematic
  differential equations for u; L = T - V is formed from the bodies, the velocity constraints
  (which, as in sympy, include the time derivatives of the configuration constraints) become
  k(q, v) = 0;
* a ``LagrangesMethod(L, qs, hol_coneqs=..., nonhol_coneqs=..., forcelist=..., frame=N)``: its
  Lagrangian, coordinates and ``coneqs`` (the holonomic constraints differentiated in time, then
  the nonholonomic ones, linear in q'(t) as (1c) requires);
* a ``System`` (sympy >= 1.13): coordinates, speeds, kinematic equations, bodies, loads,
  actuators and constraints are read from it as for ``KanesMethod``;
* or a Lagrangian (sympy expression in dynamicsymbols) with ``q=[q1(t), ...]`` and
  ``constraints=[...]`` (velocity constraints; holonomic ones given as their time derivative).

Kinetic energy from the bodies. Lagrange-d'Alembert (1) needs L on all of TQ, not only on the
constraint manifold: a point velocity set "the Kane way" (the rolling condition built into the
kinematics, e.g. ``v2pt_theory`` from the contact point) equals the true velocity only where the
constraints hold, and gives an L that lacks some velocities. So a mass centre's velocity is the
time derivative of its position from a point fixed in the inertial frame (zero velocity there)
when such a chain of positions exists, and a frame's angular velocity comes from its direction
cosine matrix when it has one; the velocities set in the model must agree with these on the
constraint manifold (checked at random points), otherwise the model is refused with the name of
the point or frame.

Loads. Forces (Point, Vector) and torques (ReferenceFrame, Vector) enter through their
generalized forces Q_i = F . d v_P / d q'_i (T . d w_B / d q'_i). A load is accepted when it
has a potential: Q independent of the velocities and curl free (dQ_i/dq_j = dQ_j/dq_i, checked
symbolically, numerically where simplification does not decide), and V with Q = -grad V is
found (V = -F . r for a constant force on a point with a position from a fixed point, else by
integrating coordinate by coordinate and checking the gradient). L becomes T - V. A load without
a potential is refused in one line naming it: generalized forces are not part of (1) here.

Each q_i(t) becomes a plain symbol named after it and q_i'(t) a symbol ``v_<name>``; the time
``dynamicsymbols._t`` becomes the system's t. Free symbols other than t are the system's
parameters (values at integrate time) unless ``params`` lists them explicitly. Anything that
cannot be mapped is refused with a one-line ``SystemDefinitionError`` naming it.
"""
from __future__ import annotations

from typing import Any, Optional, Sequence

import numpy as np
import sympy

from .errors import SystemDefinitionError

#: points at which the set velocities are compared with the derived ones (fixed seed: the
#: same model always gives the same verdict)
_N_CHECK = 3
#: expressions larger than this (sympy.count_ops) are not simplified or integrated: the cost of
#: trigsimp / integrate grows quickly with size, and a model must not make the build hang
_SIMPLIFY_OPS = 400


def _is_zero(e, num, on_manifold=False) -> bool:
    """e == 0: exactly after expansion, else at random points (``_Numeric``), the one test that
    always terminates; simplification is not needed for the verdict."""
    if e == 0 or sympy.expand(e) == 0:
        return True
    return num.zero([e], on_manifold=on_manifold)


def _to_symbols(exprs, qs, t):
    """Replace q_i(t)'' (refused), q_i'(t) and q_i(t) by plain symbols."""
    from sympy.core.function import AppliedUndef
    qsym, vsym = [], []
    for x in qs:
        if not (isinstance(x, AppliedUndef) and x.args == (t,)):
            raise SystemDefinitionError(f"coordinates must be dynamicsymbols q(t), got {x!r}")
        nm = str(x.func)
        qsym.append(sympy.Symbol(nm))
        vsym.append(sympy.Symbol(f"v_{nm}"))
    dsub = {sympy.Derivative(x, t): vs for x, vs in zip(qs, vsym)}
    qsub = dict(zip(qs, qsym))
    out = []
    for e in exprs:
        e = sympy.sympify(e)
        if any(d.derivative_count > 1 for d in e.atoms(sympy.Derivative)):
            raise SystemDefinitionError("L or a constraint contains second time derivatives")
        e = e.subs(dsub).subs(qsub)
        if e.atoms(AppliedUndef) or e.has(sympy.Derivative):
            rest = sorted(map(str, e.atoms(AppliedUndef) | e.atoms(sympy.Derivative)))
            raise SystemDefinitionError(f"L or a constraint contains functions of t that are not coordinates: {rest}")
        out.append(e)
    return out, qsym, vsym


def _refuse_strings(model, q, constraints):
    """Strings are refused here: text in dynamicsymbols (q1(t), Derivative(q1(t), t)) has no
    bounded parser, and sympify would execute it. (LagrangianSystem itself parses strings in
    plain symbols, ``tableau.parse_expression``.)"""
    for what, val in (("the model", model), ("q", q), ("constraints", constraints)):
        items = list(val) if isinstance(val, (list, tuple)) else [val]
        if any(isinstance(x, (str, bytes)) for x in items):
            raise SystemDefinitionError(f"from_mechanics: {what} must be sympy expressions in dynamicsymbols, "
                                        "not strings (text is never evaluated; use LagrangianSystem with plain "
                                        "symbols for expressions given as text)")


class _Model:
    """What the adapter reads from a sympy model: inertial frame, coordinates q, speeds u with
    the map u -> u(q, q'), the Lagrangian (given, or None: from the bodies), bodies, loads,
    velocity constraints (in q, q', u) and a fixed point when the model names one."""

    def __init__(self, kind, frame, q, u_map, L, bodies, loads, cons, fixed=None):
        self.kind, self.frame, self.q, self.u_map = kind, frame, list(q), u_map
        self.L, self.bodies, self.loads, self.cons, self.fixed = L, list(bodies or []), list(loads or []), cons, fixed


def _speed_map(kind, q, u, kdes):
    """{u_j: u_j(q, q')} from kinematic equations linear in u and q' (solved for u)."""
    u = list(u)
    if not u:
        return {}
    if not kdes or len(kdes) != len(u):
        free = [str(getattr(x, "func", x)) for x in u if not any(sympy.sympify(e).has(x) for e in kdes or [])]
        which = f" ({', '.join(free)} {'appears' if len(free) == 1 else 'appear'} in none)" if free else ""
        raise SystemDefinitionError(
            f"{kind}: {len(u)} generalized speeds but {len(kdes or [])} kinematic differential equations{which}: "
            "(1) needs a coordinate for every speed (add the ignored coordinates, e.g. wheel angles with q' = u, "
            "and for a rolling contact point its position and the rolling condition as velocity constraints)")
    kd = sympy.Matrix(list(kdes))
    A = kd.jacobian(u)
    rest = kd.xreplace(dict.fromkeys(u, 0))
    if A.has(*u):
        raise SystemDefinitionError(f"{kind}: the kinematic differential equations are not linear in u")
    if A.is_diagonal() and all(A[i, i] != 0 for i in range(A.rows)):
        sol = [-rest[i] / A[i, i] for i in range(A.rows)]
    else:
        try:
            sol = list(A.LUsolve(-rest))
        except (ValueError, ZeroDivisionError, sympy.matrices.exceptions.NonInvertibleMatrixError):
            raise SystemDefinitionError(f"{kind}: the kinematic differential equations cannot be solved for "
                                        "the generalized speeds u (their u-coefficient matrix is singular)") from None
    if any(e.has(sympy.nan, sympy.zoo, sympy.oo, -sympy.oo) for e in sol):
        raise SystemDefinitionError(f"{kind}: the kinematic differential equations cannot be solved for "
                                    "the generalized speeds u (their u-coefficient matrix is singular)")
    out = dict(zip(u, sol))
    if any(e.has(*u) for e in sol):
        raise SystemDefinitionError(f"{kind}: the kinematic differential equations do not determine u from q'")
    return out


def _read_kane(model):
    from sympy.physics.mechanics import dynamicsymbols
    t = dynamicsymbols._t
    q, u = list(model.q), list(model.u)
    if getattr(model, "_k_ku_implicit", None) is None or not len(model._k_ku_implicit):
        raise SystemDefinitionError("KanesMethod without kinematic differential equations (kd_eqs): "
                                    "u cannot be mapped to q'")
    qd = sympy.Matrix([x.diff(t) for x in q])
    kdes = list(model._k_ku_implicit * model.u + model._k_kqdot_implicit * qd + model._f_k_implicit)
    u_map = _speed_map("KanesMethod", q, u, kdes)
    cons = []
    if len(model._k_nh):
        cons = list(model._k_nh * model.u + model._f_nh)
    if not model.bodies:
        raise SystemDefinitionError("KanesMethod has no bodies: give bodies=[...] (or call "
                                    "kanes_equations(bodies, loads) first)")
    return _Model("KanesMethod", model._inertial, q, u_map, None, model.bodies, model.loads or [], cons)


def _read_lagranges(model):
    loads = list(model._forcelist or [])
    if loads and model.inertial is None:
        raise SystemDefinitionError("LagrangesMethod with a forcelist needs frame=<the inertial frame> to "
                                    "form the generalized forces")
    return _Model("LagrangesMethod", model.inertial, list(model.q), {}, model._L[0], [], loads,
                  list(model.coneqs))


def _read_system(model):
    q, u = list(model.q), list(model.u)
    u_map = _speed_map("System", q, u, list(model.kdes))
    loads = list(model.loads or [])
    for act in getattr(model, "actuators", None) or []:
        loads.extend(act.to_loads())
    cons = list(model.velocity_constraints)
    if not model.bodies:
        raise SystemDefinitionError("System has no bodies: add them with add_bodies(...)")
    return _Model("System", model.frame, q, u_map, None, model.bodies, loads, cons, fixed=model.fixed_point)


def _name(obj) -> str:
    return getattr(obj, "name", None) or str(obj)


class _Kin:
    """Velocities of points and frames in the inertial frame, in q and q', as (1) needs them:
    derived from positions / orientations when possible, else the set ones with u -> u(q, q')."""

    def __init__(self, m: _Model):
        self.m = m
        self.N = m.frame
        self.checks = []          # (what, derived vector, set vector): compared on the manifold

    def _sub(self, vec):
        return vec.xreplace(self.m.u_map) if self.m.u_map else vec

    def _fixed_origin(self, P):
        """A point of P's position tree with zero velocity set in N (the model's fixed point
        first), or None."""
        seen, todo = set(), [P]
        fixed = self.m.fixed
        cands = []
        while todo:
            x = todo.pop(0)
            if id(x) in seen:
                continue
            seen.add(id(x))
            if x is fixed:
                return x
            vel = x._vel_dict.get(self.N)
            if vel is not None and vel == 0:
                cands.append(x)
            todo.extend(x._pos_dict.keys())
        if len(cands) > 1:
            # two zero-velocity points at a varying distance: one of them moves (an instantaneous
            # contact point, the Kane way); the origin of a model is the far end of the chain of
            # positions (the consistency check below catches a wrong choice)
            t = sympy.physics.mechanics.dynamicsymbols._t
            if any(a.pos_from(b).diff(t, self.N) != 0 for a in cands for b in cands if a is not b):
                return cands[-1]
        return cands[0] if cands else None

    def point_velocity(self, P):
        set_v = P._vel_dict.get(self.N)
        O = self._fixed_origin(P)
        if O is not None and O is not P:
            # differentiated in components of N (direction cosines only): Vector.dt would use the
            # angular velocities set in the model, which may be written in speeds
            t = sympy.physics.mechanics.dynamicsymbols._t
            comps = P.pos_from(O).to_matrix(self.N).diff(t)
            derived = comps[0] * self.N.x + comps[1] * self.N.y + comps[2] * self.N.z
            if set_v is not None:
                self.checks.append((f"point {_name(P)}", derived, self._sub(set_v)))
            return derived
        if O is P:
            return set_v
        try:
            return self._sub(P.vel(self.N))
        except ValueError:
            raise SystemDefinitionError(f"{self.m.kind}: the velocity of point {_name(P)} in {_name(self.N)} is "
                                        "not defined (set it, or locate the point from a fixed point)") from None

    def angular_velocity(self, B):
        if B is self.N:
            return sympy.physics.vector.Vector(0)
        set_w = B._ang_vel_dict.get(self.N)
        try:
            path = B._dict_list(self.N, 0)
        except ValueError:
            path = None
        derived = None
        if path is not None:
            # step by step along the orientation tree (each step an elementary orientation, cheap
            # to differentiate) instead of differentiating the composed direction cosine matrix
            derived = sympy.physics.vector.Vector(0)
            speeds = set(self.m.u_map)
            for a, b in zip(path[:-1], path[1:]):
                stored = a._ang_vel_dict.get(b)
                # the one orientation gave (in q'), unless the model set it in terms of speeds
                if stored is not None and not (speeds and stored.free_dynamicsymbols(b) & speeds):
                    derived += stored
                else:
                    derived += a._w_diff_dcm(b)
        if derived is not None:
            if set_w is not None:
                self.checks.append((f"frame {_name(B)}", derived, self._sub(set_w)))
            return derived
        try:
            return self._sub(B.ang_vel_in(self.N))
        except ValueError:
            raise SystemDefinitionError(f"{self.m.kind}: the angular velocity of frame {_name(B)} in "
                                        f"{_name(self.N)} is not defined") from None


def _components(vec, frame):
    """Components of a vector in ``frame``, each trigonometrically simplified."""
    if vec == 0:
        return sympy.zeros(3, 1)
    return sympy.Matrix([sympy.trigsimp(c) if sympy.count_ops(c) <= _SIMPLIFY_OPS else c
                         for c in vec.to_matrix(frame)])


def _kinetic_minus_potential(m: _Model, kin: _Kin):
    """T - V of the bodies (V: their ``potential_energy``)."""
    import sympy.physics.mechanics as me
    T = sympy.S.Zero
    V = sympy.S.Zero
    for body in m.bodies:
        # components simplified one by one (cheap) before they are multiplied out: the derivation
        # of (1) differentiates L twice, and its cost grows with the size of L
        if isinstance(body, me.RigidBody):
            v = _components(kin.point_velocity(body.masscenter), m.frame)
            w = _components(kin.angular_velocity(body.frame), body.frame)
            Ic = body.central_inertia.to_matrix(body.frame)
            T += body.mass * (v.T * v)[0, 0] / 2 + (w.T * Ic * w)[0, 0] / 2
        elif isinstance(body, me.Particle):
            v = _components(kin.point_velocity(body.point), m.frame)
            T += body.mass * (v.T * v)[0, 0] / 2
        else:
            raise SystemDefinitionError(f"{m.kind}: body {body!r} is neither a RigidBody nor a Particle")
        V += sympy.sympify(getattr(body, "potential_energy", 0) or 0)
    return T - V


def _load_parts(load, kind):
    import sympy.physics.mechanics as me
    try:
        loc, vec = load
    except (TypeError, ValueError):
        raise SystemDefinitionError(f"{kind}: load {load!r} is not a (Point, Vector) or (ReferenceFrame, Vector) "
                                    "pair") from None
    if not isinstance(vec, sympy.physics.vector.Vector) and vec != 0:
        raise SystemDefinitionError(f"{kind}: load on {_name(loc)}: {vec!r} is not a Vector")
    if not isinstance(loc, (me.Point, me.ReferenceFrame)):
        raise SystemDefinitionError(f"{kind}: load on {loc!r}: not a Point or a ReferenceFrame")
    return loc, vec


class _Numeric:
    """Random points (t, q, v, parameters) on the constraint manifold, for checks that
    simplification does not decide."""

    def __init__(self, qsym, vsym, tsym, ks, seed=20260):
        self.q, self.v, self.t, self.ks = qsym, vsym, tsym, list(ks)
        self.rng = np.random.default_rng(seed)
        self._pts = None

    def points(self, exprs):
        syms = set().union(*(sympy.sympify(e).free_symbols for e in list(exprs) + self.ks)) \
            - set(self.q) - set(self.v) - {self.t}
        pars = sorted(syms, key=str)
        if self._pts is None or set(self._pts[0][1]) != set(pars):
            pts = []
            for _ in range(_N_CHECK):
                sub = {x: float(self.rng.uniform(0.3, 1.2)) for x in self.q}
                sub.update({p: float(self.rng.uniform(0.5, 1.5)) for p in pars})
                sub[self.t] = float(self.rng.uniform(0, 1))
                z = self.rng.uniform(-1, 1, len(self.v))
                if self.ks:
                    kk = sympy.Matrix(self.ks).xreplace(sub)
                    A = np.array(kk.jacobian(self.v).xreplace(dict(zip(self.v, [0] * len(self.v)))), dtype=float)
                    b = np.array(kk.xreplace(dict(zip(self.v, [0] * len(self.v)))), dtype=float).reshape(-1)
                    z = z - np.linalg.pinv(A) @ (A @ z + b)
                sub.update(dict(zip(self.v, map(float, z))))
                pts.append({x: sympy.Float(val, 30) for x, val in sub.items()})
            self._pts = (pts, pars)
        return self._pts[0]

    def zero(self, exprs, on_manifold=True) -> bool:
        exprs = [sympy.sympify(e) for e in exprs]
        pts = self.points(exprs) if on_manifold else self._free_points(exprs)
        for sub in pts:
            for e in exprs:
                try:
                    val = complex(e.xreplace(sub).evalf(30))
                except (TypeError, ValueError):
                    return False
                scale = 1 + max((abs(complex(a.xreplace(sub).evalf(30))) for a in sympy.Add.make_args(e)),
                                default=0)
                if not np.isfinite(abs(val)) or abs(val) > 1e-9 * scale:
                    return False
        return True

    def _free_points(self, exprs):
        pts = [dict(p) for p in self.points(exprs)]
        for p in pts:
            p.update({x: sympy.Float(float(self.rng.uniform(-1, 1)), 30) for x in self.v})
        return pts


def _potential(i, load, m: _Model, kin: _Kin, qs, conv, num: _Numeric):
    """V of one load (plain symbols), or SystemDefinitionError saying why it has none."""
    import sympy.physics.mechanics as me
    t = me.dynamicsymbols._t
    loc, vec = _load_parts(load, m.kind)
    what = f"loads[{i}] ({'force on point' if isinstance(loc, me.Point) else 'torque on frame'} {_name(loc)})"
    if m.frame is None:
        raise SystemDefinitionError(f"{m.kind}: {what}: no inertial frame to form its generalized force")
    if vec == 0:
        return sympy.S.Zero
    from sympy.physics.units import Quantity
    units = sorted({str(x) for c in vec.to_matrix(m.frame) for x in sympy.sympify(c).atoms(Quantity)})
    if units:
        raise SystemDefinitionError(f"{m.kind}: {what} contains physical units ({', '.join(units[:6])}); the "
                                    "integrator works on numbers: give the values in one consistent unit system")
    vec = kin._sub(vec)
    qd = [x.diff(t) for x in qs]
    vel = kin.point_velocity(loc) if isinstance(loc, me.Point) else kin.angular_velocity(loc)
    Q = [vec.dot(vel.diff(d, m.frame)) for d in qd]
    Qs, qsym, vsym = conv(Q, what)
    moving = sorted({str(x) for e in Qs for x in e.free_symbols if x in set(vsym)})
    if moving:
        raise SystemDefinitionError(f"{m.kind}: {what} depends on the velocities ({', '.join(moving)}): it has no "
                                    "potential, and loads without a potential (generalized forces) are not "
                                    "supported yet")
    n = len(qsym)
    for a in range(n):
        for b in range(a + 1, n):
            d = Qs[a].diff(qsym[b]) - Qs[b].diff(qsym[a])
            if not _is_zero(d, num):
                raise SystemDefinitionError(f"{m.kind}: {what} is not conservative: its generalized force has "
                                            f"dQ_{qsym[a]}/d{qsym[b]} != dQ_{qsym[b]}/d{qsym[a]} (no potential "
                                            "V(q) with Q = -grad V); loads without a potential are not supported yet")
    V = None
    if isinstance(loc, me.Point):
        O = kin._fixed_origin(loc)
        comps = vec.to_matrix(m.frame)
        if O is not None and O is not loc and not any(c.has(t) or c.atoms(sympy.core.function.AppliedUndef)
                                                      for c in comps):
            V = conv([-vec.dot(loc.pos_from(O))], what)[0][0]
    if V is None:
        V = sympy.S.Zero
        for j, x in enumerate(qsym):
            rest = -Qs[j] - V.diff(x)
            if _is_zero(rest, num):
                continue
            if sympy.count_ops(rest) > _SIMPLIFY_OPS:
                raise SystemDefinitionError(f"{m.kind}: {what}: its generalized force is too large to integrate to "
                                            "a potential here; give the potential as a body's potential_energy")
            rest = sympy.simplify(rest)
            others = rest.free_symbols & set(qsym[:j])
            if others:
                raise SystemDefinitionError(f"{m.kind}: {what}: no potential found (integrating its generalized "
                                            f"force left terms in {sorted(map(str, others))})")
            part = sympy.integrate(rest, x)
            if part.has(sympy.Integral):
                raise SystemDefinitionError(f"{m.kind}: {what}: its generalized force could not be integrated "
                                            "to a potential")
            V = V + part
    grad = [-V.diff(x) - e for x, e in zip(qsym, Qs)]
    if not all(_is_zero(g, num) for g in grad):
        raise SystemDefinitionError(f"{m.kind}: {what}: no potential V(q) with Q = -grad V found")
    return V


def _convert_model(m: _Model, name):
    """(L, k, qsym, vsym) in plain symbols from a read model."""
    import sympy.physics.mechanics as me
    t = me.dynamicsymbols._t
    tsym = sympy.Symbol("t")
    kin = _Kin(m)
    u = list(m.u_map)
    cons = [sympy.sympify(c).xreplace(m.u_map) if m.u_map else sympy.sympify(c) for c in m.cons]
    left = sorted({str(x) for c in cons for x in me.find_dynamicsymbols(c) if x in set(u)})
    if left:
        raise SystemDefinitionError(f"{m.kind}: the velocity constraints still contain speeds {left} after u -> q'")

    def conv(exprs, what):
        try:
            ex, qsym, vsym = _to_symbols(exprs, m.q, t)
        except SystemDefinitionError as exc:
            raise SystemDefinitionError(f"{m.kind}: {what}: {exc}") from None
        return [e.subs(t, tsym) for e in ex], qsym, vsym

    ks, qsym, vsym = conv(cons, "velocity constraints")
    # the Kane form stores the constraints with q' -> u(q, q') of its own solve: mapped back they
    # carry removable 0/0 (1/sin, 1/cos of the inverted kinematics), which cancel out here
    ks = [sympy.simplify(sympy.cancel(e))
          if not e.as_numer_denom()[1].is_number and sympy.count_ops(e) <= 4 * _SIMPLIFY_OPS else e for e in ks]
    num = _Numeric(qsym, vsym, tsym, ks)
    L = m.L if m.L is not None else _kinetic_minus_potential(m, kin)
    Ls = conv([L], "the Lagrangian")[0][0]
    for i, load in enumerate(m.loads):
        Ls = Ls - _potential(i, load, m, kin, m.q, conv, num)
    # the velocities set in the model must be the derived ones where the constraints hold
    for what, derived, given in kin.checks:
        diff = list((derived - given).to_matrix(m.frame))
        dsym = conv(diff, what)[0]
        if not all(_is_zero(d, num, on_manifold=True) for d in dsym):
            raise SystemDefinitionError(
                f"{m.kind}: the velocity set for {what} differs from the time derivative of its position / "
                "orientation even where the constraints hold; give velocities consistent with the kinematics "
                "(a point given zero velocity that moves, such as a rolling contact, needs coordinates for its "
                "position and the rolling condition among the velocity constraints)")
    return Ls, ks, qsym, vsym, tsym


def from_mechanics(model: Any, q: Optional[Sequence] = None, constraints: Optional[Sequence] = None,
                   params: Optional[Sequence] = None, name: str = "system", cls: Optional[type] = None) -> Any:
    """A ``LagrangianSystem`` from a KanesMethod, LagrangesMethod, System or a Lagrangian in
    dynamicsymbols (see the module docstring); ``params`` defaults to every free symbol other
    than t. ``cls``: the class to build, ``LagrangianSystem`` or a subclass
    (``LagrangianSystem.from_mechanics`` passes its own: this adapter sits below the system
    module and does not import it)."""
    import sympy.physics.mechanics as me
    if cls is None:
        raise SystemDefinitionError("from_mechanics: give cls (or call LagrangianSystem.from_mechanics)")
    _refuse_strings(model, q, constraints)
    t = me.dynamicsymbols._t
    readers = [(me.KanesMethod, _read_kane), (me.LagrangesMethod, _read_lagranges)]
    if hasattr(me, "System"):
        readers.append((me.System, _read_system))
    reader = next((r for typ, r in readers if isinstance(model, typ)), None)
    if reader is not None:
        if q is not None or constraints is not None:
            raise SystemDefinitionError("give q and constraints only with a plain Lagrangian")
        try:
            mdl = reader(model)
            Ls, ks, qsym, vsym, tsym = _convert_model(mdl, name)
        except SystemDefinitionError:
            raise
        except (sympy.SympifyError, sympy.polys.polyerrors.PolynomialError, TypeError, ValueError, KeyError,
                AttributeError, NotImplementedError, ZeroDivisionError) as exc:
            msg = str(exc).splitlines()[0][:160] if str(exc) else type(exc).__name__
            raise SystemDefinitionError(f"{type(model).__name__}: cannot map the model to (1): {msg}") from None
        exprs = [Ls] + ks
        if not ks:
            raise SystemDefinitionError(f"{type(model).__name__}: the model has no velocity constraints; (1) needs "
                                        "1 <= m < n velocity constraints")
    else:
        if isinstance(model, (me.RigidBody, me.Particle, me.ReferenceFrame, me.Point)) or \
                type(model).__module__.startswith("sympy.physics"):
            raise SystemDefinitionError(f"from_mechanics takes a KanesMethod, LagrangesMethod, System or a "
                                        f"Lagrangian expression, not a {type(model).__name__}")
        if q is None:
            raise SystemDefinitionError("give q=[q1(t), ...] with a Lagrangian in dynamicsymbols")
        try:
            L = sympy.sympify(model, strict=True)
        except (sympy.SympifyError, TypeError, ValueError):
            raise SystemDefinitionError(f"from_mechanics: {type(model).__name__} is not a sympy expression") from None
        qs, cons = list(q), list(constraints or [])
        if not cons:
            raise SystemDefinitionError("the model has no constraints; (1) needs 1 <= m < n velocity constraints")
        exprs, qsym, vsym = _to_symbols([L] + cons, qs, t)
        tsym = sympy.Symbol("t")
        exprs = [e.subs(t, tsym) for e in exprs]
    Ls, ks = exprs[0], exprs[1:]
    if params is None:
        found = set().union(*(e.free_symbols for e in exprs)) - set(qsym) - set(vsym) - {tsym}
        params = sorted(found, key=str) or None
    system = cls(Ls, ks, qsym, vsym, t=tsym, name=name, params=params)
    if getattr(system, "lvv_problem", None):
        # a model read from sympy.physics.mechanics: refused at once (the usual cause, kinematics
        # with the rolling condition built in, is a modelling choice the user can change)
        raise SystemDefinitionError(system.lvv_problem)
    return system
