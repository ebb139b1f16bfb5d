"""The compiled engine's kernel runner: a system's generated model (``compile_system``,
``CompiledSystem``), the kernel description of a method (``kernel_spec``) and one kernel run
(``run_compiled`` -> ``FastSolution``), without fallback. Below ``fast`` (the entry points with
the fallbacks: ``fast_integrate``), ``rescue`` (the generic full-Newton step after a kernel
failure) and ``roundoff`` (the Kahan study), which all run kernels through it.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np
import sympy

from ..core.errors import InputError, LdasparkError, NewtonError, NonFiniteError
from ..core.rootfinder import Newton
from . import modeltypes as mt
from . import native
from .cache import CacheDirectoryError, load_source, source_key
from .codegen import NotCompilableError, fill_params, general_source, mechanical_source, nonideal_term

# comparator names with a specialised kernel: name -> lf2 variant
LF2_VARIANTS = {
    "lobatto-iiia-iiib-2-leapfrog": 0,
    "lobatto-iiia-iiib-2-modified": 1,
    "lobatto-iiia-iiib-2-modified-leapfrog": 1,
    "mp-lobatto-iiib-a-2": 2,
}
FAST_METHODS = ("any SPARK tableau (gauss-S, lobatto-iiia-iiib-S, lobatto-iiia-iiib-iiid-S, euler-i, euler-ii)",
                ) + tuple(LF2_VARIANTS)
STAT_NAMES = ("steps", "newton_iterations", "nfev", "njev", "nlu", "max_iterations", "failed_step", "failure",
              "full_newton_steps", "failed_iterations")
#: the work counters among STAT_NAMES (indices), kept across a kernel's dense retry
_WORK_STATS = tuple(STAT_NAMES.index(c) for c in ("newton_iterations", "nfev", "njev", "nlu"))


# --- mechanical form ---------------------------------------------------------------------
def mechanical_parts(system) -> dict:
    """(M, U, K, b) as sympy objects with L = 1/2 v^T M v - U, k = K v + b, M constant.

    Uses ``system.mechanical`` when set, else detects the form: L_vv free of t, q, v;
    grad_v L - M v = 0 (no gyroscopic terms); k_v free of v. Raises NotCompilableError."""
    if nonideal_term(system) is not None:
        raise NotCompilableError(f"{system.name}: a nonideal term (3.3) needs the general form")
    q, v, t = list(system.q), list(system.v), system.t
    mech = system.mechanical
    if mech is not None:
        from ..core.system import check_mechanical, completed_mechanical, refuse_text
        refuse_text(mech, f"{system.name}: mechanical")     # set by hand after construction: never sympify text
        check_mechanical(system, mech)                       # the generic engine's M (L_vv), symmetric
        mech = completed_mechanical(mech)                    # U and b default to 0, as on every engine
        M = _matrix(mech["M"])
        U = sympy.sympify(mech["U"], strict=True)
        K, b = mech["K"], mech["b"]
    else:
        # on the nonzero entries of the sparse derivation: the dense L_vv, M v and simplify of
        # every row cost 2.7 s at n = 121 (what a first integrate of such a system waited)
        from ..core.system import _derived_nonzeros, numerically_zero
        Mnz = _derived_nonzeros(system, "L_vv")
        if any(e.free_symbols & (set(q) | set(v) | {t}) for e in Mnz.values()):
            raise NotCompilableError(f"{system.name}: L_vv depends on (t, q, v); not mechanical form")
        zero_v = {x: 0 for x in v}
        Lv = _derived_nonzeros(system, "L_v")
        rows: dict = {}
        for (i, j), e in Mnz.items():
            rows.setdefault(i, []).append(e * v[j])
        for i in sorted(set(rows) | {i for i, _ in Lv}):
            gyro = Lv.get((i, 0), sympy.S.Zero) - sympy.Add(*rows.get(i, ()))
            # decided at random points (parameters too: one model serves every value), not by
            # sympy.simplify (minutes for a large power)
            if gyro != 0 and not numerically_zero(gyro, q + v + [t] + list(system.params), signs=True):
                raise NotCompilableError(f"{system.name}: grad_v L is not M v (terms linear in v); not mechanical "
                                         "form")
        M = sympy.SparseMatrix(system.n, system.n, Mnz)
        # xreplace, not subs: subs of n symbols walks L n times (2.3 s at n = 121)
        U = -system.L.xreplace(zero_v)
        K = system.k_v
        if K.free_symbols & set(v):
            raise NotCompilableError(f"{system.name}: k is not affine in v; not mechanical form")
        b = system.k.xreplace(zero_v)
    if _entry_symbols(M) - set(getattr(system, "params", ())):
        raise NotCompilableError(f"{system.name}: mass matrix M is not constant")
    return {"M": M, "U": U, "K": K, "b": b}


def _matrix(x):
    """A sympy matrix as it is (no copy: copying a dense 1001 x 1001 M cost 0.2 s), else Matrix(x)."""
    return x if isinstance(x, sympy.MatrixBase) else sympy.Matrix(x)


def _entry_symbols(M) -> set:
    """The free symbols of a sympy matrix's nonzero entries (MatrixBase.free_symbols visits all n^2)."""
    return set().union(*(e.free_symbols for e in M.todok().values()))


