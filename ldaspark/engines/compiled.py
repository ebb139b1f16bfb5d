"""The compiled engine: the numba kernels of ``ldaspark.compiled`` (float64; every system: the
mechanical form, the general L(t, q, v) and k(t, q, v), nonideal terms, the block LU of the
sparse Newton matrix, the semi-implicit kernel of (25) and the comparators of Fig. 4, and the
root-finder kinds run by modules of their own, ``compiled.runner.KIND_RUNNERS``, e.g. "quasi").

A block engine (``Engine.mode = "block"``): ``run`` is one kernel call of n steps keeping every
``every``-th sample (``compiled.fast.run_engine``: the kernel, with the generic full-Newton step
where a kernel's Newton fails, ``compiled.rescue``); the driver cuts long runs into blocks of
``core.chunks.COMPILED_CHUNK`` steps. Walk: driver -> ``CompiledEngine.run`` -> ``fast.run_engine`` ->
``runner._run_checked`` -> the kernels.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from ..core.errors import InputError, LdasparkError, NewtonError, NonFiniteError
from ..core.result import MSG_DONE, Result
from ..core.tableau import SparkTableau
from .base import Engine, Prepared
from ..core.guard import SparkSafeRoot



class CompiledEngine(Engine):
    """The compiled engine (module docstring)."""

    name = "compiled"
    label = "compiled"
    path = "fast"
    support = "compiled"
    mode = "block"
    samples = True
    chunked = True

    def unavailable(self, system, prob) -> Optional[str]:
        from ..compiled import fast
        if prob.kind == "comparator" and prob.name not in fast.LF2_VARIANTS:
            return f"comparator {prob.name} has no compiled kernel"
        try:
            cs = fast.compile_system(system)
            cs.model  # noqa: B018  (build the model now so that failures fall back)
            fast._kernels()     # checks the directory numba loads the kernels from (compiled.cache)
        except (fast.NotCompilableError, fast.CacheDirectoryError) as exc:
            return str(exc)
        except Exception as exc:  # numba typing/lowering errors of generated code
            return f"{system.name}: compilation failed ({type(exc).__name__})"
        if prob.kind == "comparator" and cs.form != "mechanical":
            # decided here, not by the kernel runner's fallback to the generic path, which ran the
            # comparator without the root finder's fields (max_iter, kind) and said "compiled"
            return f"{system.name}: comparator {prob.name} needs a system in mechanical form"
        return None

    def root_finder(self, newton, prob):
        """(the root finder, its name in ``SUPPORT``): lobatto-iiia-iiib-2 runs on the
        semi-implicit kernel (25) by default ("compiled-lf2"); a root finder that kernel does not
        run (another kind, the block LU, matrix reuse) runs it on the SPARK kernel (the same
        method (21))."""
        from ..compiled.runner import kernel_spec
        if prob.kind == "comparator":
            return newton.check_for("compiled-lf2"), "compiled-lf2"
        if kernel_spec(prob.method, "auto")[0] == "lf2":
            try:
                return newton.check_for("compiled-lf2"), "compiled-lf2"
            except InputError:
                pass
        return newton.check_for("compiled"), "compiled"

    def prepare(self, system, prob, opts) -> Prepared:
        """The kernel options (``compiled.runner.KernelOptions``) of the root finder ``opts.newton``:
        every field honoured or refused here."""
        from ..compiled.runner import NEWTON_MODES, KernelOptions
        from ..core.rootfinder import PREDICTOR_CODES
        root, support = self.root_finder(opts.newton, prob)
        kernel = "spark" if support == "compiled" and prob.kind == "spark" and _is_lf2(prob.method) else "auto"
        kopts = KernelOptions(True, opts.tol, root.iterations, kernel, PREDICTOR_CODES[root.predictor], root.reuse,
                              root.linear_solver, NEWTON_MODES.get(root.kind, 0), root.kind, root.predictor)
        return Prepared(system, prob, opts, root, support, {"kopts": kopts})

    def point_model(self, prepared):
        from ..compiled import fast
        return fast.model_checks(fast._loaded(prepared.system))

    def check_block(self, prepared, n_steps, every):
        from ..compiled import runner
        k, s = prepared.data["kopts"], prepared.system
        runner._check_options(n_steps, every, k.predictor, prepared.opts.tol, k.max_iter, s.n, s.m)

    def run(self, prepared, start, n_steps, every) -> Result:
        from ..compiled import fast
        fs = fast.run_engine(prepared.system, prepared.prob.method, start, (prepared.prob.h, n_steps, every),
                             prepared.data["kopts"], fallback=False)
        st = dict(fs.stats)
        used = "compiled" if st.get("path") == "fast" else "generic"
        st.update(engine=prepared.support if used == "compiled" else "generic",
                  root_finder=dict(prepared.opts.newton.describe(), runs=st.get("newton_kind", "generic")))
        st.setdefault("rescued_steps", st.get("generic_steps", 0))
        return Result(fs.t, fs.q, fs.v, fs.energy, fs.constraint, fs.psi, 0, MSG_DONE,
                      *(st.get(c, 0) for c in ("nfev", "njev", "nlu", "newton_iterations")), engine=used, stats=st)

    def safe_root(self, prepared):
        prob, o = prepared.prob, prepared.opts
        if prob.kind == "comparator":
            from .comparator import ComparatorSafeRoot
            return ComparatorSafeRoot(prepared.system, prob, o)
        return SparkSafeRoot(prepared.system, prob.what, None, o.tol, o.newton.iterations, float(prob.h))

    def stage_solver(self, prepared):
        """SPARK tableaus: ``SparkStages`` (the kernel's one-step solve, the generic step where it
        fails); comparators: None (cubic Hermite)."""
        if prepared.prob.kind != "spark":
            return None
        return SparkStages(prepared.system, prepared.prob.what, float(prepared.prob.h), prepared.opts.tol,
                           prepared.root.iterations)

    def explain(self, prepared, exc, prefix, start):
        """The kernels report only the failing step k of a Newton failure: step k again with the
        generic step from the same state (the end of the prefix, or ``start``), whose error says why
        (singular matrix, divergence, domain error)."""
        from ..core.spark import SparkMethod
        method, h, (t0, q0, v0) = prepared.prob.method, prepared.prob.h, start
        if not isinstance(exc, NewtonError) or not isinstance(method, SparkTableau):
            return exc
        k = exc.step
        q, v = (np.asarray(q0, float), np.asarray(v0, float)) if prefix is None else (prefix.q[-1], prefix.v[-1])
        tk = float(t0) + k * float(h)
        # the generic step with the run's root finder (its kind where the generic engine has it,
        # its max_iter and tol): what engine='generic' would do there, which the message promises
        root = prepared.root
        kind = root.kind if root.kind in ("auto", "full", "simplified") else "full"
        try:
            SparkMethod(prepared.system, method, tol=prepared.opts.tol, newton=kind,
                        max_iter=root.iterations).step(tk, q, v, float(h), step_index=k)
        except NonFiniteError as gen:   # outside the domain of L or k (a NewtonError too): it says why
            return gen
        except NewtonError as gen:      # the root finder fails there on both engines: both said
            return NewtonError(f"Newton did not converge at step {k} (compiled engine, {_ran(prepared)}): {exc}; "
                               f"the generic engine's {kind} Newton step with the same root finder fails there too "
                               f"({gen})", step=k, time=tk)
        except LdasparkError as gen:    # singular, not finite, outside the domain: the generic step says why
            return gen
        return NewtonError(f"Newton did not converge at step {k} (compiled engine, {_ran(prepared)}): {exc}; "
                           f"the generic engine's {kind} Newton step with the same root finder converges there "
                           "(engine='generic')", step=k, time=tk)


def _ran(prepared) -> str:
    """The root finder the kernels ran, by name, for a failure message: the quasi-Newton iteration
    where "auto" chose it (``runner.auto_runs_quasi``) or where it was asked for, else the kernels'
    Newton."""
    from ..compiled import runner
    k = prepared.data["kopts"]
    try:
        quasi = k.newton_kind == "quasi" or (k.newton_kind == "auto" and runner.auto_runs_quasi(
            runner.compile_system(prepared.system), runner.kernel_spec(prepared.prob.method, k.kernel), k))
    except LdasparkError:
        quasi = False
    return "the quasi-Newton iteration, then the Newton chain" if quasi else f"Newton ({k.newton_kind})"


def _is_lf2(method) -> bool:
    from ..compiled.runner import kernel_spec
    return kernel_spec(method, "auto")[0] == "lf2"


class SparkStages:
    """The stage velocities V_i of one step of a compiled SPARK run, solved again from its saved
    start (t, q, v) (``Engine.stage_solver``): the SPARK kernel for one step with full Newton
    (``compiled.runner.StageSolver``; lobatto-iiia-iiib-2 too, which ran on the semi-implicit
    kernel (25) of the same method), else the generic full-Newton step (``SparkMethod.step``);
    a root is taken when its end point is the saved one (``core.guard.same_root``), so the V_i
    are the run's to the Newton tolerance. None: no such root (cubic Hermite on that step)."""

    def __init__(self, system, tableau, h, tol, max_iter):
        self.system, self.tableau, self.h, self.tol, self.max_iter = system, tableau, h, tol, max_iter
        self.c = np.asarray(tableau.arrays(None).c, dtype=float)
        self._kernel = self._generic = None

    def _solvers(self):
        if self._kernel is None:
            from ..compiled import fast, runner
            try:
                self._kernel = runner.StageSolver(fast.compile_system(self.system), self.tableau, self.tol,
                                                  self.max_iter)
            except LdasparkError:          # NotCompilableError, CacheDirectoryError: the generic step
                self._kernel = False
        return self._kernel

    def __call__(self, t, q, v, q1, v1):
        from ..core.guard import same_root
        kernel = self._solvers()
        if kernel:
            hit = kernel(t, q, v, self.h)
            if hit is not None and same_root(hit[1], hit[2], q1, v1, self.tol):
                return hit[0]
        if self._generic is None:
            from ..core.spark import SparkMethod
            self._generic = SparkMethod(self.system, self.tableau, tol=self.tol, newton="full", max_iter=self.max_iter)
        try:
            r = self._generic.step(float(t), np.asarray(q, float), np.asarray(v, float), self.h)
        except LdasparkError:
            return None
        return np.asarray(r.V, float) if same_root(r.q1, r.v1, q1, v1, self.tol) else None
