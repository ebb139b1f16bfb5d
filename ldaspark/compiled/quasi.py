"""The quasi-Newton root finder of the SPARK step (21) on the compiled float64 engine
(``kernels_quasi``): ``run_quasi`` runs it on a compiled mechanical system and returns the
``FastSolution`` of ``runner.run_compiled`` with its counters; ``ldaspark.integrate(...,
engine="compiled", newton="quasi")`` reaches it through ``solve``.
"""
from __future__ import annotations

import threading
import time

import numpy as np

from ..core.errors import InputError

from .codegen import NotCompilableError
from .runner import STAT_NAMES, FastSolution, _check_options, _failure, kernel_spec, kernel_start, n_samples
from . import runner, specialised

#: the counters ``run_quasi`` adds to the stats of ``runner.run_compiled``: quasi-Newton
#: iterations, steps it solved, steps sent to the Newton chain, multiplier matrices factored,
#: steps sent there without an attempt (``kernels_quasi.QS_SKIPPED``), Hessian decompositions and
#: steps solved with the velocity block carrying Hess U (``kernels_quasi.curvature_matrix``) and
#: steps accepted after one increment by the rate carried from the previous steps
#: (``kernels_quasi.quasi_newton``'s eta, RADAU5's first-iteration test)
QUASI_STAT_NAMES = ("quasi_iterations", "quasi_steps", "quasi_fallbacks", "multiplier_lu", "quasi_skipped",
                    "curvature_refreshes", "curvature_steps", "rate_first_steps")


def lagrange_weights(nodes, points) -> np.ndarray:
    """W[i, p] = l_p(points[i]), the Lagrange basis of ``nodes`` (distinct) at ``points``."""
    nodes = np.asarray(nodes, float)
    W = np.ones((len(points), len(nodes)))
    for i, x in enumerate(points):
        for p, xp in enumerate(nodes):
            for r, xr in enumerate(nodes):
                if r != p:
                    W[i, p] *= (x - xr) / (xp - xr)
    return W


def extrapolation(c) -> tuple[np.ndarray, np.ndarray]:
    """(Ev, El) of the collocation predictor (``kernels_quasi.collocation_predict``): the velocity
    polynomial through (c_j, V_j) and (0, v0) (the node 0 only where no c_j is 0: Lobatto) at
    1 + c_i and 2, its weights on the stage nodes (the node 0 carries a zero increment); the
    multipliers' polynomial through (c_j, Psi_j) at 1 + c_i."""
    c = [float(x) for x in c]
    s = len(c)
    extra = [] if min(abs(x) for x in c) < 1e-12 else [0.0]
    Ev = lagrange_weights(c + extra, [1.0 + x for x in c] + [2.0])[:, :s]
    El = lagrange_weights(c, [1.0 + x for x in c])
    return np.ascontiguousarray(Ev), np.ascontiguousarray(El)


_LOCK = threading.Lock()
_ENTRY: dict = {}
_EXTRAP: dict = {}


def entry(form="mechanical"):
    """The compiled ``kernels_quasi.quasi_run`` (form "mechanical") or
    ``kernels_quasi_general.general_quasi_run`` ("general") for its one signature (compiled or
    loaded from numba's cache on first use)."""
    ep = _ENTRY.get(form)
    if ep is not None:
        return ep
    import warnings
    from numba.core.errors import NumbaExperimentalFeatureWarning
    from . import kernels, kernels_general, kernels_mech, kernels_quasi, kernels_quasi_general, newton
    from .cache import check_kernel_cache
    check_kernel_cache((kernels, kernels_general, kernels_mech, newton, kernels_quasi, kernels_quasi_general))
    with _LOCK:
        if form not in _ENTRY:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NumbaExperimentalFeatureWarning)
                if form == "mechanical":
                    disp, sig = kernels_quasi.quasi_run, kernels_quasi.QUASI_SIG
                else:
                    disp, sig = kernels_quasi_general.general_quasi_run, kernels_quasi_general.GENERAL_QUASI_SIG
                cres = disp.overloads.get(tuple(sig.args))
                _ENTRY[form] = cres.entry_point if cres is not None else disp.compile(sig)
    return _ENTRY[form]