def _param_floats(system) -> tuple:
    """The system's parameter values as floats, in its ``params`` order (() without parameters)."""
    if not getattr(system, "params", ()):
        return ()
    vals = tuple(float(x) for x in system._param_arg_values(None))
    if not all(math.isfinite(x) for x in vals):
        raise NotCompilableError(f"{system.name}: a parameter value is not a finite float64 number")
    return vals


@dataclass
class CompiledSystem:
    """A system's generated model (source text, loaded lazily), its form ("mechanical" or
    "general") and, for the mechanical form, the constant M and M^-1. Picklable: a worker
    process rebuilds the module from the source text."""

    name: str
    n: int
    m: int
    source: str
    M: np.ndarray
    Minv: np.ndarray
    form: str = "mechanical"
    #: the values of the system's parameters (its ``params`` order) as floats: the source keeps
    #: the parameters symbolic (one model for all values), the run passes these
    params: tuple = ()

    @functools.cached_property
    def digest(self) -> str:
        return source_key(self.source)

    @functools.cached_property
    def mass_positive_definite(self) -> bool:
        """M symmetric positive definite (the mechanical form; False for the general form): what
        the quasi-Newton kernel's curvature block factors (M = L L^T, ``kernels_quasi``). A
        Lagrangian with an indefinite or negative kinetic term ((vx^2 - vy^2) / 2, -|v|^2 / 2) is a
        valid system (1) that the kernels' Newton solves, but not that factorisation."""
        if self.form != "mechanical":
            return False
        try:
            np.linalg.cholesky(self.M)
        except np.linalg.LinAlgError:
            return False
        return bool(np.array_equal(self.M, self.M.T))

    @property
    def model_id(self) -> tuple:
        """What identifies the model a run calls: the source's digest and the parameter values."""
        return (self.digest, self.params)

    @functools.cached_property
    def run_source(self) -> str:
        """The source with the parameter values filled in (the source itself without parameters):
        what numba compiles and the set-up checks run as Python."""
        return fill_params(self.source, self.params)

    @property
    def module(self):
        return load_source(self.run_source, digest=None if self.params else self.digest)

    @property
    def model(self):
        """The model tuple (n, functions...) as the kernels take it: each function as the address
        of its compiled code (numba's wrapper address protocol), built once per process: native
        code straight from LLVM (``native``: a fraction of a second) where the translator takes
        the source, else numba's compilation of the module; passing the dispatchers themselves
        would cost their type conversion at every call."""
        hit = _MODELS.get(self.model_id)
        if hit is None:
            if native.enabled():
                try:
                    hit = native.compile_model(self.source, self.params)
                except native.NotNativeError:
                    hit = None
            if hit is None:
                from numba.core.types.function_type import CompileResultWAP
                mod = self.module.MODEL
                hit = (mod[0],) + tuple(f if isinstance(f, bool) else CompileResultWAP(f.overloads[f.signatures[0]])
                                        for f in mod[1:])      # a general model ends with its flag has_N
            _MODELS[self.model_id] = hit
        return hit

    @property
    def is_native(self) -> bool:
        """True when this process runs the model as native code (``native``), False for numba's
        compilation; loads the model."""
        return isinstance(self.model[1], native.NativeFunction)

    @property
    def functions(self):
        """The model's functions callable from Python (the set-up checks): numba's module where
        this process compiled it, else the source as plain Python (nothing compiled)."""
        if self.model_id in _MODELS and not self.is_native:
            return self.module
        hit = _PYTHON.get(self.model_id)
        if hit is None:
            hit = _PYTHON[self.model_id] = native.python_module(self.run_source)
        return hit

    @functools.cached_property
    def hess_pattern(self):
        """The structurally nonzero (i, j) of the Newton matrix's q-blocks (mechanical form), or None."""
        return native.module_constants(self.source).get("HESS_PATTERN")

    @property
    def key(self) -> str:
        return self.digest[:20]

    def newton_structure(self):
        """The block structure of the Newton matrix (``sparse.NewtonStructure``) of a mechanical
        system, or None (general form, or a pattern too dense for the symbolic elimination's
        budget). Computed once per process and model."""
        if self.form != "mechanical":
            return None
        key = (self.digest, self.M.tobytes())       # M may hold parameter values
        if key not in _STRUCTURES:
            from .sparse import newton_structure
            pairs = self.hess_pattern
            _STRUCTURES[key] = None if pairs is None else newton_structure(self.n, pairs, self.M)
        return _STRUCTURES[key]


