"""One entry point: ``ldaspark.integrate(system, method, t_span, q0, v0, h, ...) -> Result``.

    import ldaspark
    res = ldaspark.integrate("skate", "gauss-2", t_span=(0, 10), h=0.01, dense_output=True)
    res.q[-1], res.status, res.message, res.nfev     # one Result type for every engine
    q, v = res.sol(3.14159)                          # dense output between the steps

``system``: a LagrangianSystem, a Scene (its initial data are the defaults) or a scene name.
``method``: a SPARK method name (gauss-S, lobatto-iiia-iiib-S, lobatto-iiia-iiib-iiid-S,
euler-i, euler-ii), a ``SparkTableau``, or a comparator name (``ldaspark.core.comparators``).

Engines: ``"generic"`` steps (21a-f) with ``SparkMethod`` in float64, or in mpmath with ``dps``;
``"compiled"`` runs the numba kernels of ``ldaspark.compiled.fast`` (every system: mechanical
form, general L(t, q, v) and k(t, q, v), nonideal terms; float64); ``"auto"`` (default) is compiled whenever the system and method qualify, else generic
with a one-line notice on stderr. Both solve the same equations (21) to round-off (the compiled
kernels with their own root finders, by default the quasi-Newton iteration where it applies, and
compensated sums), and agree to ~1e-13 relative over 1e4 steps (skate and particle, gauss-2,
h = 0.01: 1.4e-11 on |q| <= 100 and 1.5e-13 on |q| <= 3.3).

A step failure (NewtonError, SingularSaddleError, non-finite values) ends the run with a
negative ``status`` and keeps the trajectory up to the last good step; ``raise_on_failure=True``
raises instead. ``save_every=k`` keeps steps 0, k, 2k, ... and the last one; the computed numbers
do not depend on k. Dense output and events: ``ldaspark.core.dense``. Parameters: values for
``LagrangianSystem(..., params=[...])`` symbols, applied without deriving again; a list of
dicts (or q0, v0 with a leading batch axis) runs an ensemble and returns a batched Result.
"""
from __future__ import annotations

import copy
import dataclasses
import functools
import re
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np

from .core import validate
from .core.backend import Backend
from .core.dense import CollocationDense, EventTracker, HermiteDense, step_piece
from .core.errors import InputError, LdasparkError, NewtonError, SingularSaddleError, TableauError
from .core.options import ENGINES as ENGINE_CHOICES, IntegrationOptions  # noqa: F401 (the engine option's values)
from .core.guard import STATUS_GUARD
from .core.chunks import run_in_blocks as _chunked
from .core.result import (COUNTERS, MSG_DONE, STATUS_EVENT, STATUS_NEWTON, STATUS_OTHER, STATUS_SADDLE, Result, add_counters,
                          attach_counters, failure_counters, float_array,
                          save_indices, stack)
from .core.grid import steps_between
# the det (4) scan of a run (shared with run_many, a layer below)
from .ensemble import _saddle_may_change_sign, _saddle_signs, first_saddle_crossing, saddle_crossing  # noqa: F401
from .core.system import LagrangianSystem
from .core.tableau import SparkTableau
MSG_EVENT = "A termination event occurred."


def _notice(msg: str) -> None:
    print(f"ldaspark.integrate: {msg}; using the generic engine", file=sys.stderr, flush=True)


#: longest method name (the longest built-in name has 26 characters): a name of 5000 digits is
#: refused before any int() conversion of it
MAX_METHOD_NAME = 100


def resolve_method(method: Union[str, SparkTableau], max_stages: Optional[int] = None) -> tuple:
    """("spark", SparkTableau, name) or ("comparator", name, name); ``max_stages`` raises the
    stage limit of built-in names (SPARK and gauss-irk-S alike)."""
    if isinstance(method, SparkTableau):
        return "spark", method, method.name
    hit = _METHODS.get(method) if isinstance(method, str) and max_stages is None else None
    if hit is not None:                   # a SPARK name seen before (never a comparator's)
        return "spark", hit, method
    from .core.comparators import comparator_names, is_comparator
    from .core.families import get_method
    from .core.tableau_file import check_stages
    if not isinstance(method, str):
        raise InputError(f"method must be a name or a SparkTableau, got {type(method).__name__}")
    if len(method) > MAX_METHOD_NAME:
        raise InputError(f"unknown method {method[:40]!r}... ({len(method)} characters)")
    if is_comparator(method):
        if method.startswith("gauss-irk-"):
            check_stages(int(method[len("gauss-irk-"):]), max_stages, what=method)
        return "comparator", method, method
    try:
        tab = get_method(method, max_stages=max_stages)
    except TableauError as exc:
        if not str(exc).startswith("unknown method"):
            raise
        raise InputError(f"unknown method {method!r}; choose gauss-S, lobatto-iiia-iiib-S, lobatto-iiia-iiib-iiid-S, "
                         f"euler-i, euler-ii, a SparkTableau, or a comparator ({', '.join(comparator_names(2))}, ...)"
                         ) from None
    if len(_METHODS) >= 64:        # bounded: names are few, but a sweep over s could make many
        _METHODS.clear()
    _METHODS[method] = tab
    return "spark", tab, method


def _stages(kind: str, what) -> int:
    """The stages of a resolved method, for the work bound (``validate.check_work``): a SPARK
    tableau's s; a comparator "gauss-irk-S" has S, the others (Lobatto pairs, Euler compositions)
    at most 2."""
    if kind == "spark":
        return int(what.s)
    tail = what.rsplit("-", 1)[-1]
    return int(tail) if what.startswith("gauss-irk-") and tail.isdigit() else 2


#: method name -> its SparkTableau, built once per process: a tableau computes its coefficients
#: (mpmath, ~0.2 ms for gauss-2) once and keeps them, and the compiled engine's kernel_spec cache
#: is keyed by the tableau object, so a repeated call by name re-derives nothing. Tableaux are
#: not modified after construction (their _cache only memoizes derived views).
_METHODS: dict = {}


def _resolve_system(system, dps):
    """(LagrangianSystem, scene name or None, default (t0, q0, v0) or None)."""
    from .models.scenes import Scene, get_scene
    if isinstance(system, str):
        system = get_scene(system)
    if isinstance(system, Scene):
        return system.system, system.name, system.initial(dps)
    if isinstance(system, LagrangianSystem):
        from .core.system import check_as_built
        check_as_built(system)              # every engine refuses an L, k or N set after construction
        return system, None, None
    raise InputError(f"system must be a LagrangianSystem, a Scene or a scene name, got {type(system).__name__}")


def _time_grid(t_span, t0, t_end, n_steps, h, start):
    """(t0, N) of the run; ``start`` is (the scene's t0 or None, dps)."""
    default_t0, dps = start
    if t_span is not None:
        if t0 is not None or t_end is not None:
            raise InputError("give t_span or t0/t_end, not both")
        if isinstance(t_span, (str, bytes)) or not isinstance(t_span, (list, tuple, np.ndarray)) \
                or len(t_span) != 2:           # a dict or set "pair" would give its keys, in any order
            raise InputError(f"t_span must be a pair (t0, t_end), got {validate._describe(t_span)}")
        t0, t_end = t_span
        validate.real_number(t0, "t0")           # (None, 1) is not the default t0
    if t0 is None:
        t0 = default_t0 if default_t0 is not None else 0.0
    if h is None:
        raise InputError("give the step size h")
    validate.real_number(t0, "t0")
    validate.real_number(h, "h", nonzero=True)
    if (t_end is None) == (n_steps is None):
        raise InputError("give exactly one of t_span / t_end or n_steps")
    if n_steps is None:
        from .core.spark import n_steps_for
        te = validate.real_number(t_end, "t_end")
        # at dps the grid is counted at the digits (h = "1e-420" is 0.0 as a float)
        n_steps = (n_steps_for(float(t0), float(te), float(h)) if dps is None
                   else n_steps_for(t0, t_end, h, dps=dps))
    validate.count(n_steps, "n_steps")
    return t0, n_steps


