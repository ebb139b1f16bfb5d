"""The ``Scene`` type: a system (1) with initial data, an optional closed-form solution and its
parameters. Apart from the scene library (``scenes``) so that the model modules that build scenes
(``systems_classic``, ``bicycle``) and the registry that lists them import it from below.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import mpmath
import numpy as np
import sympy

from ..core.errors import InputError
from ..core.system import LagrangianSystem


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