_MODELS: dict[str, tuple] = {}
_PYTHON: dict[str, object] = {}
_STRUCTURES: dict[str, object] = {}
#: ``linear_solver="auto"`` factors by blocks when the dense LU costs more than SPARSE_MARGIN
#: times the block factorisation's multiply-adds (the block code does more bookkeeping per flop;
#: measured: at a ratio dense/blocks of 2.1 (robot, n = 4) the dense LU was 2-20% faster, at 3.8
#: (mp-particles-nh, n = 7) the blocks 10-40% faster, gauss-2 to gauss-4)
SPARSE_MARGIN = 2.5
LINEAR_SOLVERS = ("auto", "dense", "sparse")
#: ``reuse_matrix="auto"`` reuses the Newton matrix across steps from this n on: measured on
#: mp-particles-nh (h = 0.01 at n = 7, 0.001 at n = 121, block solver), reuse saved 5-8% of a step
#: at n = 7 and 23-33% at n = 121 (gauss-2, gauss-3), with results equal to 6e-14; below this
#: size the saving is within noise and the paper's scenes keep one fresh matrix per step
REUSE_AUTO_MIN_N = 32


def _sparse_structure(cs, s, linear_solver):
    """The structure to factor by blocks with, or None for the dense LU."""
    if linear_solver not in LINEAR_SOLVERS:
        raise InputError(f"linear_solver must be one of {LINEAR_SOLVERS}, got {linear_solver!r}")
    if linear_solver == "dense" or cs.form != "mechanical":
        if linear_solver == "sparse":
            raise InputError(f"{cs.name}: linear_solver='sparse' needs a system in mechanical form")
        return None
    st = cs.newton_structure()
    if st is None:
        if linear_solver == "sparse":
            raise InputError(f"{cs.name}: the Newton matrix's pattern is too dense to factor by blocks")
        return None
    if linear_solver == "sparse":
        return st
    from .sparse import dense_flops
    return st if SPARSE_MARGIN * st.factor_flops(s, cs.m) < dense_flops(s, cs.n, cs.m) else None


_COMPILED: dict[tuple, tuple] = {}


def compile_system(system, form: str = "auto") -> CompiledSystem:
    """Generate (and cache per system object) the compiled model: the mechanical form where the
    system has it (``form="auto"`` or "mechanical"), else the general form (always for a
    nonideal term N(t, q, v, psi) of 3.3). The module itself
    is compiled at first use (``CompiledSystem.module``). Raises NotCompilableError."""
    if form not in ("auto", "mechanical", "general"):
        raise InputError(f"form must be 'auto', 'mechanical' or 'general', got {form!r}")
    key = (id(system), form)
    hit = _COMPILED.get(key)
    if hit is not None and hit[0] is system:
        return hit[1]
    # the copies ``with_params`` makes share the source system's ``_compiled`` store: one model
    # (generated for symbolic parameters) serves them all, so a new value costs no derivation
    shared = system.__dict__.get("_compiled") if getattr(system, "params", ()) else None
    tpl = None if shared is None else shared.get(("compiled.runner", form))
    if tpl is not None:
        try:
            cs = _with_values(system, tpl)
        except SingularMassError:
            if form == "mechanical":
                raise
            # M singular at these values only: the general form, as when they came first
            cs = compile_system(system, "general")
        _COMPILED[key] = (system, cs)
        return cs
    cs, by_value = None, False
    if form in ("auto", "mechanical"):
        try:
            cs = _mechanical(system)
        except NotCompilableError as exc:
            if form == "mechanical":
                raise
            # a mass matrix singular at these parameter values is no reason to give every other
            # value the general form: the form must not depend on the values run first
            by_value = isinstance(exc, SingularMassError) and shared is not None
    if by_value:
        cs = compile_system(system, "general")
    elif cs is None:
        eye = np.eye(system.n)
        cs = CompiledSystem(system.name, system.n, system.m, general_source(system), eye, eye, "general",
                            _param_floats(system))
    _COMPILED[key] = (system, cs)
    if shared is not None and not by_value:
        M = _mechanical_matrix(system) if cs.form == "mechanical" else None
        shared[("compiled.runner", form)] = (cs, M)
    return cs


class SingularMassError(NotCompilableError):
    """The mechanical form's M is singular (at the run's parameter values, for a system with
    parameters): no M^-1 for the mechanical kernels; the general form runs it."""


def _with_values(system, tpl):
    cs, Msym = tpl
    if Msym is None or not _entry_symbols(Msym):
        return dataclasses.replace(cs, name=system.name, params=_param_floats(system))
    M, Minv = _numeric_mass(system, Msym)
    return dataclasses.replace(cs, name=system.name, M=M, Minv=Minv, params=_param_floats(system))


def _mechanical_matrix(system):
    return mechanical_parts(system)["M"]


def _numeric_mass(system, Msym):
    M = np.zeros(Msym.shape)
    if _entry_symbols(Msym):                     # the mass matrix at this run's parameter values
        # xreplace of the nonzero entries (subs of the whole matrix cost 1.5 ms per run)
        vals = {p: sympy.sympify(x, strict=True) for p, x in zip(system.params, system._param_arg_values(None))}
        for (i, j), e in Msym.todok().items():
            M[i, j] = float(e.xreplace(vals))
    else:                                        # the nonzero entries (tolist of a 1001 x 1001 M: 1 s)
        for (i, j), e in Msym.todok().items():
            M[i, j] = float(e)
    try:
        Minv = np.linalg.inv(M)
    except np.linalg.LinAlgError:
        raise SingularMassError(f"{system.name}: mass matrix M is singular") from None
    return np.ascontiguousarray(M), np.ascontiguousarray(Minv)