def _refuse_unknown_options(unknown: dict) -> None:
    import difflib
    import inspect
    known = [p for p, par in inspect.signature(integrate).parameters.items() if par.kind != par.VAR_KEYWORD]
    key = sorted(map(str, unknown))[0]
    close = difflib.get_close_matches(key, known, n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    raise InputError(f"integrate: unknown option {key[:40]!r}{hint}; the options are {', '.join(known)}")


def integrate(system: Union[LagrangianSystem, Any, str], method: Union[str, SparkTableau],
              t_span: Optional[Sequence] = None, q0: Optional[Sequence] = None, v0: Optional[Sequence] = None,
              h: Any = None, *, t0: Any = None, t_end: Any = None, n_steps: Optional[int] = None,
              engine: str = "auto", dps: Optional[int] = None, save_every: int = 1, dense_output: bool = False,
              events: Union[None, Callable, Sequence[Callable]] = None, params: Union[None, dict, list] = None,
              raise_on_failure: bool = False, newton: Any = "auto", project: bool = False,
              tol: Optional[float] = None, executor: Any = None, energy_jump: Optional[float] = None,
              max_stages: Optional[int] = None, guard: bool = True, **unknown: Any) -> Result:
    """Integrate the index-2 DAE (1) by an s-stage SPARK method (21a-f) with constant step h.

    Each step solves the stage equations (21a-f) for (Q_i, V_i, Psi_i) by Newton with the
    analytic Jacobian, then updates (q, v) by (21c, d); the multipliers enter (21b, d) through
    A_tilde and b_tilde, the constraint (1c) is imposed at the stages by omega (21e) and at the
    end point (21f).

    Parameters
    ----------
    system : LagrangianSystem, Scene or str
        The system (1); a Scene or a scene name (``get_scene``) also gives the initial data.
    method : str or SparkTableau
        A SPARK method name (``gauss-S``, ``lobatto-iiia-iiib-S``, ``lobatto-iiia-iiib-iiid-S``,
        ``euler-i``, ``euler-ii``), a `SparkTableau`, or a comparator name of sections 7-8
        (``ldaspark.core.comparators``).
    t_span : (float, float), optional
        Start and end time; alternatively ``t0`` with ``t_end`` or ``n_steps``.
    q0, v0 : array_like, optional
        Initial positions and velocities, shape (n,); shape (B, n) runs an ensemble of B
        members. Default: the scene's initial data.
    h : float
        The constant step size; it must advance t in float64.
    t0, t_end : float, optional
        Start and end time (keywords), instead of ``t_span``.
    n_steps : int, optional
        Number of steps, instead of an end time.
    engine : {"auto", "compiled", "generic"}, optional
        ``"generic"`` steps (21) with the float64 / mpmath code; ``"compiled"`` runs the numba
        kernels (float64); ``"auto"`` (default) is compiled whenever the system and method
        qualify, else generic with a one-line notice on stderr.
    dps : int, optional
        Decimal digits of an mpmath run (16 to 2000); None: float64.
    save_every : int, optional
        Keep steps 0, k, 2k, ... and the last one; the computed numbers do not depend on k.
    dense_output : bool, optional
        Attach ``Result.sol(t) -> (q, v)`` on the run's interval (an InputError outside it): on
        each step the polynomial through the stage velocities corrected to the grid, so that it
        reproduces the saved q_n, v_n (``ldaspark.core.dense``); the same on every engine (the
        compiled engine solves each step's stages again from its saved start after the run; the
        comparators get the cubic Hermite of the grid). h < 0 works too.
    events : callable or list of callable, optional
        ``g(t, q, v) -> float``; zeros are located on the same interpolant of the steps where g
        changes sign (attributes ``terminal`` and ``direction`` as in scipy: the direction is
        along the integration, also for h < 0).
    params : dict or list of dict, optional
        ``{symbol or name: value}`` for the system's symbolic parameters; a list runs an
        ensemble over parameter values. A list of P dicts with (B, n) initial data runs every
        pair, P B members, parameter-major: member p B + b has dict p and initial row b.
    raise_on_failure : bool, optional
        Raise the step failure instead of returning a Result with negative ``status``.
    newton : Newton or {"auto", "full", "simplified", "mixed", "quasi"}, optional
        The root finder of the stage equations (``ldaspark.Newton``: kind, tol, max_iter,
        predictor, linear_solver, reuse), which every engine receives: each field is honoured
        or refused with one InputError naming the engine and the field. A name is the kind:
        "auto" (simplified Newton continuing as full Newton when it contracts slowly), "full",
        "simplified", at mpmath precision "mixed" (Newton matrix in float64, residual at
        full precision; "full" in float64), and on the compiled engine "quasi" (the
        multiplier-only quasi-Newton iteration, which "auto" picks there where it pays).
        ``Result.stats["root_finder"]`` says what was asked for, and on the compiled engine
        ``["runs"]`` what ran.
    project : bool, optional
        Project v0 onto the constraint k(t0, q0, v) = 0 (in the L_vv metric) before the first
        step.
    tol : float, optional
        Newton tolerance; default: the round-off of the stage values. At least the unit
        round-off of the arithmetic (2^-52; 10^-dps with dps), else an InputError.
    executor : concurrent.futures.Executor, optional
        Where ensemble members run (default: a loop in this process); a single run is one
        member, run there too.
    energy_jump : float, optional
        End the run with status -3 at the first step whose energy (8) changes by more than
        ``energy_jump (1 + |E|)``.
    max_stages : int, optional
        Raise the stage limit (20) of built-in method names.
    guard : bool, optional
        The step-acceptance guard (``ldaspark.core.guard``, on by default): a step whose
        energy (8) change is far beyond what the method's local error explains is solved again
        from safe starts; a different root ends the run with status -4 and a message naming the
        step, the two roots and their energies.
    **unknown
        Any other keyword is refused with an `InputError` naming the closest option (a
        misspelt option must not be a raw TypeError, nor silently ignored).

    Returns
    -------
    Result
        t, q, v, psi, energy (8), constraint (1c), ``status`` (0 success, 1 terminal event,
        negative on failure with the trajectory up to the last good step), ``message`` and the
        counters ``nfev``, ``njev``, ``nlu``; batched arrays for an ensemble.

    Raises
    ------
    InputError
        When an argument is invalid: every argument is checked before any work (a method name
        with more stages than ``max_stages`` is a ``TableauError``).
    SystemDefinitionError
        When ``params`` lacks a value for a symbolic parameter of the system, gives one
        parameter two different values (as "m" and Symbol("m")) or gives text that is not a
        number (as ``LagrangianSystem.with_params``; a non-finite, complex or non-numeric value
        is an InputError).
    InconsistentInitialDataError
        When k(t0, q0, v0) = 0 does not hold to rounding and ``project`` is False.
    SingularSaddleError
        When the saddle matrix (4) is singular at the initial point; with
        ``raise_on_failure=True`` also a step failure of status -2.
    NewtonError
        On a step failure of status -1, only with ``raise_on_failure=True``.
    NonFiniteError
        On a step failure of status -3 (non-finite values, the ``energy_jump`` monitor), only
        with ``raise_on_failure=True``.
    RootMismatchError
        On a step failure of status -4 (the ``guard``), only with ``raise_on_failure=True``.

    See Also
    --------
    fast_integrate : deprecated (a DeprecationWarning): the compiled path with its own statistics.
    run_many : several ensembles through one executor.

    Examples
    --------
    >>> import ldaspark
    >>> res = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.1, engine="generic")
    >>> res.status, len(res.t)
    (0, 11)
    >>> bool(abs(res.constraint).max() < 1e-12)
    True
    """
    if unknown:
        _refuse_unknown_options(unknown)
    # the API boundary: every user value checked once, for every engine, into one frozen
    # options object that every engine path below reads (the engines check nothing again)
    opts = IntegrationOptions.checked(engine=engine, dps=dps, newton=newton, tol=tol, save_every=save_every,
                                      dense_output=dense_output, energy_jump=energy_jump, executor=executor,
                                      max_stages=max_stages, project=project, raise_on_failure=raise_on_failure,
                                      guard=guard)
    dps = opts.dps
    sysm, scene, init = _resolve_system(system, dps)
    kind, what, name = resolve_method(method, max_stages)
    t0, N = _time_grid(t_span, t0, t_end, n_steps, h, (init[0] if init else None, dps))
    validate.step_advances(t0, h, N, dps, s=_stages(kind, what), n=sysm.n, m=sysm.m)
    if q0 is None or v0 is None:
        if init is None:
            raise InputError("give q0 and v0 (or pass a Scene / scene name for its initial data)")
        q0 = init[1] if q0 is None else q0
        v0 = init[2] if v0 is None else v0
    validate.real_vector(q0, "q0")
    validate.real_vector(v0, "v0")
    opts = opts.with_events(events)
    if dps is not None and (opts.dense_output or opts.events):
        # the interpolant and the event search run on the float64 grid (``core.dense``): a step
        # that advances t only in the digits would end the run, after every step, in a
        # refusal of non-monotone times
        validate.step_advances(t0, h, N, None, what="h (dense output and events interpolate on a float64 grid)")
    prob = _Problem(kind, what, name, t0, h, N, scene)
    batch_params = isinstance(params, (list, tuple))
    # (B, n) initial data is an ensemble at any precision (at dps it ran the last row alone)
    batch_ic = _ndim(q0) == 2
    if batch_params and not params:
        raise InputError("params is an empty list: an ensemble needs at least one member")
    if batch_params or batch_ic:
        plist = list(params) if batch_params else [params]
        Q0 = list(q0) if batch_ic else [q0]
        V0 = list(v0) if batch_ic else [v0]
        if batch_ic and (_ndim(v0) != 2 or len(Q0) != len(V0)):
            got = f"{len(V0)} rows" if _ndim(v0) == 2 else "one vector (give one row per member)"
            raise InputError(f"q0 has {len(Q0)} rows (an ensemble) but v0 has {got}")
        _check_ensemble_storage(sysm, prob, opts, len(plist) * len(Q0))
        if executor is not None and batch_ic and not batch_params:
            if params is None:
                _check_initial_point(_with_params(sysm, None), (t0, q0, v0), dps, opts=opts)     # every member
            fast = _compiled_ensemble(sysm, params, Q0, V0, prob, opts)
            if fast is not None:
                return fast
        jobs = [(k, p, a, b) for k, (p, (a, b)) in enumerate((p, ab) for p in plist for ab in zip(Q0, V0))]
        member_opts = opts.replace(executor=None)      # a member runs where it is (and the task pickles)
        if executor is None:
            return stack([_member(sysm, prob, member_opts, j) for j in jobs])
        # a module-level task over a system without its lambdified functions (rebuilt in the
        # worker), so that process pools and clusters can run the members as well as threads
        threads = isinstance(executor, ThreadPoolExecutor)
        run = functools.partial(_captured, _member, sysm if threads else _portable(sysm), prob,
                                member_opts)
        return stack(_run_members(executor, run, jobs, captured=True))
    if executor is not None:
        # one run is an ensemble of one member: it runs on the executor asked for, as every member
        # does (the executor was accepted and the run made here)
        threads = isinstance(executor, ThreadPoolExecutor)
        run = functools.partial(_captured, _solo, sysm if threads else _portable(sysm), prob,
                                opts.replace(executor=None))
        return _run_members(executor, run, [(params, q0, v0)], captured=True)[0]
    return _single(sysm, (params, q0, v0), prob, opts)


def _check_ensemble_storage(system, prob: _Problem, opts: IntegrationOptions, members: int) -> None:
    """The storage bound of ``_drive_steps`` for the ensemble as a whole, before any member runs:
    the batched Result holds every member's samples (t, q, v, E, k, psi: 2 + 2n + m + s m numbers
    each), and with dense output or events each member's steps, so ``members`` runs that each fit
    can together not (each member's own check would let it run, until stacking them ran out of
    memory)."""
    from .compiled.fast import n_samples
    s, n, m = _stages(prob.kind, prob.what), system.n, system.m
    validate.check_storage(n_samples(prob.N, opts.save_every) * members, 2 + 2 * n + m + s * m,
                           mp=opts.dps is not None, what="the ensemble samples", every=True)
    if opts.dense_output or opts.events:
        validate.check_storage((prob.N + 1) * members, n + s * n, what="the ensemble's dense output")


def _ndim(x) -> int:
    """The number of axes of q0 / v0 as numpy reads a nested sequence of numbers (objects kept)."""
    if type(x) is np.ndarray:
        return x.ndim
    if type(x) in (list, tuple) and all(type(e) is float for e in x):
        return 1 if x else np.ndim(np.asarray(x, dtype=object))
    return np.ndim(np.asarray(x, dtype=object))


def _run_members(executor, run, jobs, captured=False) -> list:
    """The members' Results from ``executor``, each member submitted now and checked as
    ``run_many``'s work units are (``executors._submit``): a ``submit`` that raises or returns
    something other than a future is the same InputError naming the executor on every path (its
    ``map`` made it an AttributeError's text in an LdasparkError here); a member's LdasparkError
    as it is; a future that fails otherwise, or that hands back something other than a Result:
    one LdasparkError naming the executor. Any exception (Ctrl-C) cancels the pending members.
    ``captured``: each task hands back (Result, its warnings) (``_captured``), said here in member
    order, as the run in this process says them."""
    name = type(executor).__name__
    futures = []
    try:
        for job in jobs:
            try:
                fut = executor.submit(run, job)
            except Exception as exc:  # noqa: BLE001  (a user's executor's own error: one line)
                raise validate.submit_error(executor, exc) from exc
            futures.append(validate.submitted(executor, fut))
        members = [f.result() for f in futures]
    except LdasparkError:
        _cancel(futures)
        raise
    except RuntimeError as exc:     # "cannot schedule new futures after shutdown" and the like
        _cancel(futures)
        raise validate.executor_shut_down(exc) from exc
    except Exception as exc:       # a third-party executor's own failure (a cancelled future, ...)
        _cancel(futures)
        raise LdasparkError(f"the executor {name} failed to run the ensemble members "
                            f"({type(exc).__name__}: {str(exc)[:120]})") from exc
    except BaseException:          # Ctrl-C: what has not started does not start
        _cancel(futures)
        raise
    said = []
    if captured:
        members, said = ([m[0] for m in members], [m[1] for m in members]) if all(
            isinstance(m, tuple) and len(m) == 2 and isinstance(m[1], list) for m in members) else (members, [])
    bad = [type(m).__name__ for m in members if not isinstance(m, Result)]
    if bad or len(members) != len(jobs):
        raise LdasparkError(f"the executor {name} returned {len(members)} results for {len(jobs)} ensemble members"
                            + (f", not Results ({bad[0]})" if bad else ""))
    import warnings
    for ws in said:
        for category, text in ws:
            warnings.warn(text, category, stacklevel=3)
    return members


def _captured(task, *args):
    """``task(*args)`` and the warnings of its run as (category, text): for a task of an executor,
    which may run in another process (a process pool, a cluster), where a warning said there
    never reached the caller (``project=True``'s change of v0, the singular L_vv of (5) and a
    params key that is no parameter were lost, while the run in this process says them). The run
    hands them over (``said``) instead of warning: no ``warnings.catch_warnings``, which is not
    thread safe (a cluster's threads in this process, or a worker's threads, would swap each
    other's and the caller's warning state). A thread pool's members too: their warnings came in
    the order the threads ran, and a thread's warning need not reach the caller's
    ``catch_warnings`` (Python 3.14's context-aware warnings); ``_run_members`` says them in
    member order."""
    said = []
    return task(*args, said=said), said


def _cancel(futures) -> None:
    for f in futures:
        try:
            f.cancel()
        except Exception:  # noqa: BLE001  (a user's future's own error: the first error is the one said)
            pass


@dataclass(frozen=True)
class _Problem:
    """What one ``integrate`` call integrates (its options are ``IntegrationOptions``): the
    resolved method (kind "spark" with a SparkTableau, or "comparator" with its name), the name
    it reports, the time grid t0 + i h for i <= N, and the scene's name (or None)."""

    kind: str
    what: Any
    name: str
    t0: Any
    h: Any
    N: int
    scene: Optional[str]

    @property
    def method(self):
        """What the compiled engine runs: the tableau of a SPARK method, else the comparator's name."""
        return self.what if self.kind == "spark" else self.name


def _member(system, prob: _Problem, opts: IntegrationOptions, job, said=None) -> Result:
    """One member of an ensemble over parameters or initial data (the fallback notice once per
    ensemble, not once per member). An error that ends the call (a member's bad parameter value or
    initial point, an event function that raises, a failure with raise_on_failure) names the member,
    as the initial-point check of every member does (``_check_initial_point``), on every path."""
    try:
        return _single(system, job[1:], prob, opts, quiet=job[0] > 0, said=said)
    except LdasparkError as exc:
        tag = f"ensemble member {job[0]}: "
        if exc.args and isinstance(exc.args[0], str) and not exc.args[0].startswith("ensemble member "):
            exc.args = (tag + exc.args[0],) + exc.args[1:]
        raise


def _solo(system, prob: _Problem, opts: IntegrationOptions, member, said=None) -> Result:
    """A single run (``member`` = (params, q0, v0)) as a task of the executor asked for."""
    return _single(system, member, prob, opts, said=said)


def _portable(system):
    """A copy of ``system`` that pickles: its lambdified functions (closures over generated code)
    are dropped and rebuilt where it is unpickled."""
    out = copy.copy(system)
    out._compiled = {}
    return out


def _compiled_ensemble(system, params, Q0, V0, prob: _Problem, opts: IntegrationOptions) -> Optional[Result]:
    """Initial-data ensembles on the compiled engine go through
    ``ldaspark.ensemble.ensemble_integrate`` (tasks that pickle, so any executor, process
    pools and clusters included); None when the run does not qualify (then the loop runs: a root
    finder other than the default with any tol, whose fields the kernel tasks do not take, too, and
    guard=True, the default: ``run_many``'s guard raises for the whole ensemble, while the loop
    drives each member as its single run, a member with another root ending with its own status)."""
    from .engines import ENGINES
    if (opts.engine == "generic" or opts.dps is not None or opts.dense_output or opts.events or opts.project
            or opts.guard or opts.energy_jump is not None or dataclasses.replace(opts.newton, tol=None) != "auto"
            or params is not None or system.params
            or ENGINES["compiled"].unavailable(system, prob) is not None):
        return None
    from .core.result import from_ensemble
    from .ensemble import run_ensemble
    from .executors import UnitsFailed
    try:
        ens = run_ensemble(system, prob.method, prob.t0, Q0, V0, prob.h, prob.N, every=opts.save_every,
                           tol=opts.tol, executor=opts.executor, guard=False)
    except (UnitsFailed, SingularSaddleError):
        # a member's step failed (NonFiniteError, NewtonError), or a member crossed the singular
        # set of (4) (``RunSpec.saddle_check``): the kernel task has no rescue chain and no partial
        # Result, so the ensemble runs again as the loop of single runs, where that member ends
        # with its own status (-2 with the det (4) monitor's error, ``_saddle_scan``) and the
        # others are kept (the loop's numbers are the same)
        return None
    # each member says what ran as a single run's Result does: the root finder asked for, and the
    # kernel's choice ("runs"), not the kernel's bare kind name
    asked = opts.newton.describe()
    support = ENGINES["compiled"].root_finder(opts.newton, prob)[1]      # "compiled" or "compiled-lf2"
    for st in ens.stats:
        st["root_finder"] = dict(asked, runs=st.get("newton_kind", st.get("root_finder", "generic")))
        st.setdefault("rescued_steps", st.get("generic_steps", 0))
        if st.get("path") == "fast":
            st["engine"] = support
    res = from_ensemble(ens, method=prob.name, system=system.name, scene=prob.scene, h=prob.h,
                        save_every=opts.save_every)
    # what every single run's Result names (``_single``): the coordinates, each Result its own list
    for r in [res] + res.members:
        r.coordinate_names = _coordinate_names(system)
    return res


def _with_params(system: LagrangianSystem, params, said=None) -> LagrangianSystem:
    if params is None:
        if system.params:
            system._param_arg_values(None)     # raises if a value is missing
        return system
    if not isinstance(params, dict):
        raise InputError(f"params must be a dict (or a list of dicts for an ensemble), got {validate._describe(params)}")
    for key, val in params.items():
        validate.param_value(key, val)
    if said is not None:
        # the note of a key that is no parameter (``with_params``), said by the caller
        # (``_captured``): the value changes nothing, so the key is left out here
        from .core.errors import LdasparkWarning
        names = {str(p) for p in system.params}
        for key in [k for k in params if k not in system.params and str(k) not in names]:
            said.append((LdasparkWarning, system.not_a_parameter(key)))
        params = {k: v for k, v in params.items() if k in system.params or str(k) in names}
    return system.with_params(params)


def _choose_engine(system, prob: _Problem, opts: IntegrationOptions, quiet: bool):
    """The registered engine (``ldaspark.engines.ENGINES``) that runs this problem: "compiled"
    when asked for or, with "auto", whenever it can run the system and method in float64; else the
    generic SPARK engine, or the comparator engine for a comparator. (engine, notice): "auto"
    falls back with one notice on stderr (unless ``quiet``), which the caller prints once the
    fallback engine has taken the run (a refusal there is then the one line the user sees); an
    explicit "compiled" that cannot run is refused."""
    from .engines import ENGINES
    use, notice = opts.engine, None
    if use != "generic":
        if opts.dps is not None:
            use = "generic"
        else:
            # parameters are the model's run-time values (compiled.codegen.fill_params, native
            # wrappers): the model is generated and compiled once for every value
            reason = ENGINES["compiled"].unavailable(system, prob)
            if reason is None:
                use = "compiled"
            elif use == "compiled":
                raise InputError(f"engine 'compiled' cannot run this: {reason}")
            else:
                if prob.kind == "comparator":
                    # a comparator the generic engine refuses too: its refusal, not a notice of a
                    # fallback and then the refusal (two lines)
                    from .core.comparators import require_mechanical
                    require_mechanical(prob.name, system)
                if opts.newton == "quasi":       # refused below: one line, not a notice first
                    raise InputError(f"newton='quasi' runs on the compiled engine only, which cannot run this: "
                                     f"{reason}")
                use = "generic"
                if not quiet:
                    notice = reason
    if use != "compiled" and opts.newton == "quasi":       # (Newton.__eq__ is not cheap)
        raise InputError(f"newton='quasi' runs on the compiled engine only; the generic engine would run {prob.name} "
                         "here")
    if use == "generic" and prob.kind == "comparator":
        use = "comparator"
    return ENGINES[use], notice


def _single(system, member, prob: _Problem, opts: IntegrationOptions, quiet=False, said=None) -> Result:
    """The driver, for one run of ``member`` = (params, q0, v0): parameters applied, the engine
    chosen (``_choose_engine``) and prepared (its root finder honoured or refused), the one
    initial-point check, then the engine driven (``_drive``) into one Result."""
    (params, q0, v0), t0, dps = member, prob.t0, opts.dps
    system = _with_params(system, params, said)
    pvals = {str(k): v for k, v in system.param_values().items()}
    engine, notice = _choose_engine(system, prob, opts, quiet)
    prep = engine.prepare(system, prob, opts)
    bk = engine.backend(prep, opts)
    start, notes = _check_initial_point(prep.system, (t0, q0, v0), dps, bk=bk, opts=opts, model=engine.point_model(prep))
    if notice is not None:          # after the fallback engine's refusals: one line, not two
        _notice(notice)
    res = _drive(engine, prep, start)
    res.method, res.system, res.scene, res.h, res.dps, res.save_every, res.params = \
        prob.name, system.name, prob.scene, prob.h, dps, opts.save_every, pvals
    res.coordinate_names = _coordinate_names(system)
    if opts.project and len(res.t):
        _note_projection(res, v0, said)
    if notes and res.status >= 0:
        _warn_regular(system, notes, said)
    if opts.raise_on_failure and res.status < 0:
        res.raise_for_status()
    return res


def _warn_regular(system, notes, said=None) -> None:
    """A run that ended well from a point where L_vv is singular while (4) holds: one
    LdasparkWarning (``validate.warn_singular_lvv``, which run_many's members say too); a failed
    run says its own error, alone. ``said``: a list that gets (category, text) instead (``_captured``)."""
    if said is not None:
        from .core.errors import LdasparkWarning
        said.append((LdasparkWarning, validate.singular_lvv_message(system, notes)))
        return
    validate.warn_singular_lvv(system, notes, stacklevel=3)     # at integrate, as before


def _coordinate_names(system) -> list:
    """The names of the coordinates q as printed (a fresh list), printed once per tuple of q symbols
    (sympy's printer took ~3 us a name at every call)."""
    key = tuple(system.q)
    hit = _NAMES.get(key)
    if hit is None:
        if len(_NAMES) >= 256:         # bounded: a sweep over new systems makes a key per system
            _NAMES.clear()
        hit = _NAMES[key] = tuple(str(x) for x in key)
    return list(hit)


#: tuple of q symbols -> their printed names (``_coordinate_names``)
_NAMES: dict = {}


def _note_projection(res: Result, v0, said=None) -> None:
    """``project=True`` replaced the user's v0 by its projection onto k = 0: the change is
    recorded (``stats["projected_v0_change"]``, max abs over the components) and, where it is
    above the rounding of v0 (64 ulps of its largest component: the projection of consistent data
    moves it by a few), said in one LdasparkWarning, so the run never starts silently from other
    speeds than the ones given."""
    import warnings

    from .core.errors import LdasparkWarning
    given = float_array(np.asarray(v0, dtype=object))
    change = float(np.max(np.abs(float_array(res.v[0]) - given), initial=0.0))
    res.stats["projected_v0_change"] = change
    if change > 64 * np.finfo(float).eps * max(1.0, float(np.max(np.abs(given), initial=0.0))):
        text = (f"project=True changed v0 by up to {change:.3g} (to {np.array2string(float_array(res.v[0]), precision=6)}) "
                "so that k(t0, q0, v0) = 0")
        if said is not None:        # said by the caller (``_captured``)
            said.append((LdasparkWarning, text))
        else:
            warnings.warn(text, LdasparkWarning, stacklevel=3)


def _check_initial_point(system, start, dps, bk=None, opts: Optional[IntegrationOptions] = None, model=None):
    """The initial point of a run (or of every member of an initial-data ensemble, q0 and v0 with a
    leading axis) through the one check ``ldaspark.core.validate.initial_point``: numbers, shapes,
    finite, the energy (8) and k finite real numbers (U = 1/x at x = 0, oo or zoo in L, v0 = 1e200,
    sqrt(x) at x = -1 are one error here, never a NaN, inf or complex energy[0] in a returned
    Result, nor a ZeroDivisionError printed by a compiled kernel), (4) regular, v0 projected with
    ``opts.project``, (1c). ``start`` = (t0, q0, v0); returns (start in ``bk``'s numbers (of the
    last member), notes: what the check found without refusing, ``validate.initial_point``)."""
    (t0, q0, v0), bk = start, Backend(dps) if bk is None else bk
    if _ndim(q0) == 2:                            # an initial-data ensemble: every member
        rows = list(zip(np.asarray(q0, dtype=object), np.asarray(v0, dtype=object)))
    else:
        rows = [(q0, v0)]
    project, tol = (False, None) if opts is None else (opts.project, opts.tol)
    start, notes = None, {}
    with bk.context():
        for j, (q, v) in enumerate(rows):
            member = f"ensemble member {j}: " if len(rows) > 1 else ""
            start = validate.initial_point(system, bk, t0, q, v, member=member, project=project, tol=tol,
                                           model=model, notes=notes)
    return start, notes


# --- the driver -----------------------------------------------------------------------------
def _drive(engine, prep, start) -> Result:
    """Drive ``engine`` (prepared: ``prep``) from the checked ``start`` over the problem's grid into
    one Result, with what the driver owns for every engine: save_every, dense output, events, the
    energy monitor, the step-acceptance guard, the prefix of a failed run and (block engines) the
    chunks."""
    return _drive_steps(engine, prep, start) if engine.mode == "steps" else _drive_blocks(engine, prep, start)


class _StepWatch:
    """The driver's per-step monitors on a stepping engine: the energy monitor (``energy_jump``,
    the test of ``_energy_jump_cut``) and the step-acceptance guard (``ldaspark.core.guard``: each
    step's energy change and Newton iterations against the previous steps'; a suspect step is
    solved again from the safe starts of ``engine.resolve_step``, and a different root ends the
    run)."""

    def __init__(self, engine, prep, E0, h):
        from .core.guard import StepGuard
        self.engine, self.prep, self.h = engine, prep, h
        self.jump = prep.opts.energy_jump
        self.test = StepGuard(prep.opts.tol) if prep.opts.guard else None
        # the energy in the run's numbers (mpmath at dps: its change is taken there, then made a
        # float, so that a jump below float64's resolution of E is seen) and as a float
        self.Ex, self.E = E0, float(E0)
        self.prev = None            # (V, Psi, h) of the previous step
        self.flagged = self.confirmed = self.unverified = 0

    def step(self, st) -> Optional[LdasparkError]:
        """None when the step ``st`` (``engines.Step``) stands, else the error that ends the run."""
        from .core import guard
        from .core.errors import NonFiniteError
        E1 = float(st.energy)
        dE = float(abs(st.energy - self.Ex)) if self.jump is not None else 0.0
        if self.jump is not None and dE > float(self.jump) * (1 + abs(self.E)):
            return NonFiniteError(
                f"step {st.index} (t = {float(st.t):.6g} -> {float(st.t + self.h):.6g}): energy jumped from "
                f"{self.E:.6g} to {E1:.6g} (by {dE:.3g}, more than energy_jump = {float(self.jump):g} relative): a "
                "collision with a singularity of L or a step too large", step=st.index, time=float(st.t))
        if self.test is not None:
            if self.test.suspect(st.index, self.E, E1, st.iterations):
                self.flagged += 1
                label, safe = self.engine.resolve_step(self.prep, st.index, (st.t, st.q, st.v), self.prev)
                if safe is None:
                    self.unverified += 1
                elif guard.same_root(st.q1, st.v1, safe[0], safe[1], self.prep.opts.tol):
                    self.confirmed += 1
                else:
                    # the energy in the run's numbers: E1 is inf beyond float64's range at dps
                    return guard.mismatch(st.index, st.t, self.h, (st.q1, st.v1, st.energy), safe, label)
            self.test.accept(self.E, E1, st.iterations)
        self.Ex, self.E = st.energy, E1
        self.prev = (st.V, st.Psi, self.h)
        return None

    def stats(self) -> dict:
        if self.test is None:
            return {"guard": False}
        return {"guard": True, "guard_flagged": self.flagged, "guard_confirmed": self.confirmed,
                "guard_unverified": self.unverified}


def _drive_steps(engine, prep, start) -> Result:
    """A stepping engine (the generic one) driven step by step: every ``every``-th point (t, q, v,
    E, k, psi) kept, the stage polynomial corrected to the grid for dense output and events, the
    monitors (``_StepWatch``), and the prefix on a step failure."""
    from .compiled.fast import n_samples
    prob, opts, system = prep.prob, prep.opts, prep.system
    N, every, dense, events, dps = prob.N, opts.save_every, opts.dense_output, opts.events, opts.dps
    c = engine.nodes(prep)
    # what this run stores: every ``every``-th point (t, q, v, E, k, psi), and with dense output or
    # events the nodes and stage velocities of every step (refused before allocating, as the
    # compiled engine does)
    s, n, m = len(c), system.n, system.m
    validate.check_storage(n_samples(N, every), 2 + 2 * n + m + s * m, mp=dps is not None, every=True)
    if dense or events:
        validate.check_storage(N + 1, n + s * n, what="the dense output")
    bk = engine.backend(prep, opts)
    status, message, error = 0, MSG_DONE, None
    with bk.context():
        t0_, q, v = start
        h_ = bk.scalar(prob.h)
        tracker = EventTracker(events, t0_, q, v) if events else None
        saved_i, Qs, Vs, Ps = [0], [q], [v], []
        dense_q, dense_v, dense_V = [], [], []
        done = 0
        watch = _StepWatch(engine, prep, system.energy(bk, t0_, q, v), h_) \
            if opts.guard or opts.energy_jump is not None else None
        steps = engine.steps(prep, (t0_, q, v), N)
        while True:
            try:              # only the step itself: an error raised by an event function propagates
                st = next(steps, None)
            except LdasparkError as exc:
                (status, message), error = _failure(exc), exc
                break
            if st is None:
                break
            i, ti = st.index, st.t
            if watch is not None:
                error = watch.step(st)
                if error is not None:
                    status, message = _failure(error)
                    break
            if i % every == 0:
                Ps.append(st.Psi)
            if dense:
                dense_q.append(float_array(q))
                dense_v.append(float_array(v))
                dense_V.append(float_array(st.V))
            t1 = t0_ + (i + 1) * h_           # the grid's t_n+1: the piece ends where the search looks
            stop = tracker is not None and tracker.after_step(
                ti, t1, st.q1, st.v1, step_piece(ti, h_, (q, v), (st.q1, st.v1), c, st.V, t1=t1))
            q, v = st.q1, st.v1
            done = i + 1
            if done % every == 0 or done == N or stop:
                saved_i.append(done)
                Qs.append(q)
                Vs.append(v)
            if stop:
                status, message = STATUS_EVENT, MSG_EVENT
                break
        if saved_i[-1] != done:           # failure: the last good state ends the trajectory
            saved_i.append(done)
            Qs.append(q)
            Vs.append(v)
        ts = [t0_ + j * h_ for j in saved_i]
        E = [system.energy(bk, ts[j], Qs[j], Vs[j]) for j in range(len(ts))]
        K = [system.constraint(bk, ts[j], Qs[j], Vs[j]) for j in range(len(ts))]
    dt = object if bk.is_mp else float
    # the counters of every step worked on (the failed one too); "steps" the accepted ones (a step
    # the saddle monitor, the guard or the energy monitor refused was solved but not accepted)
    st = dict(engine.stats(prep), steps=done)
    st["mean_iterations"] = st["newton_iterations"] / max(done, 1)
    psi = np.array(Ps[:len(ts) - 1], dtype=dt).reshape(len(ts) - 1, s, m)
    guard_stats = watch.stats() if watch is not None and watch.test is not None else {"guard": False}
    res = Result(np.array(ts, dtype=dt), np.array(Qs, dtype=dt), np.array(Vs, dtype=dt), np.array(E, dtype=dt),
                 np.array(K, dtype=dt).reshape(len(ts), m), psi, status, message,
                 st["nfev"], st["njev"], st["nlu"], st["newton_iterations"], engine=engine.label,
                 stats=dict(st, path="generic", engine=prep.support, root_finder=prep.root.describe(),
                            **guard_stats), error=error)
    if dense and done > 0:
        tg = float(t0_) + np.arange(done + 1) * float(h_)
        res.sol = CollocationDense(tg, np.array(dense_q + [float_array(q)]), c, np.array(dense_V),
                                   np.array(dense_v + [float_array(v)]))
    if tracker is not None:
        res.t_events, res.q_events, res.v_events = tracker.arrays()
    return res


def _drive_blocks(engine, prep, start) -> Result:
    """A block engine (compiled kernels, comparators) driven in blocks: the run in chunks
    (``_chunked``), the prefix of a failed run (``_prefix_run``, explained by ``engine.explain``),
    the guard (``_guard_scan``), the energy monitor (``_energy_jump_cut``), then dense output,
    events and ``save_every`` (``_finish_prefix``)."""
    prob, opts = prep.prob, prep.opts
    N, energy_jump = prob.N, opts.energy_jump
    inner = opts.save_every if engine.samples and not opts.every_step else 1
    try:
        engine.check_block(prep, N, inner)
    except InputError as exc:
        # the kernel's storage bound on the samples save_every keeps: say that a larger one fits
        if not (engine.samples and not opts.every_step) or not str(exc).endswith(validate.STORAGE_ADVICE):
            raise
        raise InputError(f"{exc}{validate.EVERY_ADVICE}") from None

    def run(n, e):      # block ends on the saved points of the run (``inner``), for its reruns too
        return _chunked(engine, prep, start, n, e, boundaries=inner)
    res, exc = _prefix_run(run, N, inner)
    if exc is not None:
        # the diagnosis's own steps are not the run's work: the failed run's counters stay
        spent = failure_counters(exc)
        exc = engine.explain(prep, exc, res, start)
        if failure_counters(exc) is None:
            attach_counters(exc, spent)
    res, exc = _saddle_scan(res, exc, prep, inner, (lambda n: run(n, 1)) if inner > 1 else None)
    res, exc = _guard_scan(res, exc, engine, prep, (lambda n: run(n, 1)) if engine.samples else None)
    if exc is None:
        res, exc = _energy_jump_cut(res, energy_jump)
    # without dense output, events, an energy-jump watch or the guard the kernels kept every
    # ``every``-th point already (inner = every): nothing to post-process (with every = 1 too:
    # re-slicing would copy the arrays unchanged)
    return _finish_prefix(res, exc, prep, start, engine, sliced=engine.samples and not opts.every_step)


def _saddle_scan(res, exc, prep, every, rerun=None) -> tuple:
    """The det (4) monitor of the stepping engines (``core.spark.march``: a sign change of det (4)
    between t0 and a step point is a SingularSaddleError, status -2) on a SPARK run of a block
    engine, which solves (21) with no such check and would go on across the singular set of (4)
    on another branch: (the run up to the step that crossed, that error) or (res, exc). ``every``:
    the samples' spacing in steps; ``rerun(n)``: the first n steps with every step kept, to name the
    step that crossed between two samples (a crossing and its return between two samples is not
    seen). Skipped where det (4) cannot change sign (``_saddle_may_change_sign``)."""
    prob, system = prep.prob, prep.system
    if res is None or len(res.t) < 2 or prob.kind != "spark" or not _saddle_may_change_sign(system):
        return res, exc

    def first_change(r, start):
        t, Q, V = float_array(r.t), float_array(r.q), float_array(r.v)
        change = np.nonzero(_saddle_signs(system, t[start:], Q[start:], V[start:]) != sign0)[0]
        return int(change[0]) + start if len(change) else None
    t0 = float_array(res.t)[0]
    sign0 = _saddle_signs(system, float_array(res.t)[:1], float_array(res.q)[:1], float_array(res.v)[:1])[0]
    j = first_change(res, 1) if sign0 else None
    if j is None:
        return res, exc
    steps, i = res, j
    if every > 1:                               # the step that crossed, between samples j - 1 and j
        at = save_indices(steps_between(res.t[0], res.t[-1], prob.h), every)
        steps = rerun(int(at[j]))
        i = first_change(steps, int(at[j - 1]) + 1)
        i = int(at[j]) if i is None else i
    k = i - 1                                   # step k ends at point i: the prefix ends at point k
    tk = t0 + k * float(prob.h)
    err = SingularSaddleError(saddle_crossing(k, tk, float(prob.h)))
    idx = np.arange(k + 1) if every == 1 else save_indices(k, every) if k > 0 else np.array([0])
    for nm in ("t", "q", "v", "energy", "constraint"):
        setattr(res, nm, np.asarray(getattr(steps, nm))[idx])
    res.psi = None if steps.psi is None else np.asarray(steps.psi)[idx[:-1]]
    return res, err


def _energy_jump_cut(res: Result, energy_jump) -> tuple:
    """The ``energy_jump`` monitor on a run that returned every step (compiled kernels,
    comparators): (the prefix up to the first step whose energy changes by more than
    energy_jump (1 + |E|), the NonFiniteError) or (res, None). The same test as the stepping
    engines' monitor (``_StepWatch``)."""
    from .core.errors import NonFiniteError
    if energy_jump is None or res is None or len(res.t) < 2:
        return res, None
    E = float_array(res.energy)
    # the changes in the run's numbers (mpmath at dps), then as floats: a jump below float64's
    # resolution of E is seen at the digits the run has
    dE = float_array(np.abs(np.diff(np.asarray(res.energy))))
    jump = dE > float(energy_jump) * (1 + np.abs(E[:-1]))
    if not jump.any():
        return res, None
    k = int(np.argmax(jump))
    t = float_array(res.t)
    exc = NonFiniteError(f"step {k} (t = {t[k]:.6g} -> {t[k + 1]:.6g}): energy jumped from {E[k]:.6g} to "
                         f"{E[k + 1]:.6g} (by {dE[k]:.3g}, more than energy_jump = {float(energy_jump):g} relative): "
                         "a collision with a singularity of L or a step too large", step=k, time=t[k])
    for nm in ("t", "q", "v", "energy", "constraint"):
        setattr(res, nm, np.asarray(getattr(res, nm))[:k + 1])
    if res.psi is not None:
        res.psi = np.asarray(res.psi)[:k]
    return res, exc


def _failure(exc: BaseException) -> tuple:
    from .core.errors import NonFiniteError
    from .core.guard import RootMismatchError
    if isinstance(exc, RootMismatchError):
        return STATUS_GUARD, str(exc)
    if isinstance(exc, NonFiniteError):     # before NewtonError: a NonFiniteStepError is both
        return STATUS_OTHER, str(exc)
    if isinstance(exc, NewtonError):
        return STATUS_NEWTON, str(exc)
    if isinstance(exc, SingularSaddleError):
        return STATUS_SADDLE, str(exc)
    return STATUS_OTHER, str(exc)


def _post_process(full: Result, every: int, dense: bool, events, sliced: bool = False, stages=None) -> Result:
    """Dense output, events and ``save_every`` for engines that return every step (``sliced``:
    the engine already kept every ``every``-th point; no dense output or events). ``stages``
    (``Engine.stage_solver``): the stage velocities of a step solved again from its saved start,
    for the stage polynomial corrected to the grid (every step for dense output, only the steps
    where an event changes sign for events); None: the cubic Hermite of the grid (comparators)."""
    if sliced:
        return full
    t, q, v = float_array(full.t), float_array(full.q), float_array(full.v)
    done = len(t) - 1
    if stages is not None and dense and done > 0:
        validate.check_storage(done + 1, len(stages.c) * q.shape[1], what="the dense output")
    solved: dict = {}

    def stage_V(i):
        if i not in solved:
            solved[i] = stages(t[i], q[i], v[i], q[i + 1], v[i + 1])
        return solved[i]

    def piece(i):
        if stages is None:
            return HermiteDense(t[i:i + 2], q[i:i + 2], v[i:i + 2])
        return step_piece(t[i], t[i + 1] - t[i], (q[i], v[i]), (q[i + 1], v[i + 1]), stages.c, stage_V(i))
    if events:
        # g at t0 and one array per event function also when the first step failed (done = 0),
        # as the stepping engine, which sets up the tracker before its first step
        tracker = EventTracker(events, t[0], q[0], v[0])
        for i in range(done):
            # the step's interpolant is built (its stages solved) only where an event changes sign
            local = functools.partial(_lazy_piece, [None], piece, i)
            if tracker.after_step(t[i], t[i + 1], q[i + 1], v[i + 1], local):
                done = i + 1
                # the run ends here, before any later step's failure or monitor cut (the block ran
                # past the event; the stepping engine never takes those steps): status 1, no error
                full.status, full.message, full.error = STATUS_EVENT, MSG_EVENT, None
                break
        full.t_events, full.q_events, full.v_events = tracker.arrays()
    if dense and done > 0:
        if stages is None:
            full.sol = HermiteDense(t[:done + 1], q[:done + 1], v[:done + 1])
        else:       # each step's stages solved when the step is first evaluated (``CollocationDense``)
            full.sol = CollocationDense(t[:done + 1], q[:done + 1], stages.c, None, v[:done + 1], stage_fn=stage_V)
    if every == 1 and done == len(full.t) - 1:
        return full                       # every step kept and asked for: nothing to slice
    idx = save_indices(done, every) if done > 0 else np.array([0])
    for name in ("t", "q", "v", "energy", "constraint"):
        setattr(full, name, np.asarray(getattr(full, name))[idx])
    if full.psi is not None:
        full.psi = np.asarray(full.psi)[idx[:-1]]
    return full


def _lazy_piece(memo: list, build: Callable, i: int, tt):
    """(q, v) at tt on step i's interpolant, built by ``build(i)`` at the first call."""
    if memo[0] is None:
        memo[0] = build(i)
    return memo[0](tt)


def _prefix_run(run: Callable, N: int, every: int) -> tuple:
    """run(n_steps, every) -> Result; on a step failure at step k, rerun k steps (the kernels and
    the comparators do not return partial trajectories) and mark the failure. The rerun may fail
    at an earlier step j < k (a comparator checks its points' energies only at the end of a run: a
    point outside the domain of L made by step j is met inside a later step k of the long run):
    then step j ends the run, with the prefix of j steps. Counters (``core.result``): those the
    failure carries (``failure_counters``: the failed run's work, its failed step included), not
    the rerun's, which repeats work already counted."""
    try:
        return run(N, every), None
    except LdasparkError as exc:
        err = exc
    while True:                         # k < N decreases: at most N reruns
        k = getattr(err, "step", None)
        if not isinstance(k, int) or k < 0 or k >= N:
            raise err
        if k == 0:
            return None, err
        try:
            return _charge(run(k, every), failure_counters(err)), err
        except LdasparkError as exc:
            err, N = exc, k


def _charge(res: Result, counters: Optional[dict]) -> Result:
    """``res`` with the counters ``counters`` (``FAILURE_COUNTERS``; None: its own)."""
    if counters is not None:
        for c in COUNTERS:
            setattr(res, c, counters[c])
        res.stats.update(counters)
        res.stats["mean_iterations"] = counters["newton_iterations"] / max(counters["steps"], 1)
    return res


def _guard_scan(res, exc, engine, prep, rerun=None) -> tuple:
    """The step-acceptance guard (``ldaspark.core.guard.judge``) on a run of a block engine: (the run
    up to the first step with another root, that RootMismatchError or ``exc``), the guard's
    counters in ``res.stats``. ``rerun(n)``: the first n steps again with every step kept (an
    engine that keeps samples ``save_every`` steps apart unless dense output, events or the energy
    monitor kept every step); None: ``res`` holds every step."""
    from .core import guard
    prob, opts, system = prep.prob, prep.opts, prep.system
    if res is None:
        return res, exc
    if not opts.guard:
        res.stats["guard"] = False
        return res, exc
    every = 1 if rerun is None or opts.every_step else opts.save_every
    st, cut = guard.judge(res, every, prob.h, lambda n, state, before: engine.resolve_step(prep, n, state, None, before),
                          rerun if every > 1 else None, 2 + 2 * system.n + system.m, opts.tol)
    res.stats.update(st)
    if cut is None:
        return res, exc
    n, err, steps = cut
    idx = np.arange(n + 1) if every == 1 else save_indices(n, every) if n > 0 else np.array([0])
    for nm in ("t", "q", "v", "energy", "constraint"):
        setattr(res, nm, np.asarray(getattr(steps, nm))[idx])
    res.psi = None if steps.psi is None else np.asarray(steps.psi)[idx[:-1]]
    return res, err


def _finish_prefix(res, exc, prep, start, engine, sliced=False) -> Result:
    """The run's Result: the prefix ``res`` (None: the initial point ``start`` = (t0, q0, v0)
    only) with the failure ``exc`` marked, then dense output, events and ``save_every`` (not for a
    run whose ``engine`` sliced it already; else with the engine's ``stage_solver``)."""
    system, opts, (t0, q0, v0) = prep.system, prep.opts, start
    every, dense, events = opts.save_every, opts.dense_output, opts.events
    if res is None:        # failure in the first step: the initial point only
        bk = Backend(None)
        q, v = bk.array(q0), bk.array(v0)
        # the stats every engine's Result carries (what ran, the guard), with no step accepted and
        # the failed step's work (the counters its error carries, ``core.result``)
        spent = add_counters(failure_counters(exc), None)
        stats = {**spent, "steps": 0, "mean_iterations": float(spent["newton_iterations"]), "path": engine.path,
                 "engine": prep.support, "root_finder": dict(prep.opts.newton.describe()), "guard": bool(opts.guard)}
        if opts.guard:      # no step judged: the guard's counters as a run of the same engine has them
            from .core.guard import counters
            stats.update(counters())
        # no step, no stage multipliers: an empty (0, s, m) psi as the generic engine's (None would
        # make an ensemble's batch psi None, and its file lose every member's)
        psi = np.zeros((0, prep.prob.what.s, system.m)) if prep.prob.kind == "spark" else None
        res = Result(np.array([float(t0)]), q[None], v[None], np.array([system.energy(bk, float(t0), q, v)]),
                     system.constraint(bk, float(t0), q, v)[None], psi, engine=engine.label, stats=stats,
                     **{c: spent[c] for c in COUNTERS})
    if exc is not None:
        (res.status, res.message), res.error = _failure(exc), exc
    stages = engine.stage_solver(prep) if (dense or events) and not sliced else None
    res = _post_process(res, every, dense, events, sliced, stages)
    # the accepted steps: up to the last good point (a monitor's cut or a terminal event: the
    # block ran further, its work is counted, its later steps are not the run's)
    # (in the run's numbers: at dps digits h may be below the float range, h = 1e-400 was 0.0)
    res.stats["steps"] = steps_between(t0, res.t[-1], prep.prob.h)
    return res
