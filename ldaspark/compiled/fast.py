"""Compiled float64 path (numba): the SPARK method (21) for any system L(t, q, v), k(t, q, v)
and the semi-implicit comparators for mechanical systems.

``compile_system`` prints the scene's sympy expressions into a small model module
(``codegen``: mechanical form M, U, K, b when the system has it, else the general form grad_v L,
grad_q L, k and the Jacobian blocks), written to a private cache directory (``cache``) and
compiled by numba with ``cache=True``. The kernels (``kernels``) are real source compiled once
for every system: they take the model functions as first-class function arguments.

Kernels (``kernels``): ``spark_run`` (mechanical: P_i - p0 = M Z_i exactly), ``general_run``
(general L and k: the momentum map implicit, as ``SparkMethod``) and ``lf2_run`` (the 2-stage
Lobatto IIIA-B SPARK method in its semi-implicit form (25), the modified method of 8.4 and
McLachlan-Perlmutter's (26), Newton on the m multipliers only; mechanical systems).

Newton: predictor = linear extrapolation of the previous two steps' unknowns (first step: zero
increments), simplified Newton with one LU factorisation per step reused by every iteration,
stopping when |dx|_inf, or the estimate theta/(1 - theta) |dx|_inf of the remaining error
(RADAU5's rate test), is <= tol (|x|_inf + |v0|_inf), the round-off of the stage values
V_i = v0 + Z_i (invariant under the scale of h and of the state), or when the increments
stagnate at round-off level with an exact matrix (``newton.newton_status``); tol defaults to 8
unit round-offs. Fallback chain (``kernels.spark_newton``): a fresh matrix at the iterate when
an increment does not contract by 1/2, then full Newton from the generic engine's starting guess,
then a NewtonError naming step, time, residual and iterations. Counters: steps,
newton_iterations, nfev (the residual's stage points, s + 1 per residual), njev, nlu, max_iterations, full_newton_steps
(steps that needed the full-Newton fallback).

A run that meets NaN or inf (L or k evaluated outside their domain, overflow) stops with
``NonFiniteError`` naming the step and the time; Newton failures raise ``NewtonError``.
Nonideal constraints (3.3) run on the general kernel (``kernels_general``: the reaction
-K^T Psi + N(t, q, v, Psi) in (21b, d) and N_q, N_v, N_psi in the Newton matrix).
Where a system cannot be compiled (an expression numba cannot compile, no safe
cache directory) ``fast_integrate`` prints one line ``ldaspark.compiled.fast: ... falling back
to the generic path`` to stderr and runs ``ldaspark.core.spark.integrate`` /
``ldaspark.core.comparators``.
"""
from __future__ import annotations

import dataclasses
import sys

import numpy as np

from ..core.errors import InputError, LdasparkError, NewtonError, NonFiniteError
from ..core.validate import _CHECKED  # noqa: F401 (the memory of checked initial points, under its old name)
from . import native, runner
from .cache import CacheDirectoryError, load_source, source_key
from .codegen import NotCompilableError, general_source, mechanical_source, nonideal_term
# the kernel runner's names stay importable from here (``fast`` is the compiled path's entry point)
from .runner import (FAST_METHODS, LF2_VARIANTS, LINEAR_SOLVERS, MAIN_KERNELS, REUSE_AUTO_MIN_N, SPARSE_MARGIN,
                     STAT_NAMES, _COMPILED, _ENTRIES, _MODELS, _OPTIONS_OK, _SPECS, _STRUCTURES, _TOL_DEFAULT,
                     CompiledSystem, FastSolution, _check_options, _check_options_now, _entry, _failure, _kernels,
                     _make_spec, _mechanical, _resolve, _run_checked, _sparse_structure, can_compile, compile_system,
                     kernel_spec, mechanical_parts, n_samples, run_compiled)

__all__ = ["fast_integrate", "FastSolution", "compile_system", "CompiledSystem", "mechanical_parts",
           "kernel_spec", "run_compiled", "generic_integrate", "FAST_METHODS", "NotCompilableError",
           "NonFiniteError", "can_compile", "load_source"]