def _mechanical(system):
    parts = mechanical_parts(system)
    M, Minv = _numeric_mass(system, parts["M"])
    return CompiledSystem(system.name, system.n, parts["K"].rows, mechanical_source(system, parts),
                          M, Minv, "mechanical", _param_floats(system))


def can_compile(system) -> tuple[bool, str]:
    """(True, form) when the compiled path takes the system, else (False, reason). Generates the
    model source (a few tenths of a second for small systems) but compiles nothing."""
    try:
        cs = compile_system(system)
    except NotCompilableError as exc:
        return False, str(exc)
    return True, cs.form


@dataclass
class FastSolution:
    """Samples at steps 0, every, 2 every, ..., and the last step (deprecated with ``fast_integrate``
    and ``run_compiled`` in favour of ``ldaspark.integrate``'s ``Result``). The first six fields are
    those of ``ldaspark.core.result.Result``, in its order (``LEADING_FIELDS``); the old positional
    order (t, q, v, energy, constraint, stats, psi) is still accepted. Unpacks as
    (t, q, v, energy, constraint, stats)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    energy: np.ndarray
    constraint: np.ndarray
    #: (samples - 1, s, m): the stage multipliers Psi_i of (21) of the step starting at each
    #: sample (None where the path does not form them: the semi-implicit kernel)
    psi: Optional[np.ndarray] = None
    stats: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        if isinstance(self.psi, dict) and not isinstance(self.stats, dict):    # the old order (..., stats, psi)
            self.psi, self.stats = self.stats, self.psi
        elif isinstance(self.psi, dict) and self.stats == {}:                  # the old (..., stats)
            self.psi, self.stats = None, self.psi

    def __iter__(self):
        return iter((self.t, self.q, self.v, self.energy, self.constraint, self.stats))


def n_samples(n_steps: int, every: int) -> int:
    return n_steps // every + 1 + (1 if n_steps % every else 0)


def _resolve(method):
    """method name or SparkTableau -> ("lf2", variant, name) or ("spark", tableau, name)."""
    from ..core.tableau import SparkTableau
    from ..core.families import get_method
    if isinstance(method, SparkTableau):
        return "spark", method, method.name
    if isinstance(method, str) and method in LF2_VARIANTS:
        return "lf2", LF2_VARIANTS[method], method
    try:
        return "spark", get_method(method), method
    except LdasparkError:
        raise InputError(f"unknown method {method!r} for the fast path; choose a SPARK name "
                         f"or one of {', '.join(LF2_VARIANTS)}") from None


_SPECS: dict = {}


def kernel_spec(method, kernel="auto"):
    """Picklable description of the kernel to run: ("lf2", variant, name) or
    ("spark", (c, A, A_hat, A_tilde, b, b_hat, b_tilde, omega) float64 arrays, name).
    ``kernel`` "auto" runs lobatto-iiia-iiib-2 with the semi-implicit kernel (the same method,
    (25)) on mechanical systems; "spark" forces the general kernel. Cached: the coefficients of a
    method name (or tableau object) are computed once per process."""
    if kernel not in ("auto", "spark"):
        raise InputError(f"kernel must be 'auto' or 'spark', got {kernel!r}")
    ck = (method if isinstance(method, str) else id(method), kernel)
    hit = _SPECS.get(ck)
    if hit is not None and (isinstance(method, str) or hit[0] is method):
        return hit[1]
    spec = _make_spec(method, kernel)
    _SPECS[ck] = (method, spec)
    return spec


def checked_kernel_spec(method, kernel="auto"):
    """``kernel_spec`` at a caller's boundary (``RunSpec``, ``fast_integrate``, ``run_kernels``):
    kernel="spark" of a comparator of Fig. 4 (``LF2_VARIANTS``: no SPARK tableau, the semi-implicit
    kernel runs it whatever ``kernel`` says) is refused, not accepted and ignored."""
    spec = kernel_spec(method, kernel)
    if kernel == "spark" and spec[0] == "lf2" and spec[2] in LF2_VARIANTS:
        raise InputError(f"kernel='spark' runs SPARK tableaus; {spec[2]} is a comparator of Fig. 4, which only the "
                         "semi-implicit kernel runs: use kernel='auto'")
    return spec


def _make_spec(method, kernel):
    kind, what, name = _resolve(method)
    if kind == "spark" and kernel == "auto" and what.name == "lobatto-iiia-iiib-2":
        return "lf2", 0, name
    if kind == "lf2":
        return "lf2", what, name
    ta = what.arrays(None)
    arr = [np.ascontiguousarray(np.asarray(getattr(ta, k), dtype=float)) for k in
           ("c", "A", "A_hat", "A_tilde", "b", "b_hat", "b_tilde")]
    arr.append(np.ascontiguousarray(np.asarray(ta.omega, dtype=float).reshape(max(what.s - 1, 0), what.s)))
    return "spark", tuple(arr), name


def _check_options(n_steps, every, predictor, tol, max_iter, n_dof, n_con):
    key = (type(n_steps), n_steps, type(every), every, type(predictor), predictor, type(tol), tol,
           type(max_iter), max_iter, n_dof, n_con)
    try:
        known = key in _OPTIONS_OK       # a repeated call's options passed already (types in the key:
    except TypeError:                    # True == 1, but predictor=True must still be refused)
        key, known = None, False         # unhashable option: the checks below say what is wrong
    if not known:
        _check_options_now(n_steps, every, predictor, tol, max_iter, n_dof, n_con)
    # the storage bound depends on the machine's memory, not on the options alone: checked at every
    # call (it was cached with them, so a run that fit once was never checked again)
    from ..core.validate import check_storage
    check_storage(n_samples(int(n_steps), int(every)), 2 + 2 * n_dof + n_con, what="the samples")
    if key is not None and not known:
        if len(_OPTIONS_OK) >= 256:
            _OPTIONS_OK.clear()
        _OPTIONS_OK.add(key)


#: option tuples (with their types) that passed ``_check_options_now``
_OPTIONS_OK: set = set()


def _check_options_now(n_steps, every, predictor, tol, max_iter, n_dof, n_con):
    from ..core.validate import MAX_STEPS, check_newton_options, count
    if predictor not in (0, 1, 2) or isinstance(predictor, bool):
        raise InputError(f"predictor must be 0, 1 or 2, got {predictor!r}")
    count(n_steps, "n_steps", 1, MAX_STEPS)     # 10**12 steps with a large every never end
    count(every, "every", 1, MAX_STEPS)
    check_newton_options(tol, max_iter)


def _kernels():
    """The kernels module, after ``cache.check_kernel_cache`` of the directory numba loads them
    from (at every call: cheap after the first, and a directory made unsafe since is refused)."""
    mods = _KERNEL_MODULES
    if not mods:
        from . import kernels       # cheap: a kernel compiles (or loads) on its first use, in _entry
        from . import kernels_general, kernels_mech, newton
        mods = _KERNEL_MODULES[:] = [(kernels, kernels_general, kernels_mech, newton)]
    from .cache import check_kernel_cache
    check_kernel_cache(mods[0])     # numba unpickles from there
    return mods[0][0]


#: [the kernel modules] once imported (``_kernels``)
_KERNEL_MODULES: list = []


# the kernels the main job's compiled-path jobs run (``reports.jobs.PRELUDE`` compiles them first)
MAIN_KERNELS = ("spark_run", "spark_sparse_run", "lf2_run")

_ENTRIES: dict[str, object] = {}


def _entry(name):
    """The compiled entry point of kernel ``name`` (one signature), compiled or loaded from
    numba's cache on first use. Calling it skips the dispatcher's typeof of every argument, which
    for the model tuple of function addresses costs ~0.3 ms per call; run_compiled builds every
    argument with exactly the signature's types."""
    ep = _ENTRIES.get(name)
    if ep is None:
        import warnings
        from numba.core.errors import NumbaExperimentalFeatureWarning
        with warnings.catch_warnings():
            # first-class function types are how the kernels take any system's model (see
            # kernels.py); numba flags them as experimental at compile time: noise for a user
            warnings.simplefilter("ignore", NumbaExperimentalFeatureWarning)
            ep = _kernels().entry_point(name)
        _ENTRIES[name] = ep
    return ep


