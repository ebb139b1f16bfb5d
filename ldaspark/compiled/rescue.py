"""The last link of the compiled engine's Newton fallback chain: a step where the
kernel's simplified, fresh-matrix and full Newton all fail is taken by the generic engine's full
Newton (``SparkMethod.step`` with newton="full", float64) from the same state, and the compiled
run goes on from the step after. So the compiled engine fails only where the generic full Newton
fails too, and then with the generic step's NewtonError (step, time, residual, iterations). A
kernel's NaN or inf (its Newton iterates outside the domain of L or k, or a non-finite end point:
``NonFiniteError``) is taken the same way: the generic step there says what the generic engine
says (a NewtonError "evaluating L or k", a NonFiniteError), or converges.

Why a generic step and not only the kernel's own full Newton: near the Newton limit (h of order
the period of the fastest motion) full Newton wanders for tens of iterations before it is caught
by a root, and which root, or whether one within max_iter, depends on the rounding of every
iterate; the kernel's increments (Z_i = V_i - v0) round differently from the generic unknowns
(V_i), so the two can part there (measured: robot lobatto-iiia-iiib-3 h = 4, mp-particles gauss-2
h = 32, step 0). Steps that converge in the kernel are not touched.

The kernel reports only the failing step; the state there is recomputed by running the kernel
again from the last restart point (the same arithmetic, so the same state). Counters
(``core.result``): the failed kernel run's (its accepted steps and the whole chain at the
failing step, carried by its error) plus the generic steps' (their failed attempts included);
the recomputed prefix repeats counted work and is not counted again. A generic step that fails
raises with the run's counters attached (``core.result.attach_counters``). Each restart begins
with the zero-increment predictor and a fresh Kahan compensation. Samples stay at the global
steps 0, every, 2 every, ... and the last step.
"""
from __future__ import annotations

import numpy as np

from ..core.errors import NewtonError, NonFiniteError


def _local_indices(n, every):
    """The local step indices of run_compiled's samples for n steps sampled every ``every``."""
    idx = list(range(0, n + 1, every))
    if idx[-1] != n:
        idx.append(n)
    return idx


