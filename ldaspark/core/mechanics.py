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

Coordinate-less speeds and Kane-way contacts. A speed that no kinematic equation ties to a
coordinate (an ignorable angle left out, as sympy's bicycle leaves out its wheel angles) gets a
coordinate q_<speed> with q_<speed>' = speed (``_add_speed_coordinates``; a body whose frame has no
orientation must spin about an axis of symmetry of its inertia, ``_spin_frame``). A point given
zero velocity and located from no fixed point while the model is located from it (a rolling
contact written the Kane way) is rebuilt as part of an unconstrained model: new coordinates for
its position in its plane, the rolling condition of its wheel as two velocity constraints after
the model's own (``_root_contacts``, which says why the constrained Lagrangian would be wrong).
The system's ``added_coordinates`` (name -> why) and ``added_constraints`` list what was added.

Loads. Forces (Point, Vector) and torques (ReferenceFrame, Vector) enter through their
generalized forces Q_i = F . d v_P / d q'_i (T . d w_B / d q'_i). A load is accepted when it
has a potential: Q independent of the velocities and curl free (dQ_i/dq_j = dQ_j/dq_i, checked
symbolically, numerically where simplification does not decide), and V with Q = -grad V is
found (V = -F . r for a constant force on a point with a position from a fixed point, else by
integrating coordinate by coordinate and checking the gradient). L becomes T - V. A load without
a potential (depending on the velocities, not curl free, or with a potential not found) enters
(1b) through its generalized force F(t, q, v), as the Lagrange-d'Alembert principle with forces
has it: d/dt grad_v L = grad_q L - K^T psi + F. F is the system's ``N`` (the slot of the nonideal
term of section 3.3, which every engine integrates, R_i = -K_i^T Psi_i + F(T_i, Q_i, V_i) in (21b,
d)); ``system.force_loads`` names those loads. A model without velocity constraints has m = 0.