def _diagnose_newton_failure(exc, system, cs, method, start, h, opts):
    """The kernels report only the failing step; for SPARK methods, recompute the state there
    (the same compiled arithmetic, k steps from ``start`` = (t0, q0, v0) with the kernel options
    ``opts``) and let the generic step report residual and iterations. Returns the NewtonError
    to raise."""
    from ..core.spark import SparkMethod
    from ..core.tableau import SparkTableau
    from ..core.families import get_method
    k = exc.step
    t0, q0, v0 = start
    try:
        tab = method if isinstance(method, SparkTableau) else get_method(method)
    except LdasparkError:
        return exc                      # a comparator kernel: no generic step to ask
    try:
        if k:
            pre = runner._run_checked(cs, method, start, (h, k, k), dataclasses.replace(opts, reuse_matrix="auto",
                                                                                          linear_solver="auto"))
            qk, vk = pre.q[-1], pre.v[-1]
        else:
            qk, vk = np.asarray(q0, float), np.asarray(v0, float)
    except NewtonError:
        return exc
    tk = float(t0) + k * float(h)
    try:
        SparkMethod(system, tab, max_iter=opts.max_iter).step(tk, qk, vk, float(h), step_index=k)
    except NewtonError as gen:
        return NewtonError(f"{exc} (generic step at the same state: residual {gen.residual:.3e} after "
                           f"{gen.iterations} iterations)", step=k, time=tk, residual=gen.residual,
                           iterations=gen.iterations)
    return NewtonError(f"{exc} (the generic full-Newton step converges at this state: use "
                       "ldaspark.core.spark.integrate for this step size)", step=k, time=tk)


def _setup_checks(system, t0, q0, v0, cs=None, tol=None, project=False):
    """The one initial-point check (``ldaspark.core.validate.initial_point``) in float64: finite
    data of the right shape, finite energy (8) and k, (4) nonsingular with K of full rank,
    consistent v0 (the compiled kernels assume all of them); (t0, q0, v0) as float64, v0 projected
    with ``project``. With ``cs`` (a mechanical-form model already loaded), (4) = [[M, K^T], [K, 0]]
    and k = K v0 + b come from the model's own compiled K_of, b_of (``model_checks``) instead of
    the lambdified sympy expressions; a point that passed for this system object is remembered."""
    from ..core.backend import Backend
    from ..core.validate import initial_point
    return initial_point(system, Backend(None), t0, q0, v0, project=project, tol=tol, model=model_checks(cs))


def model_checks(cs):
    """``model(t, q, v) -> (S, k)`` of ``initial_point`` from a loaded mechanical-form model ``cs``
    (None otherwise, or where the model has no Python form: the lambdified checks)."""
    if cs is None or cs.form != "mechanical":
        return None

    def model(t, q, v):
        try:
            return _saddle_and_k(cs, float(t), np.ascontiguousarray(q, float), np.ascontiguousarray(v, float))
        except native.NotNativeError:
            return None
    return model


def _saddle_and_k(cs, t, q, v):
    """(4) = [[M, K^T], [K, 0]] and k = K v + b at (t, q, v) from a mechanical-form model."""
    n, m, mod = cs.n, cs.m, cs.functions
    K, b = np.zeros((m, n)), np.zeros(m)
    mod.K_of(t, q, K)
    mod.b_of(t, q, b)
    S = np.zeros((n + m, n + m))
    S[:n, :n] = cs.M
    S[:n, n:] = K.T
    S[n:, :n] = K
    return S, K.dot(v) + b


def _loaded(system):
    """The system's CompiledSystem when ``compile_system`` made it and a run has loaded its
    model in this process, else None (a first call checks before compiling, so that bad data
    fail fast)."""
    hit = _COMPILED.get((id(system), "auto"))
    if hit is None or hit[0] is not system or hit[1].model_id not in _MODELS:
        return None
    return hit[1]


def _notice(msg):
    print(f"ldaspark.compiled.fast: {msg}; falling back to the generic path", file=sys.stderr, flush=True)


def generic_integrate(system, method, t0, q0, v0, h, n_steps, every=1, tol=None):
    """The generic (Python) path with the same outputs as ``run_compiled``."""
    kind, what, name = _resolve(method)
    if kind == "lf2":
        from ..core.comparators import integrate_comparator
        sol = integrate_comparator(name, system, t0, q0, v0, h, int(n_steps), tol=tol)
    else:
        from ..core.spark import integrate
        sol = integrate(system, what, t0, q0, v0, h, n_steps=int(n_steps), tol=tol)
    idx = list(range(0, int(n_steps) + 1, int(every)))
    if idx[-1] != n_steps:
        idx.append(int(n_steps))
    st = dict(sol.stats)
    st["path"] = "generic"
    return FastSolution(np.asarray(sol.t, float)[idx], np.asarray(sol.q, float)[idx],
                        np.asarray(sol.v, float)[idx], np.asarray(sol.energy, float)[idx],
                        np.asarray(sol.constraint, float)[idx],
                        psi=None if getattr(sol, "psi", None) is None else np.asarray(sol.psi, float)[idx[:-1]],
                        stats=st)


def _first_line(exc):
    return f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0][:120]}"