def run_with_rescue(system, tab, cs, method, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter,
                    kernel, predictor, first_failure, kopts=None):
    """Finish the run that failed with ``first_failure`` (the kernel's NewtonError or
    NonFiniteError, local step from t0) by generic full-Newton steps at the failing steps; returns a FastSolution with the
    kernel's statistics summed, the generic steps' iterations, nfev, njev and nlu added, and
    stats["generic_steps"] = the number of steps taken by the generic engine. Raises the generic step's NewtonError (or NonFiniteError) where that fails too. ``kopts``
    (``runner.KernelOptions``): the kernel runs' options as given (the root finder's kind, linear
    solver and matrix reuse among them); None: those of the other arguments."""
    from ..core.backend import Backend
    from ..core.result import FAILURE_COUNTERS, attach_counters, failure_counters
    from ..core.spark import SparkMethod
    from .runner import FastSolution, _run_checked, run_kernels

    want = set(range(0, n_steps + 1, every)) | {n_steps}
    samples = {}                # global step -> (t, q, v, E, k)
    psis = {}                   # global step at a sample -> Psi (s, m) of the step starting there
    totals = dict.fromkeys(("steps", "newton_iterations", "nfev", "njev", "nlu", "max_iterations",
                            "full_newton_steps"), 0)
    rescues = 0
    generic = SparkMethod(system, tab, tol=tol, newton="full", max_iter=max_iter)
    bk = Backend(None)
    start, t, q, v = 0, float(t0), np.asarray(q0, float), np.asarray(v0, float)
    failure = first_failure
    kern = {}
    last = None                 # (step after the last generic step, its StepResult, v before it)

    def keep(sol, start, n, e, skip=()):
        kern["kernel"] = sol.stats["kernel"]
        for j, loc in enumerate(_local_indices(n, e)):
            if start + loc in want:
                samples[start + loc] = (sol.t[j], sol.q[j], sol.v[j], sol.energy[j], sol.constraint[j])
                if j < len(sol.t) - 1 and sol.psi is not None:
                    psis[start + loc] = sol.psi[j]
        add(sol.stats, skip)

    def add(stats, skip=()):
        for key, val in stats.items():
            if isinstance(val, (int, np.integer)) and not isinstance(val, bool) and key not in skip:
                totals[key] = max(totals.get(key, 0), val) if key == "max_iterations" else totals.get(key, 0) + val

    def point(t, q, v, E=None):
        E = float(system.energy(bk, t, q, v)) if E is None else E
        return t, q.copy(), v.copy(), E, np.asarray(system.constraint(bk, t, q, v), float)

    def run(n, e):
        if kopts is not None:
            return _run_checked(cs, method, (t, q, v), (h, n, e), kopts)
        return run_kernels(cs, method, t, q, v, h, n, e, compensated, tol, max_iter, kernel, predictor)

    while start < n_steps:
        left = n_steps - start
        # keep the samples on the global grid: a restart off the grid first runs to the next multiple
        n = left if start % every == 0 else min(left, every - start % every)
        e = every if start % every == 0 else n
        if failure is None:
            try:
                sol = run(n, e)
            except (NewtonError, NonFiniteError) as exc:
                failure = exc
            else:
                keep(sol, start, n, e)
                t, q, v = float(sol.t[-1]), sol.q[-1].copy(), sol.v[-1].copy()
                start += n
                continue
        k = failure.step            # local to this segment
        failed = failure_counters(failure)
        failure = None
        if failed is not None:      # the failed kernel run: its accepted steps and the failing step's chain
            add(failed)
        if k:
            pre = run(k, e if k >= e else k)
            # a recomputed prefix: its steps and work are in the failed run's counters
            keep(pre, start, k, e if k >= e else k, skip=FAILURE_COUNTERS if failed is not None else ())
            t, q, v = float(pre.t[-1]), pre.q[-1].copy(), pre.v[-1].copy()
            start += k
        if start in want and start not in samples:      # a failure at a segment's first step
            samples[start] = point(t, q, v)
        # the generic engine's full Newton at this state (``_generic_step``), its work counted
        # whether it converges or not
        before = generic.stats.as_dict()
        try:
            res = _generic_step(generic, last, start, t, q, v, h)
        except (NewtonError, NonFiniteError) as exc:
            add(_spent(generic, before))
            raise attach_counters(exc, {c: totals.get(c, 0) for c in FAILURE_COUNTERS})
        add(_spent(generic, before))
        last = (start + 1, res, v.copy())
        if start in want:
            psis[start] = np.asarray(res.Psi, float)
        rescues += 1
        start += 1
        t, q, v = float(t0) + start * h, np.asarray(res.q1, float), np.asarray(res.v1, float)
        if start in want:
            samples[start] = point(t, q, v, float(res.energy))
    order = sorted(samples)
    st = dict(totals)
    st["generic_steps"] = rescues
    st["mean_iterations"] = st.get("newton_iterations", 0) / max(st.get("steps", 0), 1)
    st.update(path="fast", kernel=kern.get("kernel", "spark" if cs.form == "mechanical" else "general"),
              form=cs.form, compensated=bool(compensated))
    return FastSolution(np.array([samples[i][0] for i in order]), np.array([samples[i][1] for i in order]),
                        np.array([samples[i][2] for i in order]), np.array([samples[i][3] for i in order]),
                        np.array([samples[i][4] for i in order]),
                        psi=np.array([psis[i] for i in order[:-1]]).reshape(len(order) - 1, tab.s, cs.m)
                        if all(i in psis for i in order[:-1]) else None, stats=st)


def _spent(generic, before) -> dict:
    """The work of the generic method since its stats were ``before`` (``FAILURE_COUNTERS``)."""
    from ..core.result import FAILURE_COUNTERS
    now = generic.stats.as_dict()
    return {c: now[c] - before[c] for c in FAILURE_COUNTERS}


def _generic_step(generic, last, start, t, q, v, h):
    """The generic engine's full-Newton step ``start`` from (t, q, v): from its own predictor when
    the step before was generic too (``last`` = (step after it, its StepResult, v before it), as
    ``march``), else (or if that fails) from its default guess; its error if both fail."""
    if last is not None and last[0] == start:
        Vp, Lp, v1p = generic.unpack(last[1].x)
        dv = v - last[2]
        try:
            return generic.step(t, q, v, h, x0=generic.pack(Vp + dv, Lp, v1p + dv), step_index=start)
        except NewtonError:
            pass
    return generic.step(t, q, v, h, step_index=start)
