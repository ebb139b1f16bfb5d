"""The generic engine: the SPARK step (21a-f) of ``ldaspark.core.spark.SparkMethod`` in float64, or
in mpmath at ``dps`` digits, one step at a time (``Engine.mode = "steps"``; ``core.spark.march``:
the same predictor and checks as ``core.spark.integrate``, so the same numbers).

Also the safe root of the step-acceptance guard for every SPARK method (``SparkSafeRoot``): a
flagged step solved again by the generic full Newton from the previous step's collocation
polynomial, then from the explicit Euler predictor, then by the default variant
(``ldaspark.core.guard.safe_root``); the compiled engine uses it too.
"""
from __future__ import annotations

import math

import numpy as np

from ..core.errors import InputError, LdasparkError
from ..core.result import float_array
from .base import Engine, Prepared, Step


class SparkSafeRoot:
    """``resolve(n, state, prev, before)`` of ``Engine.resolve_step`` for a SPARK tableau: the
    guard's safe starts (``ldaspark.core.guard.safe_root``) with generic full / default Newton at
    ``dps`` digits; the method objects are built at the first flagged step."""

    def __init__(self, system, tableau, dps, tol, max_iter, h):
        self.args = (system, tableau, dps, tol, max_iter)
        self.h = h
        self.methods = None

    def _methods(self):
        if self.methods is None:
            from ..core.spark import SparkMethod
            system, tableau, dps, tol, max_iter = self.args
            mk = lambda kind: SparkMethod(system, tableau, dps=dps, tol=tol, newton=kind,  # noqa: E731
                                          max_iter=max_iter)
            self.methods = (mk("full"), mk("auto"))
        return self.methods

    def __call__(self, n, state, prev=None, before=None):
        from ..core import guard
        methods = self._methods()
        t, q, v = state
        if prev is None and before is not None and n >= 1:
            # a block engine keeps no stages: the previous step again, generic, from its start
            try:
                r = methods[0].step(before[0], before[1], before[2], self.h, step_index=n - 1)
                prev = (r.V, r.Psi, self.h)
            except LdasparkError:
                prev = None
        label, r = guard.safe_root(methods, t, q, v, self.h, prev, step_index=int(n))
        return (None, None) if r is None else (label, (r.q1, r.v1, float(r.energy)))


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

    def resolve_step(self, prepared, n, state, prev=None, before=None):
        hit = prepared.data.get("safe")
        if hit is None:
            o = prepared.opts
            hit = prepared.data["safe"] = SparkSafeRoot(prepared.system, prepared.prob.what, o.dps, o.tol,
                                                        prepared.root.iterations, prepared.data["h"])
        return hit(n, state, prev, before)