def run_quasi(cs, method, t0, q0, v0, h, n_steps, every=1, compensated=True, tol=None, max_iter=50,
              predictor="collocation", curvature=True) -> FastSolution:
    """``runner.run_compiled`` with the quasi-Newton root finder (``kernels_quasi``): the same
    method (21), the same stopping rule and failure reports; mechanical form and SPARK tableaus
    only. predictor: "collocation" (IRKGaussLegendre.jl's, default) or 0, 1, 2 as
    ``run_compiled``. curvature: the velocity block frozen at I (x) M + h^2 (A^ A) (x) Hess U where
    it pays (``kernels_quasi.CURV_*``), else at M. A system in the general form runs
    ``kernels_quasi_general`` (the velocity block frozen at L_vv at the predictor; curvature does
    not apply); one with a nonideal term (3.3) is refused. stats adds QUASI_STAT_NAMES and
    root_finder = "quasi"."""
    if cs.form != "mechanical" and cs.model[-1]:     # an InputError: never run as something else
        raise InputError(f"{cs.name}: newton='quasi' takes ideal constraints only (this system has a nonideal "
                         "term N, section 3.3, which its frozen multiplier block leaves out); use the default "
                         "root finder")
    if isinstance(predictor, str) and predictor == "collocation":
        pflag = 3
        _check_options(n_steps, every, 2, tol, max_iter, cs.n, cs.m)
    else:
        _check_options(n_steps, every, predictor, tol, max_iter, cs.n, cs.m)
        pflag = int(predictor)
    kind, what, name = method if isinstance(method, tuple) else kernel_spec(method, "spark")
    if kind != "spark":
        raise InputError(f"newton='quasi' runs SPARK tableaus; {name} is a comparator")
    if cs.form == "mechanical" and not cs.mass_positive_definite:
        raise InputError(f"{cs.name}: newton='quasi' needs a symmetric positive definite mass matrix M (its frozen "
                         "velocity block is factored as M = L L^T); use the default root finder")
    q0, v0, h, tol = kernel_start(cs, q0, v0, h, tol)
    key = what[0].tobytes()
    ex = _EXTRAP.get(key)
    if ex is None:
        ex = _EXTRAP[key] = extrapolation(what[0])
    S = n_samples(int(n_steps), int(every))
    outs = (np.zeros(S), np.zeros((S, cs.n)), np.zeros((S, cs.n)), np.zeros(S), np.zeros((S, cs.m)))
    stats = np.zeros(len(STAT_NAMES), dtype=np.int64)
    qstats = np.zeros(len(QUASI_STAT_NAMES), dtype=np.int64)
    s_ = what[1].shape[0]
    NN = s_ * (cs.n + cs.m) + cs.n
    out_x = np.zeros(NN + (S - 1) * s_ * cs.m)
    special = False
    if cs.form == "mechanical":
        # the kernel specialised to (s, n, m) where it is built: the same bits, less CPU per step
        ep = specialised.kernel(s_, cs.n, cs.m)
        special = ep is not None
        # the generic kernel's CPU counts towards a build (``specialised.note``): timed only then
        timed = not special and specialised.enabled()
        c0 = time.process_time() if timed else 0.0
        (ep or entry())(cs.model, what, cs.M, cs.Minv, ex[0], ex[1], float(t0), q0, v0, h, int(n_steps), int(every),
                        bool(compensated), tol, int(max_iter), pflag, *outs, stats, out_x, qstats, bool(curvature))
        if timed:
            specialised.note(s_, cs.n, cs.m, time.process_time() - c0)
    else:
        entry("general")(cs.model, what, cs.M, ex[0], ex[1], float(t0), q0, v0, h, int(n_steps), int(every),
                         bool(compensated), tol, int(max_iter), pflag, *outs, stats, out_x, qstats)
    st = dict(zip(STAT_NAMES, (int(x) for x in stats)))
    if st["failed_step"] >= 0:
        raise _failure(st, name, float(t0), h, float(out_x[0]))
    for k in ("failed_step", "failure", "failed_iterations"):
        st.pop(k)
    st.update(zip(QUASI_STAT_NAMES, (int(x) for x in qstats)))
    # nlu counts LU factorisations on every engine (``Result``): here the multiplier matrices as
    # well as the Newton chain's (a quasi run said 0 after factoring one matrix a step); the
    # general form's s + 1 L_vv factorisations a step are counted in the kernel
    st["nlu"] += st["multiplier_lu"]
    st["mean_iterations"] = st["newton_iterations"] / max(st["steps"], 1)
    st.update(path="fast", kernel="quasi", form=cs.form, compensated=bool(compensated), linear_solver="dense",
              reuse_matrix=False, root_finder="quasi", newton_kind="quasi", kernel_specialised=special)
    return FastSolution(*outs, st, out_x[NN:].reshape(S - 1, s_, cs.m))