def run_compiled(cs: CompiledSystem, method, t0, q0, v0, h, n_steps, every=1, compensated=True,
                 tol=None, max_iter=50, kernel="auto", predictor=2, reuse_matrix="auto", linear_solver="auto"):
    """Deprecated: ``ldaspark.integrate(..., engine="compiled", newton=ldaspark.Newton(...))`` runs
    the same kernels with every option (the root finder's fields included); this is
    ``run_kernels`` with a DeprecationWarning, the same results."""
    import warnings
    warnings.warn("run_compiled is deprecated: use ldaspark.integrate(..., engine='compiled', "
                  "newton=ldaspark.Newton(...))", DeprecationWarning, stacklevel=2)
    return run_kernels(cs, method, t0, q0, v0, h, n_steps, every, compensated, tol, max_iter, kernel, predictor,
                       reuse_matrix, linear_solver)


def run_kernels(cs: CompiledSystem, method, t0, q0, v0, h, n_steps, every=1, compensated=True,
                tol=None, max_iter=50, kernel="auto", predictor=2, reuse_matrix="auto", linear_solver="auto"):
    """Run a compiled kernel (no fallback); ``method`` a name, a SparkTableau or a kernel_spec.
    predictor: 2 = linear extrapolation of the last two steps' unknowns, 1 = last step's,
    0 = zero increments (V_i = v1 = v0, Psi = 0). linear_solver (SPARK kernels, mechanical
    form): "dense" LU of the whole Newton matrix, "sparse" block LU in a minimum-degree order
    with a Schur complement for the multipliers (``sparse``), "auto" the sparse one where its
    operation count is below 1/SPARSE_MARGIN of the dense one (large n with sparse Hess U and K),
    and the dense one when a block pivot is too small (the run is repeated with it).
    stats["linear_solver"] says which ran. reuse_matrix (SPARK kernels): start a step from the
    previous step's factored Newton matrix while it contracts fast (``kernels.REUSE_MATRIX``);
    "auto" = from n >= REUSE_AUTO_MIN_N. stats["reuse_matrix"] says whether it was on.
    Raises NewtonError, NonFiniteError."""
    _check_options(n_steps, every, predictor, tol, max_iter, cs.n, cs.m)
    if not isinstance(method, tuple):
        checked_kernel_spec(method, kernel)
    return _run_checked(cs, method, (t0, q0, v0), (h, n_steps, every),
                        KernelOptions(compensated, tol, max_iter, kernel, predictor, reuse_matrix, linear_solver))


