"""The comparator engine: the methods of sections 7-8 that are not SPARK methods (standard Gauss
IRK, the modified Lobatto method of 8.4, the compositions of 7.5, the leapfrog forms of (25) and
McLachlan-Perlmutter's (26); ``ldaspark.core.comparators``), in float64 or mpmath.

A block engine that returns every step (``samples = False``): the driver slices ``save_every``,
builds Hermite dense output and locates events, as for the compiled engine's runs with dense
output. ``Result.engine`` says "generic" for these runs (as before the protocol).
"""
from __future__ import annotations

import numpy as np

from ..core.result import Result
from .base import Engine, Prepared
# the guard's safe root of a comparator lives beside the comparators (``run_many`` judges with it too)
from ..core.comparators import ComparatorSafeRoot

from ..core.result import MSG_DONE


class ComparatorEngine(Engine):
    """The comparator engine (module docstring)."""

    name = "comparator"
    label = "generic"
    support = "comparator"
    mode = "block"
    samples = False

    def prepare(self, system, prob, opts) -> Prepared:
        root, support = self.root_finder(opts.newton, prob)
        # the comparators evaluate the system's expressions with the parameter values substituted
        return Prepared(system.substituted(), prob, opts, root, support)

    def check_block(self, prepared, n_steps, every):
        from ..core import validate
        s = prepared.system
        validate.check_storage(n_steps + 1, 2 + 2 * s.n + s.m, mp=prepared.opts.dps is not None,
                               what="the comparator's steps")

    def run(self, prepared, start, n_steps, every) -> Result:
        from ..core.comparators import integrate_comparator
        (t0, q0, v0), o, root = start, prepared.opts, prepared.root
        sol = integrate_comparator(prepared.prob.name, prepared.system, t0, q0, v0, prepared.prob.h, int(n_steps),
                                   dps=o.dps, tol=o.tol, max_stages=o.max_stages, max_iter=root.iterations)
        st = dict(sol.stats, path="generic", engine="comparator", root_finder=root.describe())
        psi = np.asarray(sol.psi)
        return Result(sol.t, sol.q, sol.v, sol.energy, sol.constraint, psi if psi.ndim == 3 else None, 0,
                      MSG_DONE, *(st.get(c, 0) for c in ("nfev", "njev", "nlu", "newton_iterations")),
                      engine="generic", stats=st)

    def safe_root(self, prepared):
        return ComparatorSafeRoot(prepared.system, prepared.prob, prepared.opts)
