"""Fake systems and scenes with a known exact solution, shared by the rule tests of the compiled
path and the peers report."""
from __future__ import annotations

import numpy as np


class _Osc:
    """q'' = -q with one (dummy) multiplier: n = 1, m = 1; E = (q^2 + v^2) / 2, k = v - 1."""
    name = "rep1-osc"
    n, m = 1, 1

    @staticmethod
    def energy(bk, t, q, v):
        return 0.5 * (float(q[0]) ** 2 + float(v[0]) ** 2)

    @staticmethod
    def constraint(bk, t, q, v):
        return float(v[0]) - 1.0


class _Scene:
    def __init__(self, system=None, t0=0.0, exact=None):
        self.system = system or _Osc()
        self.t0 = t0
        self.exact = exact
        self.name = "rep1"

    def initial(self):
        return self.t0, [1], [0]

    def exact_solution(self, t):
        return [np.cos(t)], [-np.sin(t)], None