_TOL_DEFAULT = 8 * float(np.finfo(float).eps)


@dataclass(frozen=True)
class KernelOptions:
    """How a compiled kernel runs (``run_compiled``'s keywords, checked by ``_check_options``):
    carried as one object to the kernel call."""
    compensated: bool = True
    tol: Optional[float] = None
    max_iter: int = 50
    kernel: str = "auto"
    predictor: int = 2
    reuse_matrix: object = "auto"
    linear_solver: str = "auto"
    #: the root finder's kind as the SPARK kernels run it (``kernels.NEWTON_MODE``): 0 "auto",
    #: 1 "full" (and "mixed", which is "full" in float64), 2 "simplified"; ``NEWTON_MODES``
    newton_mode: int = 0
    #: the root finder's kind by name (``ldaspark.core.rootfinder.KINDS``): a kind in
    #: ``KIND_RUNNERS`` runs there instead of the kernels' Newton
    newton_kind: str = "auto"
    #: the predictor by name (``ldaspark.core.rootfinder.PREDICTORS``): "auto" and "extrapolate"
    #: share the kernels' code 2, but a kind with a default predictor of its own (the quasi
    #: iteration's collocation predictor) runs that one for "auto" only
    predictor_name: str = "auto"


#: root-finder kind -> the SPARK kernels' Newton mode (``kernels.NEWTON_MODE``). A kind run by
#: its own module (e.g. a multiplier-only quasi-Newton iteration) registers a runner in
#: ``KIND_RUNNERS`` instead: ``KIND_RUNNERS[kind](cs, spec, start, grid, opts) -> FastSolution``
NEWTON_MODES = {"auto": 0, "full": 1, "mixed": 1, "simplified": 2, "quasi": 0}
KIND_RUNNERS: dict = {}          # "quasi": registered by ``compiled.quasi`` when imported



def auto_runs_quasi(cs, spec, opts: KernelOptions) -> bool:
    """Whether the root finder "auto" runs the quasi-Newton iteration (``compiled.quasi``, issue
    48; the same method (21) to the same stopping rule, with a per-step fallback to the kernels'
    Newton where it contracts slowly). Chosen per run where it was measured faster than the
    kernels' Newton (docs/performance.md, "The quasi-Newton step"; ``reports/quasi_step.json``,
    ``per_step``): SPARK
    tableaus on the SPARK kernel (lobatto-iiia-iiib-2 keeps the semi-implicit kernel (25)), the
    mechanical form with M positive definite (the general form's quasi step was measured no faster), n below the size from
    which the Newton matrix is reused or factored by blocks (not measured there), and no linear
    solver, matrix reuse or kernel asked for (an explicit one is a request for the kernels' Newton)."""
    if spec[0] != "spark" or cs.form != "mechanical" or cs.n >= REUSE_AUTO_MIN_N or not cs.mass_positive_definite:
        return False
    if not (isinstance(opts.reuse_matrix, str) and opts.reuse_matrix == "auto" and opts.linear_solver == "auto"
            and opts.kernel == "auto"):
        return False
    return _sparse_structure(cs, spec[1][1].shape[0], "auto") is None


def kernel_start(cs, q0, v0, h, tol) -> tuple:
    """(q0, v0, h, tol) as a kernel takes them: fresh contiguous float64 copies of q0, v0 (the
    kernel may not alias the caller's), h a nonzero finite float, tol the default where None;
    InputError for a wrong size or a NaN / inf."""
    q0 = np.array(q0, dtype=float)
    v0 = np.array(v0, dtype=float)
    if q0.shape != (cs.n,) or v0.shape != (cs.n,):
        raise InputError(f"initial data must have n = {cs.n} entries")
    h = float(h)
    if not (math.isfinite(h) and h != 0 and np.isfinite(q0).all() and np.isfinite(v0).all()):
        raise InputError("initial data or step size contain NaN/inf, or h = 0")
    return q0, v0, h, (_TOL_DEFAULT if tol is None else float(tol))