__all__ = ["run_quasi", "extrapolation", "QUASI_STAT_NAMES"]



def quasi_integrate(system, method, t0, q0, v0, h, n_steps, every=1, tol=None) -> FastSolution:
    """``fast.fast_integrate``'s checks (initial point, options) and ``run_quasi`` on the system's
    compiled model; what ``ldaspark.integrate(..., engine="compiled", newton="quasi")`` runs per
    chunk. No generic fallback: a system with a nonideal term, a comparator or a model that
    does not compile is refused (InputError), a step the Newton chain cannot solve raises
    NewtonError (``solve`` keeps the prefix and explains it with the generic step)."""
    from ..core.validate import real_number, real_vector, step_advances
    from .fast import _loaded, _setup_checks
    from .runner import compile_system
    real_number(h, "h", nonzero=True)
    real_number(t0, "t0")
    real_vector(q0, "q0")
    real_vector(v0, "v0")
    step_advances(t0, h, n_steps, None)
    _setup_checks(system, t0, q0, v0, _loaded(system))
    try:
        cs = compile_system(system)
        return run_quasi(cs, method, t0, q0, v0, h, n_steps, every, True, tol)
    except NotCompilableError as exc:
        raise InputError(f"newton='quasi' cannot run this: {exc}") from None


def _run_quasi_kind(cs, spec, start, grid, opts):
    """The "quasi" kind: ``compiled.quasi.run_quasi`` (the multiplier-only iteration of (21) with
    its fallback to this module's Newton chain). It solves the multiplier system densely and forms
    its matrix once per step: a sparse solver or matrix reuse asked for is refused, not ignored."""
    if opts.linear_solver not in ("auto", "dense"):
        raise InputError(f"newton kind 'quasi' on the compiled engine: linear_solver={opts.linear_solver!r} is not "
                         "honoured (it factors the (s m) x (s m) multiplier matrix densely); use 'auto' or 'dense'")
    if opts.reuse_matrix is True:
        raise InputError("newton kind 'quasi' on the compiled engine: reuse=True is not honoured (the multiplier "
                         "matrix is formed once per step at the predictor); use 'auto' or False")
    if spec[0] == "lf2" and spec[2] not in runner.LF2_VARIANTS:
        spec = runner.kernel_spec(spec[2], "spark")          # (25) is lobatto-iiia-iiib-2
    (t0, q0, v0), (h, n_steps, every) = start, grid
    # "auto" is the collocation predictor; "extrapolate" (the same kernel code 2) is the linear
    # extrapolation it names, not the default
    auto = opts.predictor in (None, 2, "auto") and opts.predictor_name == "auto"
    predictor = "collocation" if auto else opts.predictor
    return run_quasi(cs, spec, t0, q0, v0, h, n_steps, every, opts.compensated, opts.tol,
                     opts.max_iter if opts.max_iter is not None else 50, predictor)


runner.KIND_RUNNERS["quasi"] = _run_quasi_kind