def fast_integrate(scene_or_system, method, t0=None, q0=None, v0=None, h=None, n_steps=None,
                   every=1, compensated=True, tol=None, max_iter=50, kernel="auto", predictor=2,
                   linear_solver="auto") -> FastSolution:
    """Integrate with the compiled float64 path (numba kernels of (21)); deprecated.

    ``ldaspark.integrate(..., engine="compiled")`` runs the same kernels through the one driver
    (time grid, chunking, saving, events, dense output, monitors, the step-acceptance guard,
    ensembles) with the root finder ``ldaspark.Newton(...)``; this function emits a
    DeprecationWarning and returns the same numbers as before.

    Parameters
    ----------
    scene_or_system : Scene or LagrangianSystem
        A Scene's initial data are the defaults of t0, q0, v0.
    method : str or SparkTableau
        A SPARK method name or tableau, or one of ``LF2_VARIANTS`` (the comparators of Fig. 4).
    t0 : float, optional
        Initial time.
    q0, v0 : array_like, optional
        Initial positions and velocities, shape (n,).
    h : float
        Step size.
    n_steps : int
        Number of steps.
    every : int, optional
        Keep every ``every``-th step (and the last one).
    compensated : bool, optional
        Kahan summation of the q and v updates (default True).
    tol : float, optional
        Newton tolerance (default: the round-off of the stage values).
    max_iter : int, optional
        Newton iterations per step.
    kernel : {"auto", "spark"}, optional
        "auto" runs lobatto-iiia-iiib-2 on mechanical systems with the semi-implicit kernel
        (the same method, (25)); "spark" forces the general kernel.
    predictor : {2, 1, 0}, optional
        Stage predictor: linear extrapolation of the last two steps, the last step's
        unknowns, or zero increments.
    linear_solver : {"auto", "dense", "sparse"}, optional
        The Newton matrix's factorisation (``run_compiled``).

    Returns
    -------
    FastSolution
        t, q, v, energy, constraint and ``stats`` (Newton counters, path).

    Raises
    ------
    NewtonError
        When a step's Newton iteration fails.
    NonFiniteError
        On NaN or infinity, naming step and time.
    InputError
        For invalid arguments.

    Notes
    -----
    Falls back to the generic path, with one line on stderr, if the system cannot be compiled.

    Examples
    --------
    >>> import ldaspark
    >>> sol = ldaspark.fast_integrate(ldaspark.get_scene("skate"), "gauss-2", h=0.1, n_steps=10)
    >>> sol.q.shape
    (11, 3)
    """
    import warnings
    warnings.warn("fast_integrate is deprecated: use ldaspark.integrate(..., engine='compiled', "
                  "newton=ldaspark.Newton(...))", DeprecationWarning, stacklevel=2)
    if isinstance(scene_or_system, str):          # a scene name, as integrate takes it
        from ..models.scenes import get_scene
        scene_or_system = get_scene(scene_or_system)
    system = getattr(scene_or_system, "system", scene_or_system)
    if t0 is None or q0 is None or v0 is None:
        if not hasattr(scene_or_system, "initial"):
            raise InputError("give t0, q0, v0 (or pass a Scene)")
        st0, sq0, sv0 = scene_or_system.initial()
        t0 = st0 if t0 is None else t0
        q0 = sq0 if q0 is None else q0
        v0 = sv0 if v0 is None else v0
    if h is None or n_steps is None:
        raise InputError("give h and n_steps")
    from ..core.validate import real_number, real_vector
    real_number(h, "h", nonzero=True)           # h=True is not 1
    real_number(t0, "t0")
    real_vector(q0, "q0")
    real_vector(v0, "v0")
    _check_options(n_steps, every, predictor, tol, max_iter, len(q0), system.m)
    from ..core.validate import check_tol_resolvable, step_advances
    check_tol_resolvable(tol)                   # float64, as integrate refuses it
    step_advances(t0, h, n_steps, None)         # t0 = 1e17, h = 1: the times would repeat
    runner.checked_kernel_spec(method, kernel)        # kernel='spark' of a comparator: refused
    if linear_solver not in LINEAR_SOLVERS:
        raise InputError(f"linear_solver must be one of {LINEAR_SOLVERS}, got {linear_solver!r}")
    _setup_checks(system, t0, q0, v0, _loaded(system))
    kopts = runner.KernelOptions(compensated, tol, max_iter, kernel, predictor, linear_solver=linear_solver)
    return run_engine(system, method, (t0, q0, v0), (h, n_steps, every), kopts)