def _run_checked(cs, method, start, grid, opts: KernelOptions):
    """``run_compiled`` after ``_check_options`` passed (fast_integrate checks them once, before
    compiling; checking twice was ~3 us of a repeated short call's overhead): ``start`` =
    (t0, q0, v0), ``grid`` = (h, n_steps, every)."""
    (t0, q0, v0), (h, n_steps, every) = start, grid
    compensated, tol, max_iter, kernel, predictor = (opts.compensated, opts.tol, opts.max_iter, opts.kernel,
                                                     opts.predictor)
    reuse_matrix, linear_solver = opts.reuse_matrix, opts.linear_solver
    spec = method if isinstance(method, tuple) else kernel_spec(method, kernel)
    if opts.newton_kind == "auto" and auto_runs_quasi(cs, spec, opts):
        opts = dataclasses.replace(opts, newton_kind="quasi")   # registered by the package (__init__)
    if opts.newton_kind in KIND_RUNNERS:      # a root-finder kind with a module of its own
        return KIND_RUNNERS[opts.newton_kind](cs, spec, start, grid, opts)
    kind, what, name = spec
    if kind == "lf2" and cs.form != "mechanical":
        if name in LF2_VARIANTS:
            raise NotCompilableError(f"{cs.name}: {name} needs a system in mechanical form")
        kind, what, name = kernel_spec(name, "spark")        # (25) is lobatto-iiia-iiib-2
    if kind == "lf2":   # no block LU, no matrix reuse in the semi-implicit kernel: refused, never ignored
        Newton(linear_solver=linear_solver,
               reuse="auto" if isinstance(reuse_matrix, str) else bool(reuse_matrix)).check_for("compiled-lf2")
    q0, v0, h, tol = kernel_start(cs, q0, v0, h, tol)
    S = n_samples(int(n_steps), int(every))
    outs = (np.zeros(S), np.zeros((S, cs.n)), np.zeros((S, cs.n)), np.zeros(S), np.zeros((S, cs.m)))
    stats = np.zeros(len(STAT_NAMES), dtype=np.int64)
    # reuse_matrix (SPARK kernels): the previous step's Newton matrix (kernels.REUSE_MATRIX)
    full = kind != "lf2" and int(opts.newton_mode) == NEWTON_MODES["full"]
    if isinstance(reuse_matrix, str) and reuse_matrix == "auto":
        # full Newton forms the matrix at every iteration: the kernels drop the reuse bit there
        reuse_matrix = cs.n >= REUSE_AUTO_MIN_N and not full
    elif not isinstance(reuse_matrix, (bool, np.bool_)):
        raise InputError(f"reuse_matrix must be True, False or 'auto', got {reuse_matrix!r:.60}")
    elif reuse_matrix and full:
        raise InputError(f"newton kind '{opts.newton_kind}' on the compiled engine: reuse=True is not honoured "
                         "(full Newton forms the Newton matrix at every iteration); use 'auto' or False, or the "
                         "kind 'simplified' or 'auto'")
    pflag = int(predictor) + (4 if reuse_matrix else 0) + 8 * int(opts.newton_mode)
    run = (float(t0), q0, v0, h, int(n_steps), int(every), bool(compensated), tol, int(max_iter), pflag)
    model = cs.model
    solver = "dense"
    if kind == "lf2":
        _entry("lf2_run")(model, int(what), cs.M, cs.Minv, *run, *outs, stats)
    else:
        s_ = what[1].shape[0]
        NN = s_ * (cs.n + cs.m) + cs.n
        out_x = np.zeros(NN + (S - 1) * s_ * cs.m)          # the last unknowns, then psi per sample
        structure = _sparse_structure(cs, what[1].shape[0], linear_solver)
        solver = _spark_kernel(cs, what, run, outs, stats, out_x, structure, linear_solver == "auto")
    st = dict(zip(STAT_NAMES, stats.tolist()))          # Python ints
    if st["failed_step"] >= 0:
        # the SPARK kernels leave the residual at the last iterate in out_x[0] (kernels.spark_loop)
        raise _failure(st, name, float(t0), h, None if kind == "lf2" else float(out_x[0]))
    st.pop("failed_step")
    st.pop("failure")
    st.pop("failed_iterations")
    st["mean_iterations"] = st["newton_iterations"] / max(st["steps"], 1)
    st["path"] = "fast"
    st["kernel"] = "lf2" if kind == "lf2" else ("spark" if cs.form == "mechanical" else "general")
    st["form"] = cs.form
    st["compensated"] = bool(compensated)
    st["linear_solver"] = solver
    st["reuse_matrix"] = bool(reuse_matrix) and kind != "lf2"
    # what ran (``Result.stats["root_finder"]["runs"]``): "mixed" is full Newton in float64
    st["newton_kind"] = "lf2" if kind == "lf2" else "full" if opts.newton_kind == "mixed" else opts.newton_kind
    psi = None if kind == "lf2" else out_x[NN:].reshape(S - 1, s_, cs.m)
    return FastSolution(*outs, psi=psi, stats=st)


