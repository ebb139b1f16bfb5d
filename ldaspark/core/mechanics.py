"""Adapter from ``sympy.physics.mechanics`` models to the system (1).

``from_mechanics(model, ...)`` accepts

* a ``LagrangesMethod(L, qs, hol_coneqs=..., nonhol_coneqs=...)``: its Lagrangian, coordinates
  and ``coneqs`` (the holonomic constraints differentiated in time, then the nonholonomic ones,
  both linear in q'(t) as (1c) k(t, q, v) = 0 requires); non-conservative forces
  (``forcelist``) are not part of (1) and are refused;
* or a Lagrangian (sympy expression in dynamicsymbols) with ``q=[q1(t), ...]`` and
  ``constraints=[...]`` (velocity constraints; holonomic ones given as their time derivative).

Each q_i(t) becomes a plain symbol named after it and q_i'(t) a symbol ``v_<name>``; the time
``dynamicsymbols._t`` becomes the system's t. Free symbols other than t are the system's
parameters (values at integrate time) unless ``params`` lists them explicitly.
"""
from __future__ import annotations

from typing import Any, Optional, Sequence

import sympy

from .errors import SystemDefinitionError


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


def from_mechanics(model: Any, q: Optional[Sequence] = None, constraints: Optional[Sequence] = None,
                   params: Optional[Sequence] = None, name: str = "system", cls: Optional[type] = None) -> Any:
    """A ``LagrangianSystem`` from a LagrangesMethod or a Lagrangian in dynamicsymbols (see the
    module docstring); ``params`` defaults to every free symbol other than t. ``cls``: the class
    to build, ``LagrangianSystem`` or a subclass (``LagrangianSystem.from_mechanics`` passes its
    own: this adapter sits below the system module and does not import it)."""
    from sympy.physics.mechanics import LagrangesMethod, dynamicsymbols
    if cls is None:
        raise SystemDefinitionError("from_mechanics: give cls (or call LagrangianSystem.from_mechanics)")
    _refuse_strings(model, q, constraints)
    t = dynamicsymbols._t
    if isinstance(model, LagrangesMethod):
        if q is not None or constraints is not None:
            raise SystemDefinitionError("give q and constraints only with a plain Lagrangian")
        if model._forcelist:
            raise SystemDefinitionError("LagrangesMethod with a forcelist: non-conservative forces are not part of (1)")
        L = model._L[0]
        qs = list(model.q)
        cons = list(model.coneqs)
    else:
        if q is None:
            raise SystemDefinitionError("give q=[q1(t), ...] with a Lagrangian in dynamicsymbols")
        L, qs, cons = sympy.sympify(model), list(q), list(constraints or [])
    if not cons:
        raise SystemDefinitionError("the model has no constraints; (1) needs 1 <= m < n velocity constraints")
    exprs, qsym, vsym = _to_symbols([L] + cons, qs, t)
    tsym = sympy.Symbol("t")
    exprs = [e.subs(t, tsym) for e in exprs]
    Ls, ks = exprs[0], exprs[1:]
    if params is None:
        found = set().union(*(e.free_symbols for e in exprs)) - set(qsym) - set(vsym) - {tsym}
        params = sorted(found, key=str) or None
    return cls(Ls, ks, qsym, vsym, t=tsym, name=name, params=params)