def run_engine(system, method, start, grid, kopts, fallback=True) -> FastSolution:
    """The compiled engine's block of steps after the checks (``ldaspark.integrate``'s driver
    and ``fast_integrate`` checked the options and the initial point): ``start`` = (t0, q0, v0),
    ``grid`` = (h, n_steps, every), ``kopts`` the ``runner.KernelOptions`` (the root finder's
    fields among them). The fallbacks: the generic path where the system does not compile
    (``fast_integrate``; with ``fallback=False``, the engine's, an InputError instead: the
    generic path would drop the root finder's fields), the generic full-Newton step where a
    kernel's Newton fails (``rescue``)."""
    (t0, q0, v0), (h, n_steps, every) = start, grid
    compensated, tol, max_iter, kernel, predictor = (kopts.compensated, kopts.tol, kopts.max_iter, kopts.kernel,
                                                     kopts.predictor)
    try:
        cs = compile_system(system)
        cs.model  # noqa: B018  (build the model now so that failures fall back)
    except (NotCompilableError, CacheDirectoryError) as exc:
        _notice(str(exc))
        return generic_integrate(system, method, t0, q0, v0, h, n_steps, every, tol)
    except Exception as exc:  # numba typing/lowering errors of generated code
        _notice(f"{system.name}: compilation failed ({_first_line(exc)})")
        return generic_integrate(system, method, t0, q0, v0, h, n_steps, every, tol)
    try:
        return runner._run_checked(cs, method, (t0, q0, v0), (h, n_steps, every), kopts)
    except NotCompilableError as exc:
        if not fallback:
            raise InputError(f"engine 'compiled' cannot run this: {exc}") from None
        _notice(str(exc))
        return generic_integrate(system, method, t0, q0, v0, h, n_steps, every, tol)
    except (NewtonError, NonFiniteError) as exc:
        # a kernel's NaN or inf (a non-finite residual inside Newton: L or k outside their domain
        # at an iterate, or a non-finite end point) goes down the same chain: the generic step there
        # raises what the generic engine raises (NewtonError for a domain error inside the
        # iteration, NonFiniteError for a non-finite end point), or converges and the run goes on
        kind, what, name = _resolve(method)
        if name in LF2_VARIANTS:        # a comparator: no generic SPARK step to take over
            if isinstance(exc, NonFiniteError):
                raise
            from ..core.result import attach_counters, failure_counters
            # the diagnosis's own steps are not the run's work: the failed run's counters
            raise attach_counters(_diagnose_newton_failure(exc, system, cs, method, (t0, q0, v0), h, kopts),
                                  failure_counters(exc)) from None
        # the last link of the fallback chain: the generic full-Newton step (``rescue``)
        from .rescue import run_with_rescue
        return run_with_rescue(system, what, cs, method, t0, q0, v0, h, int(n_steps), int(every), compensated,
                               tol, max_iter, kernel, predictor, exc, kopts=kopts)


# --- warming the compile cache -------------------------------------------------------------
def warm_kernels(names=MAIN_KERNELS) -> float:
    """Compile (first time on a machine) or load the kernels ``names`` in this process; seconds
    taken. The main job runs it as its first job so that the worker processes load the kernels
    from numba's cache instead of each compiling them (~14 s CPU for spark_run, ~4 s for lf2_run
    on a fresh checkout)."""
    import time as _time
    t = _time.perf_counter()
    for name in names:
        _entry(name)
    return _time.perf_counter() - t


def _warm(scene_name, method, kernel):
    import time as _time
    from ..models.scenes import get_scene
    t = _time.perf_counter()
    if scene_name == "linear-3":
        from .roundoff import linear_test_system
        system = linear_test_system()
    else:
        system = get_scene(scene_name).system
    cs = compile_system(system)
    runner.run_kernels(cs, method, 0.0, np.zeros(system.n), np.zeros(system.n), 0.01, 1, kernel=kernel)
    return _time.perf_counter() - t


def precompile(jobs, max_workers=2):
    """Compile the kernels and the models of (scene name, method, kernel) jobs in worker
    processes so that numba's on-disk cache holds them, then load them here. ``scene name`` may
    be "linear-3" (``roundoff.linear_test_system``). Returns {job: seconds}. The kernels compile
    once per machine, a model in a few seconds, so this matters only for many new systems."""
    jobs = list(jobs)
    out = {}
    warm_kernels(_kernels().SIGNATURES)     # once, here, before the workers load them
    if jobs:
        from ..core.lifecycle import make_process_pool
        with make_process_pool(max_workers=max_workers) as ex:
            futs = {job: ex.submit(_warm, *job) for job in jobs}
            out = {job: f.result() for job, f in futs.items()}
        for job in jobs:
            _warm(*job)                     # loads the cached machine code in this process
    return out


def __getattr__(name):
    """The round-off study moved to ``roundoff``; its names stay importable from here."""
    if name in ("linear_test_system", "growth_exponent", "roundoff_errors"):
        from . import roundoff
        return getattr(roundoff, name)
    raise AttributeError(name)
