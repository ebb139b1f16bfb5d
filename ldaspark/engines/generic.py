"""The generic engine: the SPARK step (21a-f) of ``ldaspark.core.spark.SparkMethod`` in float64, or
in mpmath at ``dps`` digits, one step at a time (``Engine.mode = "steps"``; ``core.spark.march``:
the same predictor and checks as ``core.spark.integrate``, so the same numbers).

The safe root of the step-acceptance guard for every SPARK method is
``ldaspark.core.guard.SparkSafeRoot`` (the compiled engine and ``run_many`` use it too).
"""
from __future__ import annotations

import math

import numpy as np

from ..core.errors import InputError
from ..core.result import float_array
from ..core.guard import SparkSafeRoot
from .base import Engine, Prepared, Step


class GenericEngine(Engine):
    """The generic engine (module docstring): ``prepare`` builds the ``SparkMethod`` with the root
    finder's kind and iteration limit, ``steps`` yields the steps of ``march`` with its predictor."""

    name = "generic"
    label = "generic"
    support = "generic"
    mode = "steps"

    def prepare(self, system, prob, opts) -> Prepared:
        from ..core.spark import SparkMethod
        root, support = self.root_finder(opts.newton, prob)
        # the energy monitor (energy_jump) is the driver's, as on every engine
        method = SparkMethod(system, prob.what, dps=opts.dps, tol=opts.tol, newton=root.kind,
                             max_iter=root.iterations)
        bk = method.backend
        with bk.context():
            try:
                h = bk.scalar(prob.h)
            except (TypeError, ValueError) as exc:
                raise InputError(f"h must be a number: {exc}") from None
            if not math.isfinite(float(h)) or h == 0:
                raise InputError(f"step size h must be finite and nonzero, got {prob.h}")
        if opts.dps is None:
            # float64 Python steps: bounded like the mpmath runs (``validate.check_work``), 10**9
            # steps would run for weeks
            from ..core.validate import check_work
            check_work(prob.N, None, s=prob.what.s, n=system.n, m=system.m, float_generic=True)
        c = np.asarray(float_array(prob.what.arrays(None).c))
        return Prepared(system, prob, opts, root, support, {"method": method, "h": h, "c": c})

    def backend(self, prepared, opts):
        return prepared.data["method"].backend

    def steps(self, prepared, start, n_steps):
        from ..core.spark import march
        t0, q, v = start
        h = prepared.data["h"]
        for i, ti, qi, r in march(prepared.data["method"], t0, q, v, h, n_steps, predictor=prepared.root.predictor):
            yield Step(i, ti, qi, v, r.q1, r.v1, r.V, r.Psi, r.energy, r.iterations)
            v = r.v1

    def nodes(self, prepared):
        return prepared.data["c"]

    def stats(self, prepared) -> dict:
        return prepared.data["method"].stats.as_dict()

    def safe_root(self, prepared):
        o = prepared.opts
        return SparkSafeRoot(prepared.system, prepared.prob.what, o.dps, o.tol, prepared.root.iterations,
                             prepared.data["h"])