Kane's minimal speeds. Kinematic equations with fewer speeds than coordinates, q' = W(q) u + w(q)
with W of rank o < n (the rolling condition built in, a quaternion's four rates from three
angular speeds), give velocity constraints k = N(q)^T (q' - w) = 0, N spanning the left null
space of W (``_minimal_speeds``, without division where a block of W has a numeric determinant);
a quaternion's unit norm appears as e . e' = 0, its points are sampled on |e| = 1 and L gets
mu (e . e')^2 / 2 where L_vv does not see that direction (``_regularize_unit_norm``). The pieces
that come from inverting the kinematic equations are freed of removable 0/0 (``_cancel_trig``).

Each q_i(t) becomes a plain symbol named after it and q_i'(t) a symbol ``v_<name>`` (with trailing
underscores when the model has a symbol of that name, ``_final_names``); the time
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


def _to_symbols(exprs, qs, t, cache=None):
    """Replace q_i(t)'' (refused), q_i'(t) and q_i(t) by symbols: Dummy ones (named q_i and
    v_<q_i>), which no symbol of the model can equal, until ``_final_names`` names them once every
    expression is known. ``cache``: coordinate -> its (q, v) dummies, shared by the calls of one
    conversion (the same coordinate must get the same symbols every time). Without ``cache``: the
    plain symbols q_i, v_<q_i> (what a system without name collisions has, for a caller that
    writes an expression of its own in them)."""
    from sympy.core.function import AppliedUndef
    plain = cache is None
    cache = {} if cache is None else cache
    qsym, vsym = [], []
    for x in qs:
        if not (isinstance(x, AppliedUndef) and x.args == (t,)):
            raise SystemDefinitionError(f"coordinates must be dynamicsymbols q(t), got {x!r}")
        if x not in cache:
            nm = str(x.func)
            sym = sympy.Symbol if plain else sympy.Dummy
            cache[x] = (sym(nm), sym(f"v_{nm}"))
        qsym.append(cache[x][0])
        vsym.append(cache[x][1])
    dsub = {sympy.Derivative(x, t): vs for x, vs in zip(qs, vsym)}
    qsub = dict(zip(qs, qsym))
    out = []
    for e in exprs:
        e = sympy.sympify(e)
        if any(d.derivative_count > 1 for d in e.atoms(sympy.Derivative)):
            raise SystemDefinitionError("L or a constraint contains second time derivatives")
        # xreplace (structural, linear in the size) where subs would rewrite the tree at each
        # pattern: q'(t) first, then q(t)
        e = e.xreplace(dsub).xreplace(qsub)
        if e.atoms(AppliedUndef) or e.has(sympy.Derivative):
            rest = sorted(map(str, e.atoms(AppliedUndef) | e.atoms(sympy.Derivative)))
            raise SystemDefinitionError(f"L or a constraint contains functions of t that are not coordinates: {rest}")
        out.append(e)
    return out, qsym, vsym


def _refuse_strings(model, q, constraints):
    """Strings are refused here: text in dynamicsymbols (q1(t), Derivative(q1(t), t)) has no
    bounded parser, and sympify would execute it. (LagrangianSystem itself parses strings in
    plain symbols, ``numbers.parse_expression``.)"""
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

    def __init__(self, kind, frame, q, u_map, L, bodies, loads, cons, fixed=None, config=None):
        self.kind, self.frame, self.q, self.u_map = kind, frame, list(q), u_map
        self.L, self.bodies, self.loads, self.cons, self.fixed = L, list(bodies or []), list(loads or []), cons, fixed
        self.config = list(config or [])     # configuration constraints (their derivatives must be in cons)
        self.added = {}                      # coordinate added by the adapter -> why
        self.added_rows = []                 # why of the last rows of k (the adapter added them)
        self.added_terms = []                # terms added to L that vanish on k = 0 (why)
        self.free = []                       # speeds that no kinematic equation ties to a coordinate
        self.tidy = True                     # cancel removable 0/0 in the mapped constraints


def _add_speed_coordinates(m: _Model, free):
    """A speed u that no kinematic differential equation ties to a coordinate (sympy's models leave
    out ignorable angles this way, e.g. the spin of a wheel whose inertia is symmetric about its
    axis) gets a coordinate q_u(t) with q_u' = u: (1) needs a coordinate for every velocity, and
    nothing in L or k depends on the added angle itself (a body whose frame has no orientation is
    accepted only as such a spin, see ``_spin_frame``)."""
    from sympy.physics.mechanics import dynamicsymbols
    t = dynamicsymbols._t
    m.free = list(free)
    for x in free:
        nm = _fresh_name(m, f"q_{getattr(x, 'func', x)}")
        th = dynamicsymbols(nm)
        m.q.append(th)
        m.u_map[x] = th.diff(t)
        m.added[nm] = (f"{nm}' = {getattr(x, 'func', x)} (a speed in no kinematic differential equation; "
                       "nothing depends on the angle itself)")


def _fresh_name(m: _Model, base):
    import re
    base = re.sub(r"\W", "_", base)
    if not base.isidentifier():
        base = "c_" + base
    taken = {str(getattr(x, "func", x)) for x in m.q}
    nm = base
    while nm in taken:
        nm += "_"
    return nm


def _speed_map(kind, q, u, kdes):
    """({u_j: u_j(q, q')}, free) from kinematic equations linear in u and q' (solved for u);
    ``free``: the speeds that appear in no kinematic equation (they get coordinates of their own,
    ``_add_speed_coordinates``)."""
    u = list(u)
    if not u:
        return {}, [], [], []
    kdes = [sympy.sympify(e) for e in (kdes or [])]
    free = [x for x in u if not any(e.has(x) for e in kdes)]
    tied = [x for x in u if x not in free]
    if len(kdes) > len(tied) and tied:
        # Kane's minimal speeds: q' = W(q) u + w(q) with fewer speeds than equations
        return _minimal_speeds(kind, q, tied, kdes) + (free,)
    if len(kdes) != len(tied):
        which = f" (in them: {len(tied)} of the speeds)" if free else ""
        raise SystemDefinitionError(
            f"{kind}: {len(u)} generalized speeds but {len(kdes)} kinematic differential equations{which}: "
            "(1) needs the equations to determine every speed they contain from q' (a speed in none of them "
            "gets a coordinate of its own)")
    if not tied:
        return {}, [], [], free
    kd = sympy.Matrix(kdes)
    A = kd.jacobian(tied)
    rest = kd.xreplace(dict.fromkeys(tied, 0))
    if A.has(*tied):
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
    # the solve divides by pivots such as cos(theta) + sin(theta)^2/cos(theta) = 1/cos(theta): the
    # removable 0/0 it leaves would reach k and the generated code (off by 3e-2 at fl(pi/2))
    sol = [_cancel_trig(e) for e in sol]
    out = dict(zip(tied, sol))
    if any(e.has(*u) for e in sol):
        raise SystemDefinitionError(f"{kind}: the kinematic differential equations do not determine u from q'")
    return out, [], [], free


#: bounds of the derivation of Kane's minimal-speed constraints: equations, and the subsets of
#: them tried for an invertible block (C(n, o) grows quickly)
_MAX_KDES = 16
_MAX_SUBSETS = 400


def _nonzero_somewhere(e, seed=47) -> bool:
    """e is not identically zero: its value at a random point of (q, parameters) (two points; a
    determinant that vanishes at both is treated as singular)."""
    from sympy.physics.mechanics import find_dynamicsymbols
    rng = np.random.default_rng(seed)
    for _ in range(2):
        sub = {x: sympy.Float(rng.uniform(0.3, 1.2), 20) for x in find_dynamicsymbols(e)}
        val = e.xreplace(sub)
        val = val.xreplace({x: sympy.Float(rng.uniform(0.5, 1.5), 20) for x in val.free_symbols})
        try:
            if abs(complex(val.evalf(20))) > 1e-8:
                return True
        except (TypeError, ValueError):
            continue
    return False


def _minimal_speeds(kind, q, tied, kdes):
    """Kane's minimal speeds: kinematic differential equations A(q) u + r(q, q') = 0, n of them
    (one per coordinate) in o < n speeds, r linear in q' (q' = W u + w with W = -B^{-1} A of rank
    o < n). (1) needs a velocity for every coordinate, so the rolling conditions the model built
    into the kinematics become velocity constraints: the left null space of A applied to r,
    k = N(q)^T r(q, q') = 0 (zero exactly on q' = W u + w, and N^T A = 0 leaves no u).

    Derived without dividing: a block A_S of o rows with det(A_S) != 0 gives u = -adj(A_S) r_S /
    det(A_S) and the n - o rows det(A_S) r_R - A_R adj(A_S) r_S (= det(A_S) (A_R u + r_R)). A
    block whose determinant is a nonzero number after sin^2 + cos^2 = 1 is preferred (u and k
    polynomial: rolling-disc and contact coordinates); otherwise (quaternions: every 3 x 3 block
    of E(q)^T vanishes somewhere) u = -(A^T A)^{-1} A^T r (A^T A = |q|^2 / 4 for a quaternion) and
    each row is divided by the gcd of its coefficients (|q|^2: what remains is q . q' = 0). Each
    piece is reduced by ``_cancel_trig``. Returns ({u: u(q, q')}, rows, why-per-row)."""
    from itertools import combinations, islice
    from sympy.physics.mechanics import dynamicsymbols
    t = dynamicsymbols._t
    n, o = len(kdes), len(tied)
    if n > _MAX_KDES:
        raise SystemDefinitionError(f"{kind}: {n} kinematic differential equations in {o} speeds: more than "
                                    f"{_MAX_KDES} are not reduced to velocity constraints (give one speed per "
                                    "coordinate and the constraints as velocity_constraints)")
    kd = sympy.Matrix(kdes)
    qd = [x.diff(t) for x in q]
    A = kd.jacobian(tied)
    r = kd.xreplace(dict.fromkeys(tied, 0))
    if A.has(*tied) or A.has(*qd) or r.jacobian(qd).has(*qd):
        raise SystemDefinitionError(f"{kind}: the kinematic differential equations are not linear in u and q'")
    subsets = islice(combinations(range(n), o), _MAX_SUBSETS)
    numeric, symbolic = None, None
    for S in subsets:
        AS = A.extract(list(S), list(range(o)))
        d = AS.det(method="berkowitz")
        d = _trig_normal(d) if sympy.count_ops(d) <= 4 * _SIMPLIFY_OPS else d
        if d.is_number:
            if d != 0:
                numeric = (S, AS, d)
                break
        elif symbolic is None and _nonzero_somewhere(d):
            symbolic = (S, AS, d)
    if numeric is None and symbolic is None:
        raise SystemDefinitionError(f"{kind}: {o} generalized speeds but {n} kinematic differential equations, "
                                    "and the speeds' coefficients have rank < " f"{o}: the speeds are not "
                                    "independent (q' = W u + w needs W of full column rank)")
    S, AS, d = numeric or symbolic
    R = [i for i in range(n) if i not in S]
    adj = AS.adjugate(method="berkowitz")
    rS = r.extract(list(S), [0])
    rows = [d * r[i] - (A[i, :] * adj * rS)[0, 0] for i in R]
    def red(e):
        e = _cancel_trig(e)
        small = sympy.denom(e).is_number and sympy.count_ops(e) <= 4 * _SIMPLIFY_OPS
        return _trig_normal(e) if small else e
    if numeric is not None:
        sol = [red(e / d) for e in (-adj * rS)]
        rows = [red(e / d) for e in rows]
    else:
        G = (A.T * A).applyfunc(_cancel_trig)
        try:
            sol = [_cancel_trig(e) for e in G.LUsolve(-A.T * r)]
        except (ValueError, ZeroDivisionError, sympy.matrices.exceptions.NonInvertibleMatrixError):
            raise SystemDefinitionError(f"{kind}: the kinematic differential equations cannot be solved for "
                                        "the generalized speeds u (A^T A is singular)") from None
        rows = [_primitive(_cancel_trig(e), qd) for e in rows]
    if any(e.has(sympy.nan, sympy.zoo, sympy.oo, -sympy.oo) for e in list(sol) + rows):
        raise SystemDefinitionError(f"{kind}: the kinematic differential equations cannot be solved for "
                                    "the generalized speeds u")
    rows = [e for e in rows if e != 0]
    why = [f"kinematics: {o} speeds for {n} coordinates, q' = W(q) u + w(q) holds only where this row of "
           "N(q)^T (q' - w) is 0 (N spans the left null space of W)" for _ in rows]
    return dict(zip(tied, sol)), rows, why


def _primitive(e, qd):
    """e (linear in q') divided by the gcd of its coefficients, a factor that does not vanish
    where the constraint does (|q|^2 of a quaternion's q . q')."""
    ex = sympy.expand(e)
    coeffs = [ex.coeff(x) for x in qd]
    coeffs.append(ex.xreplace(dict.fromkeys(qd, 0)))
    coeffs = [c for c in coeffs if c != 0]
    if not coeffs:
        return e
    try:
        g = sympy.gcd_list(coeffs)
    except (sympy.polys.polyerrors.PolynomialError, sympy.polys.polyerrors.CoercionFailed):
        return e
    if g.is_number or g == 0:
        return e
    return sympy.expand(sympy.cancel(ex / g))


def _read_kane(model):
    from sympy.physics.mechanics import dynamicsymbols
    t = dynamicsymbols._t
    q, u = list(model.q), list(model.u)
    if getattr(model, "_k_ku_implicit", None) is None or not len(model._k_ku_implicit):
        raise SystemDefinitionError("KanesMethod without kinematic differential equations (kd_eqs): "
                                    "u cannot be mapped to q'")
    qd = sympy.Matrix([x.diff(t) for x in q])
    kdes = list(model._k_ku_implicit * model.u + model._k_kqdot_implicit * qd + model._f_k_implicit)
    u_map, krows, kwhy, free = _speed_map("KanesMethod", q, u, kdes)
    cons = []
    if len(model._k_nh):
        cons = list(model._k_nh * model.u + model._f_nh)
    cons += krows
    if not model.bodies:
        raise SystemDefinitionError("KanesMethod has no bodies: give bodies=[...] (or call "
                                    "kanes_equations(bodies, loads) first)")
    m = _Model("KanesMethod", model._inertial, q, u_map, None, model.bodies, model.loads or [], cons,
               config=list(getattr(model, "_f_h", None) or []))
    # sympy writes the constraints with q' -> u of its own solve of the kinematics; only a solve
    # with denominators (1/cos of inverted kinematics) leaves removable 0/0 to cancel
    qu = getattr(model, "_qdot_u_map", None) or {}
    m.tidy = any(not sympy.denom(sympy.together(e)).is_number for e in qu.values())
    m.added_rows = list(kwhy)
    _add_speed_coordinates(m, free)
    return m


def _read_lagranges(model):
    loads = list(model._forcelist or [])
    if loads and model.inertial is None:
        raise SystemDefinitionError("LagrangesMethod with a forcelist needs frame=<the inertial frame> to "
                                    "form the generalized forces")
    return _Model("LagrangesMethod", model.inertial, list(model.q), {}, model._L[0], [], loads,
                  list(model.coneqs))


def _read_system(model):
    q, u = list(model.q), list(model.u)
    u_map, krows, kwhy, free = _speed_map("System", q, u, list(model.kdes))
    loads = list(model.loads or [])
    for act in getattr(model, "actuators", None) or []:
        loads.extend(act.to_loads())
    cons = list(model.velocity_constraints) + krows
    if not model.bodies:
        raise SystemDefinitionError("System has no bodies: add them with add_bodies(...)")
    m = _Model("System", model.frame, q, u_map, None, model.bodies, loads, cons, fixed=model.fixed_point)
    m.added_rows = list(kwhy)
    _add_speed_coordinates(m, free)
    return m


def _name(obj) -> str:
    return getattr(obj, "name", None) or str(obj)


class _Kin:
    """Velocities of points and frames in the inertial frame, in q and q', as (1) needs them:
    derived from positions / orientations when possible, else the set ones with u -> u(q, q')."""

    def __init__(self, m: _Model):
        self.m = m
        self.N = m.frame
        self.checks = []          # (what, derived vector, set vector): compared on the manifold
        self._checked = set()
        self.roots = {}           # id(point) -> {"offset", "material"}: rolling contacts given coordinates
        self._w_cache = {}        # (id(frame), id(parent)) -> angular velocity from the orientation

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

    def _check(self, what, obj, derived, given):
        # once per point or frame: velocities are asked for again and again (every position
        # differentiated needs its frames' angular velocities)
        if id(obj) not in self._checked:
            self._checked.add(id(obj))
            self.checks.append((what, derived, self._sub(given)))

    def position(self, P):
        """(O, r): P's position r from a fixed point O (a rolling contact reconstructed by
        ``_root_contacts`` is located at its added coordinates), or (None, None)."""
        O = self._fixed_origin(P)
        if O is None:
            return None, None
        r = P.pos_from(O) if O is not P else sympy.physics.vector.Vector(0)
        root = self.roots.get(id(O))
        return (O, r + root["offset"]) if root is not None else (O, r)

    def point_velocity(self, P):
        set_v = P._vel_dict.get(self.N)
        O, r = self.position(P)
        root = self.roots.get(id(O)) if O is not None else None
        if root is not None and O is P:
            # the contact point itself: the model's zero velocity is that of the wheel's material
            # point there (a load applied at it does no work on motions that obey the rolling rows)
            return root["material"]
        if O is not None and O is not P:
            derived = self._dt(r)
            if set_v is not None:
                self._check(f"point {_name(P)}", P, derived, set_v)
            return derived
        if O is P:
            return set_v
        try:
            return self._sub(P.vel(self.N))
        except ValueError:
            raise SystemDefinitionError(f"{self.m.kind}: the velocity of point {_name(P)} in {_name(self.N)} is "
                                        "not defined (set it, or locate the point from a fixed point)") from None

    def _dt(self, r):
        """d r / dt in N with the angular velocities derived from the orientations (Vector.dt
        would use the ones set in the model, which may be written in speeds): each frame's part
        c . e as c' . e + w x (c . e), which stays in the frames the position is written in
        (far smaller than the derivative of its components in N)."""
        t = sympy.physics.mechanics.dynamicsymbols._t
        out = sympy.physics.vector.Vector(0)
        for comps, F in r.args:
            part = sympy.physics.vector.Vector([(comps, F)])
            dc = comps.diff(t)
            if any(c != 0 for c in dc):
                out += sympy.physics.vector.Vector([(dc, F)])
            if F is not self.N:
                if not _oriented(F, self.N):
                    raise SystemDefinitionError(f"{self.m.kind}: a position is given in frame {_name(F)}, which has "
                                                f"no orientation relative to {_name(self.N)}")
                out += self.angular_velocity(F).cross(part)
        return out

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
                    key = (id(a), id(b))
                    if key not in self._w_cache:      # asked again for every position differentiated
                        self._w_cache[key] = _w_quaternion(a, b) or _w_from_dcm(a, b)
                    derived += self._w_cache[key]
        if derived is not None:
            if set_w is not None:
                self._check(f"frame {_name(B)}", B, derived, set_w)
            return derived
        try:
            return self._sub(B.ang_vel_in(self.N))
        except ValueError:
            raise SystemDefinitionError(f"{self.m.kind}: the angular velocity of frame {_name(B)} in "
                                        f"{_name(self.N)} is not defined") from None


#: components larger than this are not reduced: taken in the body's frame they are compact
#: already, and expanding a large product costs more than it saves
_TRIGSIMP_OPS = 40


def _trig_normal(e):
    """``e`` with every sin(x)^k (k >= 2) written as sin(x)^(k mod 2) (1 - cos(x)^2)^(k // 2),
    expanded: a polynomial in sin(x), cos(x) has one such form modulo sin^2 + cos^2 = 1, so the
    identities that make angular velocities and velocity components compact cancel exactly.
    Used instead of ``trigsimp`` (its search over rewrite rules was more than half of building the
    KanesMethod bicycle: ~5 s of a ~10 s build); the value is the same expression."""
    e = sympy.expand(e)
    rep = {}
    for p in e.atoms(sympy.Pow):
        b, k = p.args
        if isinstance(b, sympy.sin) and k.is_Integer and k >= 2:
            rep[p] = b ** (k % 2) * (1 - sympy.cos(b.args[0]) ** 2) ** (k // 2)
    return sympy.expand(e.xreplace(rep)) if rep else e


def _cancel_trig(e, ops=4 * _SIMPLIFY_OPS):
    """``e`` with the denominators that cancel modulo sin^2 + cos^2 = 1 cancelled: numerator and
    denominator of ``together(e)`` brought to ``_trig_normal`` form, then ``cancel`` (a polynomial
    gcd in the sines and cosines). Applied to what inverting the kinematic equations produces, the
    pieces where such 0/0 arise; an expression with a numeric denominator, or larger than ``ops``
    (the cost of expansion grows quickly), is returned as it is. A denominator that remains is a
    true singularity of the model's chart (1/cos of Euler angles), not one of the solve."""
    e = sympy.sympify(e)
    n, d = sympy.fraction(sympy.together(e))
    if d.is_number or sympy.count_ops(n) + sympy.count_ops(d) > ops:
        return e
    n, d = _trig_normal(n), _trig_normal(d)
    if d.is_number:
        return sympy.expand(n / d) if d != 0 else e
    return sympy.cancel(n / d)


def _w_quaternion(a, b):
    """The angular velocity of ``a`` in ``b`` when ``a`` is oriented from ``b`` by a quaternion
    (``orient_quaternion``: direction cosines homogeneous quadratic in four coordinates), in the
    compact form sympy gives it, 2 E(e) e' (bilinear), else None. It equals vee(C' C^T) where
    |e| = 1, the only place a quaternion's orientation is a rotation (the unit norm is among the
    constraints, ``_unit_norm_groups``); vee(C' C^T) itself is cubic in e and makes L about ten
    times larger (a ball's L: ~2500 operations instead of ~300)."""
    from itertools import permutations
    from sympy.physics.mechanics import find_dynamicsymbols
    C = a.dcm(b)
    dyn = sorted(find_dynamicsymbols(C), key=str)
    if len(dyn) != 4:
        return None
    try:
        if any(not c.is_polynomial(*dyn) or sympy.Poly(c, *dyn).total_degree() != 2 for c in C if c != 0):
            return None
    except sympy.polys.polyerrors.PolynomialError:
        return None
    for order in permutations(dyn):
        tmp = sympy.physics.vector.ReferenceFrame("_quaternion")
        tmp.orient_quaternion(b, list(order))
        if all(sympy.expand(x) == 0 for x in tmp.dcm(b) - C):
            comps = tmp.ang_vel_in(b).to_matrix(tmp)
            return sympy.physics.vector.Vector([(comps, a)])
    return None


def _w_from_dcm(a, b):
    """The angular velocity of frame ``a`` in its parent ``b`` from the time derivative of their
    direction cosine matrix (the skew matrix C' C^T), reduced by ``_trig_normal``: what sympy's
    ``_w_diff_dcm`` computes, without its recursive trigsimp."""
    t = sympy.physics.vector.dynamicsymbols._t
    C = b.dcm(a)
    W = C.diff(t) * C.T
    w = [_trig_normal(W[7]), _trig_normal(W[2]), _trig_normal(W[3])]
    return sympy.physics.vector.Vector([(sympy.Matrix(w), b)])


def _components(vec, frame):
    """Components of a vector in ``frame``, the small ones reduced by ``_trig_normal``."""
    if vec == 0:
        return sympy.zeros(3, 1)
    return sympy.Matrix([_trig_normal(c) if sympy.count_ops(c) <= _TRIGSIMP_OPS else c
                         for c in vec.to_matrix(frame)])


def _oriented(F, N) -> bool:
    """F has direction cosines relative to N (a chain of orientations)."""
    if F is N:
        return True
    try:
        F._dict_list(N, 0)
    except ValueError:
        return False
    return True


def _spin_frame(body, m: _Model, num):
    """The frame in which to take the angular velocity and inertia of a body whose own frame B has
    no orientation (sympy's wheels, given only an angular velocity): a frame F with one, relative to
    which B spins as w_B/F = s e, s a speed that no kinematic equation ties (its added angle is the
    spin angle), e constant in F, and the central inertia given in F and symmetric about e. Then
    the kinetic energy is that of the rotated body whatever the spin angle, which is why nothing
    depends on the added angle. Anything else is refused: B needs an orientation."""
    import sympy.physics.mechanics as me
    B, N = body.frame, m.frame
    why = "its angular velocity relative to an oriented frame is not a spin u*e about a fixed axis"
    for F, w in B._ang_vel_dict.items():
        if F is B or not _oriented(F, N):
            continue
        comps = w.to_matrix(F)
        dyn = me.find_dynamicsymbols(comps)
        if len(dyn) != 1 or next(iter(dyn)) not in set(m.free):
            why = (f"its angular velocity relative to {_name(F)} is not one speed that no kinematic equation "
                   "ties to a coordinate")
            continue
        s = next(iter(dyn))
        e = comps.diff(s)
        if me.find_dynamicsymbols(e) or any(not _is_zero(c, num) for c in comps - e * s):
            why = f"its spin {s} relative to {_name(F)} is not about a fixed axis"
            continue
        try:
            Ic = body.central_inertia.to_matrix(F)
        except ValueError:
            why = f"its inertia is not given in a frame oriented relative to {_name(F)}"
            continue
        n2 = (e.T * e)[0, 0]
        lam = (e.T * Ic * e)[0, 0] / n2
        mu = (Ic.trace() - lam) / 2
        D = Ic - lam * e * e.T / n2 - mu * (sympy.eye(3) - e * e.T / n2)
        if all(_is_zero(d, num) for d in D):
            return F
        why = f"its inertia is not symmetric about its spin axis (the rate {s}) in {_name(F)}"
    raise SystemDefinitionError(f"{m.kind}: body {_name(body)}: its frame {_name(B)} has no orientation and {why}; "
                                f"orient {_name(B)} (e.g. orient_axis) and give its angle a kinematic equation")


def _check_symmetric(body, Ic, F, m: _Model, num):
    """An inertia dyadic is symmetric (I_ij = I_ji); sympy stores whatever dyadic it is given, and
    T = w . I . w / 2 would silently use its symmetric part only. Refused, naming the body."""
    bad = [(i, j) for i in range(3) for j in range(i + 1, 3) if not _is_zero(Ic[i, j] - Ic[j, i], num)]
    if bad:
        i, j = bad[0]
        ax = "xyz"
        raise SystemDefinitionError(
            f"{m.kind}: body {_name(body)}: its central inertia dyadic is not symmetric (in {_name(F)}: "
            f"I_{ax[i]}{ax[j]} = {str(Ic[i, j])[:60]} but I_{ax[j]}{ax[i]} = {str(Ic[j, i])[:60]}); an inertia "
            "dyadic must be symmetric: build it with inertia(frame, ixx, iyy, izz, ixy, iyz, izx)")


def _kinetic_minus_potential(m: _Model, kin: _Kin, num):
    """T - V of the bodies (V: their ``potential_energy``)."""
    import sympy.physics.mechanics as me
    T = sympy.S.Zero
    V = sympy.S.Zero
    for body in m.bodies:
        # components simplified one by one (cheap) before they are multiplied out: the derivation
        # of (1) differentiates L twice, and its cost grows with the size of L
        if isinstance(body, me.RigidBody):
            F = body.frame if _oriented(body.frame, m.frame) else _spin_frame(body, m, num)
            # |v|^2 in the body's frame: the positions that locate it are written in frames near it
            v = _components(kin.point_velocity(body.masscenter), F)
            w = _components(kin.angular_velocity(body.frame), F)
            Ic = body.central_inertia.to_matrix(F)
            _check_symmetric(body, Ic, F, m, num)
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


def _unit_norm_groups(ks, qsym, vsym):
    """The groups S of coordinates with a row of k equal to c q_S . v_S (c != 0 a constant): the
    velocity form of |q_S|^2 = const, which for a quaternion's orientation means |q_S| = 1."""
    groups = []
    vz = dict.fromkeys(vsym, 0)
    for k in ks:
        # a norm row is a small polynomial: rows with functions (sin, cos) or large ones are not
        # expanded (the build of a large model must not pay for it)
        if k.atoms(sympy.Function) or sympy.count_ops(k) > 200:
            continue
        k = sympy.expand(k)
        if k.xreplace(vz) != 0:
            continue
        a = [k.coeff(v) for v in vsym]
        S = [i for i, c in enumerate(a) if c != 0]
        if len(S) < 2 or any(v in c.free_symbols for c in a for v in vsym):
            continue
        c0 = sympy.cancel(a[S[0]] / qsym[S[0]])
        if c0.free_symbols & set(qsym) or c0 == 0:
            continue
        if all(sympy.expand(a[i] - c0 * qsym[i]) == 0 for i in S):
            groups.append(S)
    return groups


class _Numeric:
    """Random points (t, q, v, parameters) on the constraint manifold, for checks that
    simplification does not decide."""

    def __init__(self, qsym, vsym, tsym, ks, seed=20260):
        self.q, self.v, self.t, self.ks = qsym, vsym, tsym, list(ks)
        # coordinates whose velocity constraint is q_S . q_S' = 0 (a quaternion's unit norm in
        # velocity form): the points lie on |q_S| = 1, where the model's orientation is a rotation
        self.spheres = _unit_norm_groups(self.ks, qsym, vsym)
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
                for grp in self.spheres:
                    nrm = float(np.sqrt(sum(sub[self.q[i]] ** 2 for i in grp)))
                    sub.update({self.q[i]: sub[self.q[i]] / nrm for i in grp})
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
    """(V, None) for a load with a potential (plain symbols), else (None, Q): its generalized
    force Q(t, q, v), which enters (1) beside the constraint forces as in the Lagrange-d'Alembert
    principle; SystemDefinitionError for a load that cannot be read at all."""
    import sympy.physics.mechanics as me
    t = me.dynamicsymbols._t
    loc, vec = _load_parts(load, m.kind)
    what = f"loads[{i}] ({'force on point' if isinstance(loc, me.Point) else 'torque on frame'} {_name(loc)})"
    if m.frame is None:
        raise SystemDefinitionError(f"{m.kind}: {what}: no inertial frame to form its generalized force")
    if vec == 0:
        return sympy.S.Zero, None
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
    if any(x in set(vsym) for e in Qs for x in e.free_symbols):
        return None, Qs             # depends on the velocities: no potential
    V = None
    if isinstance(loc, me.Point):
        O, r = kin.position(loc)
        comps = vec.to_matrix(m.frame)
        if O is not None and O is not loc and not any(c.has(t) or c.atoms(sympy.core.function.AppliedUndef)
                                                      for c in comps):
            V = conv([-vec.dot(r)], what)[0][0]
    if V is not None and all(_is_zero(-V.diff(x) - e, num) for x, e in zip(qsym, Qs)):
        # a constant force on a located point: Q = -grad(-F . r) holds, so Q is curl free
        return V, None
    V = None
    n = len(qsym)
    for a in range(n):
        for b in range(a + 1, n):
            d = Qs[a].diff(qsym[b]) - Qs[b].diff(qsym[a])
            if not _is_zero(d, num):
                return None, Qs     # not curl free: no potential
    if V is None:
        from .bounded import TIMED_OUT, call_bounded
        V = sympy.S.Zero
        for j, x in enumerate(qsym):
            rest = -Qs[j] - V.diff(x)
            if _is_zero(rest, num):
                continue
            # a curl-free force whose potential is not found here (too large to simplify, an
            # integral sympy does not do) is as exact as a generalized force: only L differs
            if sympy.count_ops(rest) > _SIMPLIFY_OPS:
                return None, Qs
            # each symbolic step time-bounded (bounded.call_bounded): past it, the force route
            rest = call_bounded(sympy.simplify, rest)
            if rest is TIMED_OUT or rest.free_symbols & set(qsym[:j]):
                return None, Qs
            part = call_bounded(sympy.integrate, rest, x)
            if part is TIMED_OUT or part.has(sympy.Integral):
                return None, Qs
            V = V + part
    grad = [-V.diff(x) - e for x, e in zip(qsym, Qs)]
    if not all(_is_zero(g, num) for g in grad):
        return None, Qs
    return V, None


def _breadth_first(start, step):
    seen, order, todo = set(), [], list(start)
    while todo:
        x = todo.pop(0)
        if x is None or id(x) in seen:
            continue
        seen.add(id(x))
        order.append(x)
        todo.extend(step(x))
    return order


def _model_points(m: _Model):
    """The points of the bodies and loads and every point their positions are given from."""
    import sympy.physics.mechanics as me
    start = [b.masscenter if isinstance(b, me.RigidBody) else getattr(b, "point", None) for b in m.bodies]
    for load in m.loads:
        loc = load[0] if isinstance(load, (tuple, list)) and len(load) == 2 else None
        start.append(loc if isinstance(loc, me.Point) else None)
    return _breadth_first(start, lambda x: list(x._pos_dict.keys()))


def _model_frames(m: _Model):
    """The bodies' frames first, then every frame their orientations or angular velocities link."""
    import sympy.physics.mechanics as me
    start = [b.frame for b in m.bodies if isinstance(b, me.RigidBody)] + [m.frame]
    return _breadth_first(start, lambda F: list(F._dcm_dict.keys()) + list(F._ang_vel_dict.keys()))


def _root_contacts(m: _Model, kin: _Kin, conv, num):
    """Rolling contacts set "the Kane way", made part of an unconstrained model.

    A point Z given zero velocity in N, located from no fixed point (the root of its positions:
    sympy's test_kane3 bicycle builds everything from the rear contact WR_cont this way), whose
    children's set velocities are not the time derivatives of their positions from Z even where
    the model's constraints hold, is a moving contact point whose zero velocity is that of the
    wheel's material point. Its velocities obey the rolling condition by construction, so L formed
    from them is the *constrained* Lagrangian, and (1) with it lacks the reduction (Chaplygin)
    terms: it is not the model's dynamics. Reconstructed instead: Z is located at new coordinates
    along the two axes of N spanning the plane in which the model moves it (the components of its
    implied velocity v_Z = v_P(set) - d/dt r_ZP that vanish identically name the normal); every
    velocity is the derivative of positions from the fixed origin then; and the rolling condition
    of the wheel B (the frame with v_P(set) = w_B x r_ZP) becomes two velocity constraints, the
    in-plane components of the material point's velocity v_P + w_B x r_PZ (its normal component is
    - v_Z . n = 0 identically). The model's own velocity constraints are kept: written with the
    Kane-way velocities, each is the true one minus a combination of the rolling rows (every Kane-
    way velocity is the true one minus the material velocity at Z), so with the rolling rows they
    span the same constraint distribution, everywhere. Returns the rows (dynamicsymbols)."""
    import sympy.physics.mechanics as me
    t = me.dynamicsymbols._t
    N = m.frame
    if N is None:
        return []
    pts = _model_points(m)
    zero = {id(P) for P in pts if P._vel_dict.get(N) is not None and P._vel_dict[N] == 0}
    axes, letters = [N.x, N.y, N.z], "xyz"
    rows = []
    for Z in [P for P in pts if id(P) in zero]:
        tree = _breadth_first([Z], lambda x: list(x._pos_dict.keys()))
        if any(x is m.fixed for x in tree) or sum(id(x) in zero for x in tree) > 1:
            continue              # located from a fixed point: the set velocities are checked as usual
        moving = None
        for P in Z._pos_dict:
            if N not in P._vel_dict:
                continue
            vz = kin._sub(P._vel_dict[N]).to_matrix(N) - P.pos_from(Z).to_matrix(N).diff(t)
            vzs = conv(list(vz), f"point {_name(Z)}")[0]
            if not all(_is_zero(c, num, on_manifold=True) for c in vzs):
                moving = (P, vzs)
                break
        if moving is None:
            continue              # a fixed point: its children's velocities are those of its positions
        P, vzs = moving
        head = (f"{m.kind}: point {_name(Z)} is given zero velocity but moves (the velocity set for {_name(P)} "
                f"is not the derivative of its position from {_name(Z)})")
        flat = [i for i, c in enumerate(vzs) if _is_zero(c, num)]
        if len(flat) != 1:
            where = "in no coordinate plane" if not flat else "on a line or not at all"
            raise SystemDefinitionError(f"{head}, and it moves {where} of {_name(N)}: its rolling plane cannot be "
                                        f"determined; locate {_name(Z)} by coordinates and give its rolling "
                                        "condition as velocity constraints")
        wheel = None
        vset = kin._sub(P._vel_dict[N])
        for B in _model_frames(m):
            if B is N:
                continue
            try:
                wB = kin._sub(B.ang_vel_in(N))
            except ValueError:
                continue
            d = conv(list((vset - wB.cross(P.pos_from(Z))).to_matrix(N)), f"point {_name(Z)}")[0]
            if all(_is_zero(c, num) for c in d):
                wheel = B
                break
        if wheel is None:
            raise SystemDefinitionError(f"{head}, and no frame B gives it as w_B x r({_name(Z)}->{_name(P)}): the "
                                        "rolling body cannot be identified; locate it by coordinates and give its "
                                        "rolling condition as velocity constraints")
        inplane = [i for i in range(3) if i != flat[0]]
        newq = []
        for i in inplane:
            nm = _fresh_name(m, f"{letters[i]}_{_name(Z)}")
            c = me.dynamicsymbols(nm)
            m.q.append(c)
            newq.append(c)
            m.added[nm] = (f"position of the rolling contact {_name(Z)} along {_name(N)}.{letters[i]} (the model "
                           f"gives it zero velocity: the material point of {_name(wheel)})")
        kin.roots[id(Z)] = {"offset": sum((c * axes[i] for c, i in zip(newq, inplane)), sympy.physics.vector.Vector(0)),
                            "material": None}
        vmat = kin.point_velocity(P) + kin.angular_velocity(wheel).cross(Z.pos_from(P))
        kin.roots[id(Z)]["material"] = vmat
        comps = _components(vmat, N)
        if not _is_zero(conv([comps[flat[0]]], f"point {_name(Z)}")[0][0], num):
            raise SystemDefinitionError(f"{head}, and the velocity of {_name(wheel)}'s material point there has a "
                                        f"component along {_name(N)}.{letters[flat[0]]}: not a rolling contact on "
                                        "a plane")
        for i in inplane:
            rows.append(comps[i])
            m.added_rows.append(f"rolling of {_name(wheel)} at {_name(Z)}: the {_name(N)}.{letters[i]} velocity of "
                                "its material point is 0")
    return rows


def _regularize_unit_norm(L, qsym, vsym, num, m: _Model):
    """L + mu (q_S . v_S)^2 / 2 for each unit-norm group S (a quaternion, ``_unit_norm_groups``)
    along whose direction q_S L_vv vanishes, mu = trace(L_vv on S) / (|S| - 1).

    An orientation depends on q_S / |q_S| only, so its kinetic energy does not see the velocity
    q_S: L_vv q_S = 0, and although the saddle matrix (4) is regular (k's row q_S . v_S covers that
    direction) the SPARK stage equations P_i = grad_v L(Q_i, V_i) of (21) leave the component of
    V_i along q_S to the s - 1 averaged constraints: gauss-2 stops converging, gauss-3 and
    lobatto-iiia-iiib-3 lose two orders on a ball in quaternions. The added term, c k^2 / 2 with k
    the constraint row, changes no solution of (1): its Euler-Lagrange terms mu k' grad_v k + k (...)
    vanish where k = 0 holds for all t; it makes L_vv regular with the eigenvalue mu along q_S
    (the mean of the others: the scale of the body's inertia)."""
    for grp in num.spheres:
        qs, vs = [qsym[i] for i in grp], [vsym[i] for i in grp]
        grad = [L.diff(v) for v in vs]
        along = [sum(g.diff(v) * x for x, v in zip(qs, vs)) for g in grad]
        if not all(_is_zero(a, num, on_manifold=False) for a in along):
            continue               # L_vv already regular along q_S: nothing to add
        mu = sum(g.diff(v) for g, v in zip(grad, vs)) / (len(grp) - 1)
        if _is_zero(mu, num, on_manifold=False):
            continue
        k = sum(x * v for x, v in zip(qs, vs))
        L = L + mu * k ** 2 / 2
        dot = " + ".join(f"{x.name}*{v.name}" for x, v in zip(qs, vs))
        m.added_terms.append(f"mu ({dot})^2 / 2 with mu = trace of L_vv over {', '.join(v.name for v in vs)} / "
                             f"{len(grp) - 1}: makes L_vv regular along the unit-norm direction (zero on k = 0)")
    return L


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

    cache = {}

    def conv(exprs, what):
        # m.q as it is at the call: rolling contacts add coordinates on the way
        try:
            ex, qsym, vsym = _to_symbols(exprs, m.q, t, cache)
        except SystemDefinitionError as exc:
            raise SystemDefinitionError(f"{m.kind}: {what}: {exc}") from None
        return [e.subs(t, tsym) for e in ex], qsym, vsym

    def tidy(ks):
        # the Kane form stores the constraints with q' -> u(q, q') of its own solve: mapped back they
        # carry removable 0/0 (1/sin, 1/cos of the inverted kinematics), which cancel out here
        return [sympy.simplify(sympy.cancel(e))
                if not e.as_numer_denom()[1].is_number and sympy.count_ops(e) <= 4 * _SIMPLIFY_OPS else e
                for e in ks]

    ks, qsym, vsym = conv(cons, "velocity constraints")
    if m.tidy:
        ks = tidy(ks)
    rolling = _root_contacts(m, kin, conv, _Numeric(qsym, vsym, tsym, ks))
    if rolling:
        extra, qsym, vsym = conv(rolling, "rolling constraints")
        ks = ks + extra
    num = _Numeric(qsym, vsym, tsym, ks)
    L = m.L if m.L is not None else _kinetic_minus_potential(m, kin, num)
    Ls = conv([L], "the Lagrangian")[0][0]
    forces, named = [sympy.S.Zero] * len(qsym), []
    for i, load in enumerate(m.loads):
        loc = load[0] if isinstance(load, (tuple, list)) and len(load) == 2 else None
        if loc is not None and id(loc) in kin.roots:
            # applied at a rolling contact's material point: its generalized force is a combination
            # of the rolling rows' gradients, so it does no work on any motion (1) admits
            continue
        V, Q = _potential(i, load, m, kin, m.q, conv, num)
        if Q is None:
            Ls = Ls - V
        else:
            forces = [f + e for f, e in zip(forces, Q)]
            named.append(f"loads[{i}] ({'force on point' if isinstance(loc, me.Point) else 'torque on frame'} "
                         f"{_name(loc)})")
    m.forces, m.force_loads = (forces if named else None), named
    Ls = _regularize_unit_norm(Ls, qsym, vsym, num, m)
    # the velocities set in the model must be the derived ones where the constraints hold
    for what, derived, given in kin.checks:
        diff = list((derived - given).to_matrix(m.frame))
        dsym = conv(diff, what)[0]
        if not all(_is_zero(d, num, on_manifold=True) for d in dsym):
            raise SystemDefinitionError(
                f"{m.kind}: the velocity set for {what} differs from the time derivative of its position / "
                "orientation even where the constraints hold; give velocities consistent with the kinematics "
                "(a point given zero velocity that moves, such as a rolling contact located by coordinates, needs "
                "its true velocity and the rolling condition among the velocity constraints)")
    # configuration constraints: (1) keeps them through their time derivatives, which (as sympy
    # requires of a KanesMethod's dependent speeds) must be among the velocity constraints
    for i, c in enumerate(m.config):
        dc = conv([sympy.sympify(c).diff(t).xreplace(m.u_map) if m.u_map else sympy.sympify(c).diff(t)],
                  f"configuration constraint {i}")[0][0]
        if not _is_zero(dc, num, on_manifold=True):
            raise SystemDefinitionError(f"{m.kind}: the time derivative of configuration constraint {i} does not "
                                        "vanish where the velocity constraints hold: add it to the velocity "
                                        "constraints (with a dependent speed)")
    return Ls, ks, qsym, vsym, tsym


def _final_names(exprs, forces, qsym, vsym, tsym, added):
    """The system's symbols for the coordinates' dummies: q_i keeps its name, its velocity is
    v_<name>, made fresh (trailing underscores) when that name is taken by a symbol of the model, a
    coordinate or another velocity: a model constant named v_x stays a constant, never the velocity
    of x. A coordinate of the user's that shares its name with a symbol of the model is refused
    (both would be one symbol); one the adapter added (``added``) is renamed instead."""
    dummies = set(qsym) | set(vsym)
    own = {str(x) for e in list(exprs) + list(forces or []) for x in sympy.sympify(e).free_symbols
           if x not in dummies}
    own.add(str(tsym))
    taken, rename, new_added = set(own), {}, {}
    for x in qsym:
        nm = x.name
        if nm in taken:
            if nm not in added:
                what = "the time t" if nm == str(tsym) else f"a symbol {nm} of the model"
                raise SystemDefinitionError(f"from_mechanics: the coordinate {nm}(t) has the name of {what}; "
                                            "rename one of them (both would become one symbol)")
            while nm in taken:
                nm += "_"
        taken.add(nm)
        rename[x] = sympy.Symbol(nm)
        if x.name in added:
            new_added[nm] = added[x.name]
    for x in vsym:
        nm = x.name
        while nm in taken:
            nm += "_"
        taken.add(nm)
        rename[x] = sympy.Symbol(nm)
    exprs = [sympy.sympify(e).xreplace(rename) for e in exprs]
    forces = [sympy.sympify(e).xreplace(rename) for e in forces] if forces is not None else None
    return exprs, forces, [rename[x] for x in qsym], [rename[x] for x in vsym], new_added


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
        mdl = None
        try:
            mdl = reader(model)
            Ls, ks, qsym, vsym, tsym = _convert_model(mdl, name)
            forces = mdl.forces
        except SystemDefinitionError:
            raise
        except (sympy.SympifyError, sympy.polys.polyerrors.PolynomialError, TypeError, ValueError, KeyError,
                AttributeError, NotImplementedError, ZeroDivisionError) as exc:
            msg = str(exc).splitlines()[0][:160] if str(exc) else type(exc).__name__
            raise SystemDefinitionError(f"{type(model).__name__}: cannot map the model to (1): {msg}") from None
        exprs = [Ls] + ks
    else:
        forces = None
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
        exprs, qsym, vsym = _to_symbols([L] + cons, qs, t, {})
        tsym = sympy.Symbol("t")
        exprs = [e.subs(t, tsym) for e in exprs]
    added = dict(mdl.added) if reader is not None else {}
    exprs, forces, qsym, vsym, added = _final_names(exprs, forces, qsym, vsym, tsym, added)
    Ls, ks = exprs[0], exprs[1:]
    if params is None:
        found = set().union(*(e.free_symbols for e in exprs + list(forces or []))) - set(qsym) - set(vsym) - {tsym}
        params = sorted(found, key=str) or None
    # loads without a potential: their generalized forces F(t, q, v) enter (1b) as the nonideal
    # term does, d/dt grad_v L = grad_q L - K^T psi + F, on every engine
    system = cls(Ls, ks, qsym, vsym, t=tsym, name=name, params=params, nonideal=forces)
    system.force_loads = list(mdl.force_loads) if reader is not None else []
    # what the adapter added to the model (empty when nothing): coordinate name -> why, and the
    # constraint rows appended after the model's own
    system.added_coordinates = added
    system.added_constraints = list(mdl.added_rows) if reader is not None else []
    system.added_terms = list(mdl.added_terms) if reader is not None else []
    if getattr(system, "lvv_problem", None):
        # a model read from sympy.physics.mechanics: refused at once (the usual cause, kinematics
        # with the rolling condition built in, is a modelling choice the user can change)
        raise SystemDefinitionError(system.lvv_problem)
    return system