def _spark_kernel(cs, what, run, outs, stats, out_x, structure, retry_dense) -> str:
    """One call of the SPARK kernel over ``run`` into zeroed ``outs``, ``stats``, ``out_x``: the
    block-sparse one for ``structure`` (not None), else the dense one of the system's form; the
    solver that ran ("sparse" or "dense"). retry_dense: a run the block LU fails with a singular
    matrix is repeated with the dense LU (its unpivoted block order can meet a zero pivot the
    dense LU pivots past)."""
    if structure is not None:
        _entry("spark_sparse_run")(cs.model, what, cs.M, *run, *outs, stats, out_x, *structure.arrays())
        if retry_dense and stats[mt.FAILED_STEP] >= 0 and stats[mt.FAILURE] == mt.FAIL_SINGULAR:
            # the block-LU attempt's work stays counted (``Result``: every retry is work done)
            spent = {i: int(stats[i]) for i in _WORK_STATS}
            for arr in outs + (stats, out_x):
                arr[...] = 0
        else:
            return "sparse"
    else:
        spent = {}
    _entry("spark_run" if cs.form == "mechanical" else "general_run")(cs.model, what, cs.M, *run, *outs, stats,
                                                                       out_x)
    for i, c in spent.items():
        stats[i] += c
    return "dense"


class StageSolver:
    """The stage velocities V_i (s, n) of one SPARK step (21) from a saved point (t, q, v): the
    SPARK kernel (the mechanical or general form; lobatto-iiia-iiib-2 too, whose runs take the
    semi-implicit kernel (25) of the same method) run for one step with full Newton from the
    generic engine's starting guess (V_i = v1 = v, Psi = 0); the kernels leave the step's unknowns
    x = [Z | Lambda | dv] in out_x[:NN] and V_i = v + Z_i. Used by the driver for the dense
    output and the events of a compiled run, which keeps no stage values (``solve._post_process``).

    ``solver(t, q, v, h)`` -> (V (s, n), q1, v1), or None when the kernel's Newton fails there."""

    def __init__(self, cs: CompiledSystem, tableau, tol=None, max_iter=50):
        kind, what, _ = kernel_spec(tableau, "spark")
        self.cs, self.what = cs, what
        self.s = what[1].shape[0]
        self.NN = self.s * (cs.n + cs.m) + cs.n
        self.tol = _TOL_DEFAULT if tol is None else float(tol)
        self.max_iter = int(max_iter)
        self.outs = (np.zeros(2), np.zeros((2, cs.n)), np.zeros((2, cs.n)), np.zeros(2), np.zeros((2, cs.m)))
        self.stats = np.zeros(len(STAT_NAMES), dtype=np.int64)
        self.out_x = np.zeros(self.NN)          # the step's unknowns only (no multipliers stored)
        self.structure = _sparse_structure(cs, self.s, "auto")

    def __call__(self, t, q, v, h):
        q0 = np.array(q, dtype=float)
        v0 = np.array(v, dtype=float)
        # predictor 0 (zero increments), no matrix reuse, Newton mode 1 (full): ``kernels.NEWTON_MODE``
        run = (float(t), q0, v0, float(h), 1, 1, True, self.tol, self.max_iter, 8 * NEWTON_MODES["full"])
        for arr in self.outs + (self.stats, self.out_x):
            arr[...] = 0
        _spark_kernel(self.cs, self.what, run, self.outs, self.stats, self.out_x, self.structure, True)
        if self.stats[mt.FAILED_STEP] >= 0:
            return None
        V = v0[None, :] + self.out_x[:self.s * self.cs.n].reshape(self.s, self.cs.n)
        return V, self.outs[1][1].copy(), self.outs[2][1].copy()


def _failure(st, name, t0, h, residual=None):
    """The error of a kernel run that failed at step st["failed_step"], carrying the run's
    counters (``core.result.attach_counters``: the accepted steps and the work of every step,
    the failed step's whole fallback chain included)."""
    from ..core.result import attach_counters
    return attach_counters(_failure_error(st, name, t0, h, residual), st)


def _failure_error(st, name, t0, h, residual=None):
    k = st["failed_step"]
    tk = t0 + k * h
    where = f"step {k}, t = {tk:.6g}, h = {h:.3g}"
    if st["failure"] == mt.FAIL_NONFINITE:
        return NonFiniteError(f"fast path ({name}): NaN or inf at {where} (L or k evaluated outside "
                              "their domain, or overflow)", step=k, time=tk)
    why = "singular Newton matrix" if st["failure"] == mt.FAIL_SINGULAR else "Newton failed"
    it = st["failed_iterations"]
    # SPARK kernels: simplified Newton, fresh matrices, then full Newton all failed at this step
    chain = "" if residual is None else " (simplified, fresh-matrix and full Newton)"
    res = "" if residual is None else f"residual {residual:.3e} after "
    return NewtonError(f"fast path ({name}): {why} at {where}: {res}{it} iterations{chain}", step=k, time=tk,
                       residual=residual, iterations=it)
