"""Lagrangian systems with nonholonomic constraints (1): L(t, q, v) and k(t, q, v).

A scene states L and k as sympy expressions (or the mechanical form M, U, K, b); everything
else is derived here: grad_q L, grad_v L, the Hessians, K = k_v (1d), k_q, k_t, the energy (8)
and the saddle matrix (4). Derived expressions are compiled with ``sympy.lambdify`` once per
number type ("math" for float64, "mpmath" for arbitrary precision).
"""
from __future__ import annotations

import math
import sys
import warnings
from dataclasses import dataclass

import mpmath
import numpy as np
import sympy

from .backend import Backend, SingularMatrixError, fmt
from . import gensource
from .derive import install, real_jacobian  # noqa: F401 (real_jacobian: its old home)
from .gensource import SUPPORTED_FUNCTIONS  # noqa: F401 (its old home)
from .errors import InconsistentInitialDataError, LdasparkWarning, SingularSaddleError, SystemDefinitionError


@dataclass
class StageEval:
    """Values at one point (T, Q, V, Lambda), with Lambda = h Psi the scaled multiplier.

    R_lam = -K^T Lambda is h R of (21); its partials R_q, R_v enter the Newton matrix."""

    L_v: np.ndarray
    L_q: np.ndarray
    k: np.ndarray
    R_lam: np.ndarray
    L_vv: np.ndarray | None = None
    L_vq: np.ndarray | None = None
    L_qv: np.ndarray | None = None
    L_qq: np.ndarray | None = None
    k_q: np.ndarray | None = None
    k_v: np.ndarray | None = None
    R_q: np.ndarray | None = None
    R_v: np.ndarray | None = None
    R_L: np.ndarray | None = None      # d(h R)/d Lambda (n x m); None means -K^T (ideal constraints)


#: the derived expressions of ``_derive`` (mapped back from real dummies when L or k are nonsmooth)
_DERIVED = ("L_q", "L_v", "L_vv", "L_vq", "L_qq", "L_vt", "L_t", "k_q", "k_v", "k_t", "R_lam", "R_q", "R_v",
            "energy_expr", "N_q", "N_v", "N_psi")
#: derivatives of the nonsmooth functions (Abs' = sign, sign' = 2 DiracDelta, Heaviside' =
#: DiracDelta) are evaluated almost everywhere: DiracDelta is 0 off its support, which is what
#: Newton's matrix needs (the Jacobian of a piecewise-smooth residual)
_NONSMOOTH = {"DiracDelta": lambda *a: 0, "Heaviside": lambda x, *a: 0 if x < 0 else (1 if x > 0 else 0.5)}


class LagrangianSystem:
    """A Lagrangian system with ideal nonholonomic constraints (1a-d), or nonideal ones (3.3).

    The library derives grad_q L, grad_v L, the Hessians, k_q, k_v, k_t, the energy (8) and
    the saddle matrix (4) from L and k.

    Parameters
    ----------
    L : sympy expression or str
        The Lagrangian L(t, q, v).
    k : list of sympy expressions or str
        The m constraints 0 = k(t, q, v) (1c).
    q, v : list of sympy symbols
        The n coordinates and their velocities.
    t : sympy symbol, optional
        The time symbol (optional when L and k are autonomous).
    name : str, optional
        A name for reports and messages.
    mechanical : dict, optional
        Sympy M, U, K, b when L = 1/2 v^T M v - U(q) and k = K(q) v + b(q) (M symmetric); the
        compiled engine's mechanical-form kernels use it (the quasi-Newton iteration, the block
        solver). Without it that form is detected from L and k (M constant, no gyroscopic
        terms, k affine in v; ``Result.stats["form"]`` says which form ran).
    params : list or dict, optional
        Free symbols of L and k kept symbolic (a list, or a dict symbol -> default value):
        derivation happens once; values are given later (`with_params` or
        ``integrate(..., params=...)``).
    nonideal : list of sympy expressions, optional
        N(t, q, v, psi) added to (1b) (section 3.3): d/dt grad_v L = grad_q L - K^T psi + N;
        the SPARK stages take R_i = -K_i^T Psi_i + N(T_i, Q_i, V_i, Psi_i), entering (21b, d)
        with A_tilde, b_tilde.
    psi : list of sympy symbols, optional
        Names of the m multipliers in ``nonideal`` (default psi1..psim).

    Raises
    ------
    SystemDefinitionError
        When an expression, a symbol list or a parameter is invalid (an ``LdasparkError``, not
        an ``InputError``).

    See Also
    --------
    integrate : integrate the system by a SPARK method.

    Examples
    --------
    >>> import sympy, ldaspark
    >>> x, y, vx, vy = sympy.symbols("x y vx vy")
    >>> sysm = ldaspark.LagrangianSystem((vx**2 + vy**2) / 2, [vy - x * vx], [x, y], [vx, vy])
    >>> sysm.n, sysm.m
    (2, 1)
    """

    def __init__(self, L, k, q, v, t=None, name: str = "system", mechanical: dict | None = None,
                 params=None, nonideal=None, psi=None):
        L, k, q, v, t, params, nonideal, psi, mechanical = _parse_strings(L, k, q, v, t, params, nonideal, psi,
                                                                           mechanical)
        self.name = name
        self.q = list(q)
        self.v = list(v)
        self.t = t if t is not None else sympy.Symbol("t")
        self.n = len(self.q)
        if len(self.v) != self.n:
            raise SystemDefinitionError(f"q has {self.n} symbols but v has {len(self.v)}")
        from .validate import check_symbols
        check_symbols(self.q, self.v)       # q = [x, x, z] or q equal to v: one clear error
        self.L, self.k = _sympify_L_k(L, k)
        self.m = self.k.rows
        if self.m >= self.n:
            raise SystemDefinitionError(f"need m < n constraints, got m = {self.m}, n = {self.n}")
        nonideal_exprs = [] if nonideal is None else [sympy.sympify(e) for e in nonideal]
        # first, before any recursive walk of sympy's: every node known (an undefined function
        # refused by name), the nesting bounded (gensource: no user text in generated source)
        _check_functions([("L", self.L)] + [(f"k[{i}]", e) for i, e in enumerate(self.k)]
                         + [(f"nonideal[{i}]", e) for i, e in enumerate(nonideal_exprs)]
                         + _mechanical_exprs(mechanical))
        self.params, self._param_values = _parse_params(params)
        clash = set(self.params) & (set(self.q) | set(self.v) | {self.t})
        if clash:
            raise SystemDefinitionError(f"{', '.join(sorted(map(str, clash)))} cannot be a parameter: it is a "
                                        "coordinate, a velocity or the time")
        self.lam = sympy.symbols(f"lam0:{self.m}")
        self.psi = list(psi) if psi is not None else list(sympy.symbols(f"psi1:{self.m + 1}"))
        _check_names(self, nonideal_exprs)
        allowed = set(self.q) | set(self.v) | {self.t} | set(self.params)
        extra = (self.L.free_symbols | self.k.free_symbols) - allowed
        if extra:
            raise SystemDefinitionError(
                f"L or k contain symbols other than t, q, v: {sorted(map(str, extra))}; "
                "substitute them or declare them with params=[...]")
        _check_infinite_constants([("L", self.L)] + [(f"k[{i}]", e) for i, e in enumerate(self.k)]
                                  + [(f"nonideal[{i}]", e) for i, e in enumerate(nonideal_exprs)])
        _check_denominators(self, [self.L, *self.k, *nonideal_exprs])
        self.mechanical = mechanical
        self.N = None
        if nonideal is not None:
            self.N = sympy.Matrix([sympy.sympify(e) for e in nonideal])
            if self.N.rows != self.n or len(self.psi) != self.m:
                raise SystemDefinitionError(f"nonideal term needs n = {self.n} components in m = {self.m} "
                                            f"psi symbols, got {self.N.rows} and {len(self.psi)}")
            extra = self.N.free_symbols - allowed - set(self.psi)
            if extra:
                raise SystemDefinitionError(f"nonideal term N contains symbols other than t, q, v, psi: "
                                            f"{sorted(map(str, extra))}")
        self._derive()
        # what the derivation saw (``check_as_built``): sympy objects, immutable, compared by identity
        self._built = {"L": self.L, "k": self.k, "N": self.N}
        d = self._derived
        if d.engine == "sympy":
            # symengine differentiates only the functions of _SE_NODES, whose derivatives stay
            # among them; sympy's (Abs, sign, sinc, ...) are checked, sparse, not made attributes
            _check_functions([(f"{key}{ij}", e) for key in _DERIVED if key in d
                              for ij, e in d.nonzeros(key).items()], derived=True)
        if self.mechanical is not None:
            check_mechanical(self, self.mechanical)
        _check_build(self)
        self._compiled = {}
        self._fn_exprs = {}

    @classmethod
    def mechanical_form(cls, M, U, K, b=None, q=None, v=None, name="system", params=None, t=None):
        """L = 1/2 v^T M v - U(q), k = K(q) v + b(q) (section 7); M, K sympy matrices. U, K and b
        may also depend on the time t (the symbol ``t``, by that name in text too, or the symbol
        given as ``t``); ``params`` as in LagrangianSystem (M, U, K, b may contain them)."""
        n = _matrix_rows(M, f"{name}: M")
        # None (not any falsy value: q=[] or an empty array is a wrong length, not the default)
        q = _symbol_list(q, "q") if q is not None else list(sympy.symbols(f"q0:{n}"))
        v = _symbol_list(v, "v") if v is not None else list(sympy.symbols(f"v0:{n}"))
        t = _time_symbol(t) if t is not None else sympy.Symbol("t")     # the constructor's default t
        # the names text may use: those of LagrangianSystem (q, v, t, the parameters)
        pnames = [_symbol(p, "parameter") for p in params] if isinstance(params, (list, tuple, dict)) else []
        names = _names(q, v, [t], pnames)
        M, U, K, b = (_exprs(x, names, what) for x, what in ((M, "M"), (U, "U"), (K, "K"), (b, "b")))
        try:
            M = sympy.Matrix(M)
            K = sympy.Matrix(K)
            b = sympy.zeros(K.rows, 1) if b is None else sympy.Matrix(b)
        except (TypeError, ValueError, sympy.SympifyError) as exc:
            raise SystemDefinitionError(f"{name}: M, K and b must be matrices ({str(exc)[:80]})") from None
        n = M.rows
        if M.shape != (n, n) or len(q) != n or len(v) != n:
            raise SystemDefinitionError(f"{name}: M must be n x n with n = len(q) = len(v), got M {M.shape}, "
                                        f"{len(q)} coordinates")
        if K.cols != n or b.shape != (K.rows, 1):
            raise SystemDefinitionError(f"{name}: K must be m x n (n = {n}) and b m x 1, got K {K.shape}, b {b.shape}")
        if isinstance(U, (list, tuple, np.ndarray, sympy.MatrixBase)):
            raise SystemDefinitionError(f"{name}: U must be one scalar expression, got {type(U).__name__}")
        U = _scalar_expr(U, f"{name}: U")
        vv = sympy.Matrix(v)
        L = (vv.T * M * vv)[0, 0] / 2 - U
        k = list(K * vv + b)
        return cls(L, k, q, v, t=t, name=name, mechanical={"M": M, "U": U, "K": K, "b": b}, params=params)

    @classmethod
    def from_mechanics(cls, model, q=None, constraints=None, params=None, name: str = "system"):
        """From a ``sympy.physics.mechanics`` KanesMethod, LagrangesMethod or System, or a
        Lagrangian and velocity constraints in dynamicsymbols; see ``ldaspark.core.mechanics``."""
        from .mechanics import from_mechanics
        return from_mechanics(model, q=q, constraints=constraints, params=params, name=name, cls=cls)

    # --- parameters ----------------------------------------------------------------------------
    def not_a_parameter(self, key) -> str:
        """The note of a value given for ``key``, which is no parameter of the model (``with_params``)."""
        return (f"{self.name}: {key} is not a parameter "
                f"(parameters: {', '.join(map(str, self.params)) or 'none'}); its value is ignored")

    def with_params(self, values=None, **by_name) -> "LagrangianSystem":
        """A view of this system with parameter values set (symbol or name -> number); shares
        the derived expressions and compiled functions, so nothing is derived again."""
        import copy
        new = copy.copy(self)
        # the new system owns its parameter store and its containers (a store shared with the
        # source would let one system's values leak into the other); the derived expressions are
        # immutable sympy objects and the lambdified functions take the parameters as trailing
        # arguments, so sharing those (``_compiled``, ``_fn_exprs``) is safe
        new._param_values = dict(self._param_values)
        new.q, new.v, new.psi = list(self.q), list(self.v), list(self.psi)
        new.mechanical = None if self.mechanical is None else dict(self.mechanical)
        if values is not None and not isinstance(values, dict):
            raise SystemDefinitionError(f"{self.name}: with_params takes a dict {{parameter: value}} (or "
                                        f"keywords), got {type(values).__name__}")
        items = list((values or {}).items()) + list(by_name.items())
        names = {str(p): p for p in self.params}
        given = {}
        for key, val in items:
            sym = key if key in self.params else names.get(str(key))
            if sym is None:
                # a value for a symbol the model does not use changes nothing, so it is accepted
                # with a note (a shared params dict over several models is the usual cause); a
                # misspelled name still fails, as the missing value of the real parameter
                warnings.warn(self.not_a_parameter(key), LdasparkWarning, stacklevel=2)
                continue
            new._param_values[sym] = (_check_assumptions(sym, _param_value(val, sym)) if isinstance(val, str)
                                      else _checked_param(sym, val))
            # one parameter named twice ("m" and Symbol("m"), or a dict and a keyword): two
            # different values are refused (the last one ran and the other was dropped silently)
            if sym in given and (_param_value(new._param_values[sym], sym) - _param_value(given[sym], sym)).is_zero \
                    is not True:
                raise SystemDefinitionError(f"{self.name}: parameter {sym} is given twice, as {given[sym]!r} and "
                                            f"{new._param_values[sym]!r}: give it one value")
            given[sym] = new._param_values[sym]
        return new

    def param_values(self) -> dict:
        """Current values {symbol: value} (may be incomplete)."""
        return dict(self._param_values)

    def substituted(self) -> "LagrangianSystem":
        """A parameter-free system with the current values substituted (derives again; used by
        the compiled path and the comparators, which generate code from the expressions)."""
        if not self.params:
            return self
        vals = self._param_arg_values(None)
        sub = {p: _param_value(x, p) for p, x in zip(self.params, vals)}
        mech = None
        if self.mechanical is not None:
            refuse_text(self.mechanical, f"{self.name}: mechanical")    # set by hand: never sympify text
            # parts given as lists of rows (or arrays) are matrices (sympify keeps a list, without subs)
            mech = {key: None if val is None else (sympy.Matrix(val) if isinstance(val, (list, tuple, np.ndarray))
                                                   else sympy.sympify(val)).subs(sub)
                    for key, val in self.mechanical.items()}
        N = None if self.N is None else [e.subs(sub) for e in self.N]
        return LagrangianSystem(self.L.subs(sub), [e.subs(sub) for e in self.k], self.q, self.v, self.t,
                                name=self.name, mechanical=mech, nonideal=N, psi=self.psi)

    def _param_arg_values(self, backend):
        missing = [str(p) for p in self.params if p not in self._param_values]
        if missing:
            raise SystemDefinitionError(f"{self.name}: no value for parameter(s) {', '.join(missing)} "
                                        "(pass params={...} to integrate, or use system.with_params)")
        vals = [self._param_values[p] for p in self.params]
        return vals if backend is None else [backend.scalar(x) for x in vals]

    # --- symbolic derivation ----------------------------------------------------------------
    def _derive(self):
        # sparse derivatives (symengine where it differentiates every node), kept in
        # self._derived and made sympy attributes (self.L_vv, ...) at first use by __getattr__
        install(self)

    def __getattr__(self, name):
        d = self.__dict__.get("_derived")
        if name in ("N_q", "N_v", "N_psi") and d is not None:
            check_as_built(self)            # N set by hand: its partials were never derived
        if d is None or name not in _DERIVED or name not in d:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        val = self.__dict__[name] = d.get(name)
        return val

    def _fn(self, key, exprs, backend: Backend, with_lam=False):
        self._fn_exprs.setdefault(key, exprs)
        ck = (key, backend.lambdify_module)
        if ck not in self._compiled:
            args = [self.t] + self.q + self.v + (list(self.lam) if with_lam else []) + list(self.params)
            lists = [e.tolist() if isinstance(e, sympy.MatrixBase) else e for e in exprs]
            # every generated source passes gensource: symbols printed as _s<i>, nodes checked
            f = gensource.lambdify(args, lists, backend.lambdify_module, namespaces=[_NONSMOOTH], order="none")
            empty = [e.shape if isinstance(e, sympy.MatrixBase) and 0 in e.shape else None for e in exprs]
            if any(empty):
                # an m = 0 system's k, K, ... print as [] and would come back without their shape
                f = _keep_empty_shapes(f, empty)
            self._compiled[ck] = f
        f = self._compiled[ck]
        if not self.params:
            return f
        pv = self._param_arg_values(backend)     # parameters are the trailing arguments
        return lambda *a: f(*a, *pv)

    def _arrays(self, key, values, backend):
        """The outputs of the lambdified function ``key`` as arrays: those of ``_arr``, faster at
        mpmath precision. lambdify returns Python ints for integer entries (zeros, the entries of
        a constant M) and mpf for the others: the integer entries are replaced by their mpf
        (converted once, shared: mpf is immutable), then one C-level pass over the types checks
        that nothing else is left; any other type (an mpc from L evaluated outside its domain,
        an int from a Piecewise branch) sends that output through ``_arr``, which converts or
        raises as before. The per-entry conversion loop was most of a stage evaluation
        (40 digits, with Jacobians, best of 5 x 200 in one run: mp-particles 401 -> 157 us,
        robot 283 -> 150 us, relativistic 430 -> 352 us; tests/models/test_process_memos.py checks
        the arrays entry by entry against ``_arr``)."""
        if not backend.is_mp:
            return [_arr(x, backend) for x in values]
        plan = self._compiled.get(("plan", key))
        if plan is None:
            plan = self._compiled[("plan", key)] = _integer_entries(self._fn_exprs[key])
        out = []
        for x, pl in zip(values, plan):
            a = np.array(x, dtype=object)
            flat = a.reshape(-1)
            for i, c in pl:
                flat[i] = c
            if set(map(type, flat)) - _MPF_ONLY:
                a = _arr(x, backend)
            out.append(a)
        return out

    # --- numeric evaluation -------------------------------------------------------------------
    def stage(self, backend: Backend, t, q, v, lam, jacobians: bool = True, h=None) -> StageEval:
        """Evaluate L_v, L_q, k, h R = -K^T lam (and their partials) at one point. With a
        nonideal term (3.3) and the step ``h`` given, h R also carries h N(t, q, v, lam / h)
        and R_L = d(h R)/d lam = -K^T + N_psi (without ``h`` only the ideal part: the
        endpoint evaluations of (21d, f) do not use R)."""
        args = (t, *q, *v, *lam)
        if jacobians:
            f = self._fn("stage_jac", [self.L_v, self.L_q, self.k, self.R_lam, self.L_vv, self.L_vq,
                                        self.L_qq, self.k_q, self.k_v, self.R_q, self.R_v], backend, True)
            out = self._arrays("stage_jac", f(*args), backend)
            Lv, Lq, k, R, Lvv, Lvq, Lqq, kq, kv, Rq, Rv = out
            st = StageEval(Lv[:, 0], Lq[:, 0], k[:, 0], R[:, 0], Lvv, Lvq, Lvq.T, Lqq,
                           kq.reshape(self.m, self.n), kv.reshape(self.m, self.n), Rq, Rv)
        else:
            f = self._fn("stage_val", [self.L_v, self.L_q, self.k, self.R_lam], backend, True)
            Lv, Lq, k, R = (x[:, 0] for x in self._arrays("stage_val", f(*args), backend))
            st = StageEval(Lv, Lq, k, R)
        if self.N is not None and h is not None:
            self._add_nonideal(backend, st, t, q, v, lam, h, jacobians)
        return st

    def nonideal_terms(self, backend, t, q, v, psi, partials=True):
        """N, N_q, N_v, N_psi at (t, q, v, psi) (section 3.3); N_q, N_v are None unless
        ``partials``. One flat expression list, so that lambdify's CSE shares subexpressions
        (it does not across nested lists); this matters at the thousands of bits of mpmath.odefun."""
        n, m = self.n, self.m
        ck = ("N", partials, backend.lambdify_module)
        if ck not in self._compiled:
            mats = [self.N, self.N_q, self.N_v, self.N_psi] if partials else [self.N, self.N_psi]
            flat = [e for M in mats for e in M]
            args = [self.t] + self.q + self.v + self.psi + list(self.params)
            # with the nonsmooth functions' derivatives (DiracDelta: 0 off its support), as L and k
            self._compiled[ck] = gensource.lambdify(args, flat, backend.lambdify_module, namespaces=[_NONSMOOTH])
        pv = self._param_arg_values(backend) if self.params else ()
        out = _arr(self._compiled[ck](t, *q, *v, *psi, *pv), backend)
        N, rest = out[:n], out[n:]
        if not partials:
            return N, None, None, rest.reshape(n, m)
        return N, rest[:n * n].reshape(n, n), rest[n * n:2 * n * n].reshape(n, n), rest[2 * n * n:].reshape(n, m)

    def _add_nonideal(self, backend, st, t, q, v, lam, h, jacobians):
        # Lambda = h Psi is the unknown: h N(Psi) with Psi = Lambda / h; d/dLambda gives N_psi
        N, Nq, Nv, Np = self.nonideal_terms(backend, t, q, v, [x / h for x in lam])
        st.R_lam = st.R_lam + N * h
        if jacobians:
            st.R_q = st.R_q + Nq * h
            st.R_v = st.R_v + Nv * h
            st.R_L = Np - st.k_v.T

    def momentum(self, backend, t, q, v):
        return _arr(self._fn("p", [self.L_v], backend)(t, *q, *v)[0], backend)[:, 0]

    def constraint(self, backend, t, q, v):
        """k(t, q, v), shape (m,)."""
        return _arr(self._fn("k", [self.k], backend)(t, *q, *v)[0], backend)[:, 0]

    def energy(self, backend, t, q, v):
        """E = L_v v - L (8)."""
        return self._fn("E", [self.energy_expr], backend)(t, *q, *v)[0]

    def saddle_matrix(self, backend, t, q, v):
        """[[L_vv, K^T], [K, 0]] of (4)."""
        Lvv, kv = (_arr(x, backend) for x in self._fn("saddle", [self.L_vv, self.k_v], backend)(t, *q, *v))
        kv = kv.reshape(self.m, self.n)
        S = backend.zeros((self.n + self.m, self.n + self.m))
        S[:self.n, :self.n] = Lvv
        S[:self.n, self.n:] = kv.T
        S[self.n:, :self.n] = kv
        return S

    def check_saddle(self, backend, t, q, v, rcond: float | None = None, S=None, notes: dict | None = None):
        """Raise SingularSaddleError when (4) fails (numerically) at (t, q, v).

        The test is scale invariant: the saddle matrix is equilibrated symmetrically,
        D S D with D = diag(1 / sqrt(max_j |S_ij|)), before its singular values are compared,
        and K is row-equilibrated, so that large mass ratios or badly scaled coordinates are
        not mistaken for singularity while a genuine rank loss (which no diagonal scaling
        removes) still is. Returns the reciprocal condition number of the scaled matrix.
        ``S``: the matrix (4) at (t, q, v) when the caller has it (the compiled path evaluates it
        with its own model functions); the same test is applied. ``notes`` (a run's set-up): a
        dict that gets "lvv_rcond" and "t" when L_vv is singular there, i.e. (5) fails while (4)
        holds (the driver warns with a result, ``solve._warn_regular``)."""
        with backend.context():
            S = self.saddle_matrix(backend, t, q, v) if S is None else S
            if backend.is_mp:
                # at the run's digits: float64's 1e3 ulps refused (4) with K K^T of condition
                # 1e16 (rank_loss eps = 1e-8) at dps = 30 or 100, where (21) is solved to 1e-38
                return self._check_saddle_mp(backend, t, S, rcond, notes)
            Sf = np.asarray(S, float)
        if not np.all(np.isfinite(Sf)):
            raise SingularSaddleError(f"saddle matrix (4) has non-finite entries at t = {float(t):g}")
        rowmax = np.max(np.abs(Sf), axis=1)
        if np.any(rowmax == 0):
            raise SingularSaddleError(f"saddle matrix (4) has a zero row at t = {float(t):g}; assumption (4) fails")
        d = 1 / np.sqrt(rowmax)
        Ss = d[:, None] * Sf * d[None, :]
        kv = Sf[self.n:, :self.n]
        kv = kv / np.max(np.abs(kv), axis=1, keepdims=True, initial=0.0).clip(min=1e-300)
        sv = np.linalg.svd(Ss, compute_uv=False)
        r = float(sv[-1] / sv[0])
        tol = rcond if rcond is not None else 1e3 * 2.0 ** -52
        # m = 0: no K to lose rank; (4) is L_vv alone
        ksv = np.linalg.svd(kv, compute_uv=False) if self.m else np.ones(1)
        kr = float(ksv[-1] / max(ksv[0], 1e-300))
        if kr <= tol:
            raise SingularSaddleError(
                f"constraint Jacobian K = k_v is rank deficient at t = {float(t):g} "
                f"(sigma_min/sigma_max = {kr:.2e}); assumption (4) fails")
        if r <= tol:
            raise SingularSaddleError(
                f"saddle matrix (4) [[L_vv, K^T], [K, 0]] is singular at t = {float(t):g} "
                f"(reciprocal condition {r:.2e} <= {tol:.1e} after equilibration)")
        self._lvv_checks(notes, Sf[:self.n, :self.n], math.sqrt,
                         lambda A: np.linalg.svd(np.asarray(A, float), compute_uv=False), tol, t)
        return r

    def _lvv_checks(self, notes, Lv, sqrt, singular_values, tol, t):
        """After (4) passed: an L_vv singular along some velocities identically is refused
        (``lvv_problem``); with ``notes`` (a run's set-up), a numerically singular L_vv there is
        noted. (5), a regular Lagrangian, is not the paper's hypothesis ((4) is), and such an L_vv
        leaves the run to the method: measured on L = (vx + vy)^2 / 2 - U, k = vx - vy,
        lobatto-iiia-iiib-3 converges while gauss-1 ended 2-9e-2 apart on the two engines with
        status 0 (``solve._warn_regular`` warns with the result)."""
        if getattr(self, "lvv_problem", None):
            raise SingularSaddleError(self.lvv_problem)
        if notes is not None:
            lr = _lvv_rcond(Lv, sqrt, singular_values)
            if lr <= tol:
                notes.update(lvv_rcond=float(lr), t=float(t))

    def _check_saddle_mp(self, backend, t, S, rcond, notes=None):
        """``check_saddle`` at mpmath precision (inside ``backend.context()``): the same
        equilibration and singular-value tests in mpf, with the tolerance 1e3 eps of the working
        precision (10^-dps) instead of float64's, so that (4) is judged by the digits that solve
        (21). Returns the reciprocal condition number (an mpf)."""
        S = np.asarray(S, dtype=object)
        if not all(mpmath.isfinite(x) for x in S.reshape(-1)):
            raise SingularSaddleError(f"saddle matrix (4) has non-finite entries at t = {float(t):g}")
        rowmax = [max(abs(x) for x in row) for row in S]
        if any(not r for r in rowmax):
            raise SingularSaddleError(f"saddle matrix (4) has a zero row at t = {float(t):g}; assumption (4) fails")
        d = [1 / mpmath.sqrt(r) for r in rowmax]
        N = len(d)
        Ss = np.array([[d[i] * S[i, j] * d[j] for j in range(N)] for i in range(N)], dtype=object)
        tol = mpmath.mpf(rcond) if rcond is not None else 1000 * mpmath.mpf(10) ** (-backend.dps)
        if self.m:
            kv = S[self.n:, :self.n]
            kv = np.array([[x / max(max(abs(y) for y in row), mpmath.mpf(10) ** -300) for x in row]
                           for row in kv], dtype=object)
            # the m singular values of the m x n matrix K (the flint path returns n, from K^T K)
            ksv = backend.singular_values(kv)[:min(self.m, self.n)]
            kr = ksv[-1] / ksv[0] if ksv[0] else mpmath.mpf(0)
            if kr <= tol:
                raise SingularSaddleError(
                    f"constraint Jacobian K = k_v is rank deficient at t = {float(t):g} "
                    f"(sigma_min/sigma_max = {fmt(kr, 3)} at {backend.dps} digits); assumption (4) fails")
        sv = backend.singular_values(Ss)
        r = sv[-1] / sv[0]
        if r <= tol:
            raise SingularSaddleError(
                f"saddle matrix (4) [[L_vv, K^T], [K, 0]] is singular at t = {float(t):g} "
                f"(reciprocal condition {fmt(r, 3)} <= {fmt(tol, 2)} after equilibration, at {backend.dps} digits)")
        self._lvv_checks(notes, S[:self.n, :self.n], mpmath.sqrt, backend.singular_values, tol, t)   # at the run's digits
        return r

    def check_consistent(self, backend, t, q, v, tol=None, k=None):
        """Raise InconsistentInitialDataError unless |k(t, q, v)| <= tol (1 + |v|) + 2 eps |t| |k_t|
        (``k``: the value k(t, q, v) when the caller has it). The last term is the rounding of the
        time itself (1c): a rheonomic k at t ~ 1e4 is known only to |k_t| ulp(t) (a decimal t0, or a
        step of (21f) ending at fl(t_n + h) that the grid saves at fl(t0 + (n+1) h), one ulp apart),
        so a run's own saved state stays a valid start for the next chunk."""
        with backend.context():
            res = backend.norm_inf(self.constraint(backend, t, q, v) if k is None else k)
            scale = 1 + backend.norm_inf(backend.array(v))
            tol = tol if tol is not None else 1e3 * backend.eps
            bound = tol * scale
            if math.isfinite(res) and res > bound and self._rheonomic_k():
                kt = _arr(self._fn("kt", [self.k_t], backend)(t, *q, *v)[0], backend)[:, 0]
                bound = bound + 2 * backend.eps * abs(float(t)) * backend.norm_inf(kt)
        if not math.isfinite(res) or res > bound:
            raise InconsistentInitialDataError(
                f"initial data are inconsistent: |k(t0, q0, v0)| = {fmt(res)} > {fmt(bound, 2)} "
                "(pass project=True / --project to project v0 onto k = 0)")
        return res

    def _rheonomic_k(self) -> bool:
        """k depends on t (then (1c) at t0 carries the rounding of t0, ``check_consistent``)."""
        flag = self.__dict__.get("_k_has_t")
        if flag is None:
            flag = self.__dict__["_k_has_t"] = self.t in self.k.free_symbols
        return flag

    def project_velocity(self, backend, t, q, v, maxiter=50):
        """Closest v (in the L_vv metric) with k(t, q, v) = 0, by Newton on the KKT system
        L_vv (v - v0) + K^T mu = 0, k = 0: its matrix is (4) with sum_i mu_i (k_i)_vv added to L_vv
        (= -R_v at lam = mu), zero for k linear in v; without it the iteration diverges for k
        nonlinear in v once |mu| (k_i)_vv is comparable to L_vv (v0 = (3, 4, 0) onto |v| = 1)."""
        # the sparse derivative says whether there is a term (no n x n sympy matrix for a linear k)
        curv = self._fn("proj_Rv", [self.R_v], backend, with_lam=True) if self._derived.nonzeros("R_v") else None
        # L_vv depending on v: the term L_vvv (v - v0) of the matrix, left out above, made the
        # iteration linear (0.4 digits an iteration for L = vx^4/12 + |v|^2/2 - U from |v - v0| =
        # 0.4): 50 iterations reached ~25 digits and a projection at dps 100 "did not converge".
        # At mpmath precision it is taken by differences of L_vv (a step of sqrt(eps): the
        # iteration then gains ~dps/2 digits a step); float64 keeps its iteration as it was
        varies = backend.is_mp and any(e.free_symbols & set(self.v) for e in self._derived.nonzeros("L_vv").values())
        with backend.context():
            v = backend.array(v).copy()
            v_ref = v.copy()
            mu = backend.zeros(self.m)
            for _ in range(maxiter):
                S = self.saddle_matrix(backend, t, q, v)
                Lvv = S[:self.n, :self.n]
                kv = S[self.n:, :self.n]
                r1 = Lvv.dot(v - v_ref) + kv.T.dot(mu)
                r2 = self.constraint(backend, t, q, v)
                if curv is not None or varies:
                    S = S.copy()
                if curv is not None:
                    S[:self.n, :self.n] = Lvv - _arr(curv(t, *q, *v, *mu)[0], backend).reshape(self.n, self.n)
                if varies:
                    S[:self.n, :self.n] = S[:self.n, :self.n] + self._lvv_slope(backend, t, q, v, Lvv, v - v_ref)
                try:
                    dx = backend.solve(S, -np.concatenate([r1, r2]))
                except SingularMatrixError:
                    # k has no zero near v0 (k = |v|^2 + 1), or K lost rank on the way: the
                    # projection's failure, not a Newton iteration's of (21)
                    raise InconsistentInitialDataError(
                        f"projection of v0 onto k = 0 failed: the KKT matrix became singular at v = "
                        f"{np.array2string(np.asarray([float(x) for x in v]), precision=6)} "
                        f"(|k| = {fmt(backend.norm_inf(r2))}; does k(t0, q0, v) = 0 have a solution?)") from None
                v = v + dx[:self.n]
                mu = mu + dx[self.n:]
                # each block against its own round-off: mu grows like 1 / sigma_min(K) when the rows
                # of K nearly align (det (4) small but nonzero), and |dx| against 10 eps |v| alone
                # never stopped (snakeboard at phi = pi/2 - 1e-3: |mu| = 150, dmu 1e-14 a step)
                step = max(backend.norm_inf(dx[:self.n]) / (1 + backend.norm_inf(v)),
                           backend.norm_inf(dx[self.n:]) / (1 + backend.norm_inf(mu)) if self.m else 0)
                if step <= 10 * backend.eps:
                    return v
        raise InconsistentInitialDataError("projection of v0 onto k = 0 did not converge")

    def _lvv_slope(self, backend, t, q, v, Lvv, w):
        """d(L_vv(v) w)/dv for a fixed w, column k by a forward difference of L_vv along v_k with
        the step sqrt(eps) (1 + |v|) (``project_velocity``; error ~sqrt(eps) relative)."""
        step = mpmath.sqrt(backend.eps) * (1 + backend.norm_inf(v))
        cols = []
        for k in range(self.n):
            vk = v.copy()
            vk[k] = vk[k] + step
            Lk = self.saddle_matrix(backend, t, q, vk)[:self.n, :self.n]
            cols.append((Lk - Lvv).dot(w) / step)
        return np.column_stack(cols)

    def ode_rhs(self, backend, t, q, v):
        """Underlying ODE (3a-b): returns (dv/dt, psi) from the saddle system (4)."""
        Lvv, kv, Lvt, Lvq, Lq, kt, kq = self._ode_terms(backend, t, q, v)
        v = np.asarray(v)
        S = backend.zeros((self.n + self.m, self.n + self.m))
        S[:self.n, :self.n] = Lvv
        S[:self.n, self.n:] = kv.T
        S[self.n:, :self.n] = kv
        rhs = np.concatenate([-Lvt[:, 0] - Lvq.dot(v) + Lq[:, 0], -kt[:, 0] - kq.dot(v)])
        sol = backend.solve(S, rhs)
        if self.N is not None:
            sol = self._ode_nonideal(backend, t, q, v, S, rhs, sol)
        return sol[:self.n], sol[self.n:]

    def _ode_terms(self, backend, t, q, v):
        """L_vv, K = k_v, L_vt, L_vq, L_q, k_t, k_q at (t, q, v), each in its matrix's shape. One
        flat expression list, so that lambdify's CSE shares subexpressions (it does not across
        the nested lists of ``_fn``), as ``nonideal_terms``: mpmath.odefun evaluates (3a-b) at
        (1 + its degree) times the working precision (~2600 digits for a 40-digit reference), where
        the bicycle's 18,880 sines and cosines of 8 angles took 1.7 s per evaluation (5 ms shared)."""
        mats = [self.L_vv, self.k_v, self.L_vt, self.L_vq, self.L_q, self.k_t, self.k_q]
        ck = ("ode-flat", backend.lambdify_module)
        if ck not in self._compiled:
            flat = [e for M in mats for e in M]
            args = [self.t] + self.q + self.v + list(self.params)
            self._compiled[ck] = gensource.lambdify(args, flat, backend.lambdify_module, namespaces=[_NONSMOOTH],
                                                    order="none")
        pv = self._param_arg_values(backend) if self.params else ()
        out = _arr(self._compiled[ck](t, *q, *v, *pv), backend).reshape(-1)
        parts, i = [], 0
        for M in mats:
            rows, cols = M.shape
            parts.append(out[i:i + rows * cols].reshape(rows, cols))
            i += rows * cols
        return parts

    def _ode_nonideal(self, backend, t, q, v, S, rhs, sol, maxiter=30):
        """(3a) with the nonideal term: L_vv v' + K^T psi - N(t, q, v, psi) = rhs, nonlinear in
        psi; Newton from the ideal solution on [[L_vv, K^T - N_psi], [K, 0]]."""
        n = self.n
        # mpmath.odefun raises the working precision beyond the backend's: converge to the current eps
        tol = 10 * mpmath.mp.eps if backend.is_mp else 10 * backend.eps
        prev = None
        for _ in range(maxiter):
            N, _, _, Np = self.nonideal_terms(backend, t, q, v, sol[n:], partials=False)
            G = S.dot(sol) - rhs
            G[:n] = G[:n] - N
            Sj = S.copy()
            Sj[:n, n:] = S[:n, n:] - Np
            dx = backend.solve(Sj, -G)
            sol = sol + dx
            dn = backend.norm_inf(dx)
            if dn <= tol * (1 + backend.norm_inf(sol)) or (prev is not None and dn >= prev / 2
                                                           and dn <= 1e3 * tol * (1 + backend.norm_inf(sol))):
                return sol
            prev = dn
        raise SingularSaddleError(f"(3a) with the nonideal term: Newton for psi did not converge at t = {float(t):g}")


def _lvv_rcond(Lv, sqrt, singular_values):
    """The reciprocal condition number of L_vv (n x n, floats or mpf) equilibrated by its own rows,
    D L_vv D with D = diag(1 / sqrt(max_j |L_ij|)) (by the rows of (4), a row of K would make a
    small but regular mass look singular: masses 1 and 1e-12 with k = vx - 1000 vy); 0 for a zero
    row. ``sqrt`` and ``singular_values`` (descending) of the run's numbers."""
    lmax = [max(abs(x) for x in row) for row in Lv]
    if any(not x for x in lmax):
        return 0.0
    d = [1 / sqrt(x) for x in lmax]
    n = len(d)
    sv = singular_values(np.array([[d[i] * Lv[i][j] * d[j] for j in range(n)] for i in range(n)], dtype=object))
    return float(sv[-1] / sv[0])


def _check_build(system) -> None:
    """Refusals that would otherwise surface only at integrate time.

    * Physical units (``sympy.physics.units`` quantities) are not symbols: they pass the symbol
      check, then the generated code fails on an undefined name.
    * Velocities along which L_vv vanishes identically (L does not contain them, or is affine in
      them): (4) can still be regular when K covers them, but the stage equations
      P_i = grad_v L(Q_i, V_i) of (21) do not determine those components of V_i, and Newton's
      matrix is singular at the first step. Found here, named in ``lvv_problem`` and raised by
      ``check_saddle`` (the set-up check of every engine) as SingularSaddleError."""
    # a Quantity exists only once sympy.physics.units is imported: not importing it here saves
    # ~0.1 s of every build (the package defines hundreds of units when it is loaded)
    qmod = sys.modules.get("sympy.physics.units.quantities")
    exprs = [system.L, *system.k] + ([*system.N] if system.N is not None else [])
    units = sorted({str(u) for e in exprs for u in e.atoms(qmod.Quantity)}) if qmod is not None else []
    if units:
        raise SystemDefinitionError(
            f"{system.name}: L or k contain physical units ({', '.join(units[:6])}); the integrator works on "
            "numbers: substitute the quantities by their values in one consistent unit system")
    system.lvv_problem = None
    rows = {i for i, _ in system._derived.positions("L_vv")}     # sparse: L_vv is not made here
    flat = [v for i, v in enumerate(system.v) if i not in rows]
    if flat:
        absent = [v for v in flat if v not in system.L.free_symbols]
        which = (f"L does not contain the velocities {', '.join(map(str, absent))}" if len(absent) == len(flat)
                 else f"L_vv vanishes along the velocities {', '.join(map(str, flat))}")
        # kept, and raised by check_saddle after the test of (4) (so a singular (4) keeps its own
        # message): the system stays usable for what needs only (4), e.g. the ODE (3a-b)
        system.lvv_problem = (
            f"{system.name}: {which}, so L_vv is singular there; the saddle matrix (4) can still be regular, "
            "but the SPARK stage equations (21) need p = grad_v L to determine every velocity (from "
            "sympy.physics.mechanics: define point velocities from positions, not with the rolling "
            "condition built into the kinematics)")


def _symbol(x, what):
    """A symbol of the system: a sympy Symbol as given, or a plain name (an ASCII identifier)
    for one; any other string is refused (a string is never parsed as Python or by sympify)."""
    if isinstance(x, str):
        if not (x.isidentifier() and x.isascii() and len(x) <= 100):
            raise SystemDefinitionError(f"{what}: {x[:60]!r} is not a symbol name")
        return sympy.Symbol(x)
    return x


def _symbol_list(x, what):
    """The symbols of q, v or psi: a list, tuple, 1-D array or other iterable (not text, bytes or
    a dict) of Symbols or names, as a list; anything else a SystemDefinitionError (not the
    TypeError of ``list(None)``, nor bytes read as a list of small integers)."""
    from .validate import _describe
    if isinstance(x, (str, bytes, dict)) or not hasattr(x, "__iter__"):
        raise SystemDefinitionError(f"{what} must be a list of symbols (or of names), got {_describe(x)}")
    try:
        items = list(x)
    except TypeError:                   # a 0-d array has __iter__ but no items
        raise SystemDefinitionError(f"{what} must be a list of symbols (or of names), got {_describe(x)}") from None
    return [_symbol(e, what) for e in items]


def _time_symbol(t):
    """The time of the system: a sympy Symbol, or a name for one (``_symbol``)."""
    from .validate import _describe
    t = _symbol(t, "t")
    if not isinstance(t, sympy.Symbol):
        raise SystemDefinitionError(f"t must be a sympy Symbol (or a name), got {_describe(t)}")
    return t


def _matrix_rows(M, where) -> int:
    """The number of rows n of a matrix argument (a sympy Matrix, an array or a list of rows), or
    a SystemDefinitionError: M = None, a number or text has no rows."""
    from .validate import _describe
    if isinstance(M, (list, tuple)):
        return len(M)
    if isinstance(M, np.ndarray) and M.ndim >= 1:
        return M.shape[0]
    if isinstance(M, sympy.MatrixBase):
        return M.rows
    raise SystemDefinitionError(f"{where} must be an n x n matrix (a sympy Matrix, an array or a list of rows), "
                                f"got {_describe(M)}")


def _scalar_expr(e, where):
    """``e`` as one scalar sympy expression (numbers included; not None, True, a dict, bytes or an
    object sympy cannot take), else a SystemDefinitionError naming ``where``."""
    from .validate import _describe
    try:
        x = sympy.sympify(e, strict=True)
    except (sympy.SympifyError, TypeError, ValueError, AttributeError):
        x = None
    if not isinstance(x, sympy.Expr) or getattr(x, "is_Matrix", False):
        raise SystemDefinitionError(f"{where} must be one scalar expression, got {_describe(e)}")
    return x


def _names(*groups) -> dict:
    """name -> Symbol of the declared symbols (what a string expression may use)."""
    return {str(s): s for g in groups for s in g if isinstance(s, sympy.Symbol)}


def _exprs(obj, names, where):
    """``obj`` with every string in it (nested lists, tuples, arrays) replaced by its expression
    (``numbers.parse_expression``: a bounded whitelist parser in the declared names); everything
    else as it is."""
    from .numbers import parse_expression
    if isinstance(obj, str):
        if _nfkc(obj) != obj:
            odd = sorted({c for c in obj if _nfkc(c) != c})
            raise SystemDefinitionError(f"{where}: the text has characters that Unicode NFKC normalisation changes "
                                        f"({', '.join(f'U+{ord(c):04X}' for c in odd[:5])}): Python reads them as "
                                        "other letters (the micro sign as Greek mu, fullwidth x as x); "
                                        "type the names as declared, in their normal form")
        try:
            return parse_expression(obj, names, where, error=SystemDefinitionError)
        except SystemDefinitionError as exc:
            raise SystemDefinitionError(f"{exc}; expressions must be sympy expressions, or text in the declared "
                                        "symbols and the functions of numbers.parse_expression") from None
    if isinstance(obj, np.ndarray) and obj.dtype.kind in "OUS":
        obj = obj.tolist()
    if isinstance(obj, (list, tuple)):
        return type(obj)(_exprs(x, names, f"{where}[{i}]") for i, x in enumerate(obj))
    return obj


_AS_BUILT = {"L": "L", "k": "k", "N": "N (the nonideal term)"}


def check_as_built(system) -> None:
    """SystemDefinitionError when ``system.L``, ``system.k`` or ``system.N`` (the nonideal term of
    3.3) is not the object the system was built with (assigned afterwards): the derivation never
    saw it (L_vv, k_v, N_q, ... are those of the old one, or missing), text in it would be
    evaluated by sympify or sympy.Matrix, and the engines read different parts (the compiled one
    ran the old constraint with the new k, the generic one the new). Every engine calls this
    before reading them, so that none runs a system the others do not."""
    built = system.__dict__.get("_built")
    if built is None:
        return
    for attr, what in _AS_BUILT.items():
        if system.__dict__.get(attr) is not built[attr]:
            raise SystemDefinitionError(f"{system.name}: {what} was set after the system was built; give it to "
                                        "LagrangianSystem(...) (nonideal=[...] for N), which derives from it")


def refuse_text(obj, where):
    """SystemDefinitionError if ``obj`` (a dict, list, tuple, array or value) holds a string: for
    expressions read after construction (``system.mechanical`` set by hand), which sympify or
    Matrix would evaluate; LagrangianSystem(..., mechanical=...) parses them instead."""
    if isinstance(obj, (str, bytes)):
        raise SystemDefinitionError(f"{where} is text; give it to LagrangianSystem(...), which parses it, "
                                    "or as a sympy expression")
    if isinstance(obj, np.ndarray) and obj.dtype.kind in "OUS":
        obj = obj.tolist()
    if isinstance(obj, dict):
        for key, val in obj.items():
            refuse_text(val, f"{where}[{key!r}]")
    elif isinstance(obj, (list, tuple)):
        for i, val in enumerate(obj):
            refuse_text(val, f"{where}[{i}]")


def _checked_param(p, val):
    """A parameter value given as a number: a finite real one (True is not 1)."""
    from .errors import InputError
    from .validate import real_number
    try:
        real_number(val, f"parameter {p}")
    except InputError as exc:
        raise SystemDefinitionError(str(exc)) from None
    return _check_assumptions(p, val)


#: the sympy assumptions a number's value decides, and how (x: the value to 60 digits)
_DECIDED = {
    "positive": lambda x: x > 0, "negative": lambda x: x < 0, "nonnegative": lambda x: x >= 0,
    "nonpositive": lambda x: x <= 0, "zero": lambda x: x == 0, "nonzero": lambda x: x != 0,
    "integer": lambda x: x == int(x), "noninteger": lambda x: x != int(x),
    "even": lambda x: x == int(x) and int(x) % 2 == 0, "odd": lambda x: x == int(x) and int(x) % 2 == 1,
}


def _check_assumptions(p, val):
    """``val`` if it satisfies the sympy assumptions the parameter ``p`` was declared with (the
    model was derived under them: Abs(c) = c for c positive, sqrt(c**2) = c, ...), else a
    SystemDefinitionError naming the parameter, the value and the assumption (issue 45, class 8)."""
    facts = {key: b for key, b in getattr(p, "assumptions0", {}).items() if key in _DECIDED and b is not None}
    if not facts:
        return val
    try:
        x = mpmath.mpf(str(sympy.N(sympy.sympify(val, strict=True), 60))) if not isinstance(val, (int, float)) \
            else val
    except (TypeError, ValueError, sympy.SympifyError):
        return val                      # not a number: real_number / _param_value refuse it
    if isinstance(x, float) and not math.isfinite(x):
        return val
    # a violated True fact first (the declared assumption: positive, not the implied negative=False)
    for key in sorted(facts, key=lambda k: (not facts[k], list(_DECIDED).index(k))):
        if bool(_DECIDED[key](x)) != facts[key]:
            raise SystemDefinitionError(f"parameter {p} = {str(val)[:40]} contradicts its assumption "
                                        f"{key}={facts[key]} "
                                        "(the model was derived under it): give a value that satisfies it, or "
                                        "declare the symbol without the assumption")
    return val


def _nfkc(name: str) -> str:
    import unicodedata
    return unicodedata.normalize("NFKC", name)


def _check_names(system, nonideal_exprs) -> None:
    """Every symbol of the system (declared or in L, k, N) has a name of its own: two different
    symbols with one name (Symbol("x") and Symbol("x", real=True), a Dummy) cannot both be
    arguments of the generated functions, and names equal after Unicode NFKC normalisation
    (the micro sign and Greek mu, a fullwidth x and x) are one name to the expression parser
    and to Python, so a string L would bind one of them to the other."""
    seen: dict = {}
    roles = [("q", system.q), ("v", system.v), ("t", [system.t]), ("params", system.params),
             ("psi", system.psi), ("the multipliers lam0, lam1, ...", system.lam)]
    declared = [(role, x) for role, xs in roles for x in xs]
    free = set(system.L.free_symbols) | set(system.k.free_symbols)
    for e in nonideal_exprs:
        free |= set(getattr(e, "free_symbols", ()))
    known = {x for _, x in declared}
    for role, x in declared + [("L, k or N", x) for x in sorted(free - known, key=str)]:
        if not isinstance(x, sympy.Symbol):
            continue
        other, orole = seen.setdefault(_nfkc(x.name), (x, role))
        if other is x and orole == role:
            continue
        if other == x and orole == role:
            continue
        if other == x:
            raise SystemDefinitionError(f"the symbol {x.name!r} is used both in {orole} and in {role}: rename it")
        how = ("are different symbols with the same name (their assumptions differ, or one is a Dummy)"
               if other.name == x.name else "are the same name after Unicode NFKC normalisation")
        raise SystemDefinitionError(f"{other.name!r} ({orole}) and {x.name!r} ({role}) {how}: rename one of them")


def _mechanical_exprs(mech) -> list:
    """[(where, expr)] of the sympy expressions in the mechanical parts (M, U, K, b), for the node
    check (the comparators and the compiled engine generate code from them)."""
    if not isinstance(mech, dict):
        return []
    out, todo = [], [(f"mechanical[{key!r}]", val) for key, val in mech.items()]
    while todo:
        where, val = todo.pop()
        if isinstance(val, (sympy.MatrixBase, list, tuple)):
            todo += [(f"{where}[{i}]", e) for i, e in enumerate(val)]
        elif isinstance(val, sympy.Basic):
            out.append((where, val))
    return out


def _check_functions(named_exprs, derived: bool = False) -> None:
    """SystemDefinitionError naming the first node in the expressions that an engine cannot
    translate (an undefined function, besselj, polygamma, LambertW, zeta, conjugate, floor, an
    unevaluated Derivative), or a nesting deeper than ``gensource.MAX_DEPTH``, when the system is
    built, instead of a NameError, a RecursionError or PrintMethodNotImplementedError at the first
    evaluation (``gensource.check_expressions``)."""
    gensource.check_expressions(named_exprs, derived=derived)


#: the parts of the mechanical form (section 7): L = 1/2 v^T M v - U, k = K v + b
MECHANICAL_KEYS = ("M", "U", "K", "b")


def completed_mechanical(mech) -> dict:
    """The four parts of a checked ``mechanical`` dict, U and b defaulting to 0 (b as an m x 1
    column), for the engines that read them (``check_mechanical`` first)."""
    K = mech["K"] if isinstance(mech["K"], sympy.MatrixBase) else sympy.Matrix(mech["K"])
    b = mech.get("b")
    b = sympy.zeros(K.rows, 1) if b is None else sympy.Matrix(b).reshape(K.rows, 1)
    return {"M": mech["M"], "U": mech.get("U", sympy.S.Zero), "K": K, "b": b}


def check_mechanical(system, mech) -> None:
    """The mechanical form's M (used by the compiled engine and the semi-implicit comparators)
    is square, symmetric and equal to L_vv (used by the generic engine): one mass matrix for
    every engine. A non-symmetric M gave the compiled engine M and the generic one its
    symmetric part, 4e-2 apart, without a word. The keys are M, U, K and b, K required."""
    if not isinstance(mech, dict) or "M" not in mech:
        raise SystemDefinitionError(f"{system.name}: mechanical must be a dict with M, U, K (and b)")
    # every engine reads the same four parts: an unknown key ("B" for b) or a missing K was
    # accepted here and then a KeyError of one engine, while another ran without it
    unknown = sorted(map(str, set(mech) - set(MECHANICAL_KEYS)))
    if unknown or mech.get("K") is None:
        what = f"has keys {unknown} it does not know" if unknown else "has no K"
        raise SystemDefinitionError(f"{system.name}: mechanical {what}: it takes M, U, K (m x n, 0 x n without "
                                    "constraints) and b (U and b default to 0)")
    refuse_text(mech, f"{system.name}: mechanical")
    try:
        M = mech["M"] if isinstance(mech["M"], sympy.MatrixBase) else sympy.Matrix(mech["M"])
    except (TypeError, ValueError, sympy.SympifyError) as exc:
        raise SystemDefinitionError(f"{system.name}: mechanical M is not a matrix ({str(exc)[:80]})") from None
    if M.shape != (system.n, system.n):
        raise SystemDefinitionError(f"{system.name}: mechanical M must be {system.n} x {system.n}, got {M.shape}")

    def differs(a, b):
        d = sympy.sympify(a) - sympy.sympify(b)
        return d != 0 and sympy.expand(d) != 0 and sympy.simplify(d) != 0
    # compared where either side is structurally nonzero (zero against zero needs no test):
    # n^2 comparisons of a dense L_vv cost seconds at n = 121 and minutes at n = 1001
    Mnz = _nonzero_entries(M)
    for i, j in sorted({(min(i, j), max(i, j)) for i, j in Mnz if i != j}):
        if differs(Mnz.get((i, j), 0), Mnz.get((j, i), 0)):
            raise SystemDefinitionError(f"{system.name}: the mass matrix M is not symmetric (M[{i},{j}] = "
                                        f"{str(M[i, j])[:40]}, M[{j},{i}] = {str(M[j, i])[:40]}): only its "
                                        "symmetric part enters L = v^T M v / 2; give that")
    Lnz = _derived_nonzeros(system, "L_vv")
    if Lnz is not None:
        for i, j in sorted(set(Mnz) | set(Lnz)):
            if differs(Mnz.get((i, j), 0), Lnz.get((i, j), 0)):
                raise SystemDefinitionError(f"{system.name}: mechanical M[{i},{j}] = {str(M[i, j])[:40]} is not "
                                            f"L_vv[{i},{j}] = {str(Lnz.get((i, j), 0))[:40]}: M must be the "
                                            "Hessian of L in v")
    _check_mechanical_parts(system, mech, M, Mnz)

def _check_mechanical_parts(system, mech, M, Mnz) -> None:
    """U, K and b of the mechanical form (the compiled engine and the semi-implicit comparators
    build their equations from them, the generic engine from L and k) describe the same system:
    U, K, b free of v, L = v^T M v / 2 - U and k = K v + b. The identities are tested at random
    points in 40 digits (a wrong part differs at almost every point; symbolic simplification
    of a large L can take minutes): a residual above 1e-25 of the terms' size (Floats: their
    own precision) at two points where both sides are finite is a mismatch, which would make the engines integrate two
    different systems without a word."""
    import random
    try:
        U = sympy.sympify(mech.get("U", 0), strict=True)
        K = sympy.Matrix(mech["K"]) if mech.get("K") is not None else None
        b = sympy.Matrix(mech["b"]) if mech.get("b") is not None else None
    except (TypeError, ValueError, sympy.SympifyError) as exc:
        raise SystemDefinitionError(f"{system.name}: mechanical U, K, b are not expressions ({str(exc)[:80]})") from None
    if K is None:
        return
    if b is None:
        b = sympy.zeros(K.rows, 1)
    if b.rows * b.cols == K.rows:
        b = b.reshape(K.rows, 1)        # a row b is read as the column (as the compiled engine does)
    if K.shape != (system.m, system.n) or b.shape != (system.m, 1) or not isinstance(U, sympy.Expr) \
            or getattr(U, "is_Matrix", False):
        raise SystemDefinitionError(f"{system.name}: mechanical K must be {system.m} x {system.n}, b {system.m} x 1 "
                                    f"and U a scalar, got K {K.shape}, b {b.shape}")
    vs = set(system.v)
    known = set(system.q) | vs | {system.t} | set(system.params)
    Knz = _nonzero_entries(K)           # K is mostly zeros for large models: its m x n scan costs seconds
    for nm, e in [("U", U)] + [("K", x) for x in Knz.values()] + [("b", x) for x in b]:
        if getattr(e, "free_symbols", set()) - known:
            raise SystemDefinitionError(f"{system.name}: the mechanical parts do not match L and k ({nm} contains "
                                        f"symbols other than t, q and the parameters: "
                                        f"{sorted(map(str, e.free_symbols - known))[:3]})")
        if getattr(e, "free_symbols", set()) & vs:
            raise SystemDefinitionError(f"{system.name}: mechanical {nm} depends on the velocities; U, K, b are "
                                        "functions of t and q")
    vv = list(system.v)
    # v^T M v and K v over the nonzero entries (dense products are n^2 and m n terms)
    quad = sympy.Add(*[e * vv[i] * vv[j] for (i, j), e in Mnz.items()])
    Kv = [[] for _ in range(system.m)]
    for (i, j), e in Knz.items():
        Kv[i].append(e * vv[j])
    rows = [(f"k[{i}] = (K v + b)[{i}]", system.k[i], sympy.Add(*Kv[i]) + b[i]) for i in range(system.m)]
    rng = random.Random(12345)
    syms = list(system.q) + list(system.v) + [system.t] + list(system.params)
    # a parameter's float value as the exact rational it is: a Float (53 bits) bounds the precision
    # of the whole 40-digit evaluation, and the two sides, summed in different orders, then differ
    # far above 1e-25 (c = 0.7 in U refused a matching U: "-0.0621196 vs -0.0621196")
    fixed = {p: (sympy.Rational(val) if isinstance(val, (float, sympy.Float)) else sympy.sympify(val))
             for p, val in system._param_values.items() if not isinstance(val, str)}

    def mismatch(lhs, rhs):
        """A description of a test point where lhs and rhs differ, None when they agree at two
        points.

        Exact data must agree to 1e-25 of the terms' size (40 digits evaluated). A Float in the
        data carries its own precision (53 bits from Python floats), and the two sides may sum
        its terms in different orders: then the tolerance is 2^-prec times 16 per term.
        Six points in [0.3, 0.7] first; where fewer than two of them evaluate to finite real
        values (L defined only for q0 >= 1, a nan or zoo in U), up to 24 points in [-10, 10], and
        where those fail too the difference must be 0 as written: an identity left untested let any
        U or K through (the engines then integrated different systems without a word)."""
        floats = [f for e in (lhs, rhs) for f in e.atoms(sympy.Float)]
        tol = 1e-25
        if floats:
            nterms = len(sympy.Add.make_args(lhs)) + len(sympy.Add.make_args(rhs))
            tol = max(tol, 16.0 * nterms * 2.0 ** -min(f._prec for f in floats))
        tested = 0
        sides = [_point_evaluator(e) for e in (lhs, rhs)]

        def differ(pt):
            """A description where the sides differ at ``pt``, True where they agree, None where
            either side does not evaluate to a finite real number."""
            pt.update(fixed)
            try:
                a, c = (sympy.N(at(pt), 40) for at in sides)
                fa, fc = complex(a), complex(c)
            except (TypeError, ValueError, ZeroDivisionError, ArithmeticError):
                return None
            if not all(math.isfinite(z.real) and math.isfinite(z.imag) and z.imag == 0 for z in (fa, fc)):
                return None
            if abs(a - c) > tol * (1 + abs(fa) + abs(fc)):
                return f"fails at a test point: {str(sympy.N(a, 6))} vs {str(sympy.N(c, 6))}"
            return True

        def on_every_sign():
            # sides equal on the box only (U = x against Abs(x) in L): the engines integrated
            # different systems wherever a coordinate is negative (``signed_points``)
            if box_decides(lhs, rhs):
                return None
            for pt in signed_points(syms, rng):
                got = differ(pt)
                if got is not None and got is not True:
                    return got
            return None
        for i in range(6 + 24):
            if i == 6 and tested:
                return on_every_sign()  # the first box decides when one point evaluated there
            lo, hi = (300, 700) if i < 6 else (-10000, 10000)
            got = differ({x: sympy.Rational(rng.randint(lo, hi), 1000) for x in syms})
            if got is None:
                continue
            if got is not True:
                return got
            tested += 1
            if tested == 2:
                return on_every_sign()
        if tested:
            return on_every_sign()
        # no point evaluated: only a difference that is structurally 0 passes (no simplify(): on
        # user expressions it is unbounded, the reason system.numerically_zero replaced it)
        if sympy.sympify(lhs - rhs) == 0:
            return None
        return "cannot be evaluated at any test point and is not identically the same expression"

    def refuse(what, why):
        raise SystemDefinitionError(f"{system.name}: the mechanical parts do not match L and k ({what} {why}); "
                                    "the engines would integrate different systems")
    bad = mismatch(system.L, quad / 2 - U)
    if bad is not None:
        refuse("L = v^T M v / 2 - U", bad)
    if len(rows) > 8:
        # many rows: one random combination of them first (a wrong row changes it at almost every
        # point and weight); the rows one by one only to name the wrong one
        w = [sympy.Rational(rng.randint(1, 997), 997) for _ in rows]
        if mismatch(sympy.Add(*[wi * r[1] for wi, r in zip(w, rows)]),
                    sympy.Add(*[wi * r[2] for wi, r in zip(w, rows)])) is None:
            return
    for what, lhs, rhs in rows:
        bad = mismatch(lhs, rhs)
        if bad is not None:
            refuse(what, bad)


def _check_infinite_constants(named) -> None:
    """SystemDefinitionError naming an expression that holds sympy's zoo, nan, oo or -oo (a sympy
    L + zoo, or 1/0 evaluated by sympy before it reached here): the engines evaluated it and
    blamed the initial point ("the energy (8) at the initial point is nan: q0, v0 lie outside
    the domain") where the system itself is undefined everywhere."""
    bad = (sympy.zoo, sympy.nan, sympy.oo, -sympy.oo)
    for what, e in named:
        if e.has(*bad):
            found = sorted({str(a) for a in sympy.preorder_traversal(e) if a in bad})
            raise SystemDefinitionError(f"{what} contains {', '.join(found)} (an infinite or undefined constant): "
                                        "the system is not defined at any point")


#: distinct denominators ``_check_denominators`` tests (each costs a few 40-digit evaluations);
#: beyond them a system is built as before
MAX_DENOMINATOR_CHECKS = 32


def _check_denominators(system, exprs) -> None:
    """SystemDefinitionError naming a denominator of L, k or N that vanishes identically although
    it is not written as 0: (sin(q)^2 + cos(q)^2 - 1)^-1 is kept by sympy, and the engines then
    divided by its round-off (energy -9e15 with status 0). Tested by ``numerically_zero`` at
    40 digits (no simplify: unbounded on user expressions), at most MAX_DENOMINATOR_CHECKS
    distinct ones, numbers excluded (the parser refuses 1/0)."""
    seen = []
    for e in exprs:
        for node in sympy.preorder_traversal(sympy.sympify(e)):
            if (isinstance(node, sympy.Pow) and node.exp.is_negative and not node.base.is_number
                    and node.base not in seen):
                seen.append(node.base)
                if len(seen) >= MAX_DENOMINATOR_CHECKS:
                    break
        if len(seen) >= MAX_DENOMINATOR_CHECKS:
            break
    syms = list(system.q) + list(system.v) + [system.t] + list(system.params)
    for base in seen:
        if numerically_zero(base, syms):
            raise SystemDefinitionError(f"{system.name}: the denominator {_short(base)} vanishes identically "
                                        "(it is 0 to 40 digits at every test point): the system is undefined")


def _short(e, limit: int = 80) -> str:
    text = str(e)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def numerically_zero(e, syms, fixed=None, points: int = 3, signs: bool = False) -> bool:
    """Whether the expression ``e`` in ``syms`` vanishes: at ``points`` random rational points in
    [0.3, 0.7] (``fixed``: values of parameters) evaluated to 40 digits, each finite value within
    1e-25 of 0 relative to the size of its terms. A nonzero expression differs from 0 at almost
    every point; sympy.simplify of a large one (a power (q0 + ... + q7)^16) ran for minutes. Where
    fewer than two points evaluate (domain errors), False: the caller keeps the safe answer.

    ``signs``: also 0 at every point of ``signed_points`` where it evaluates. An analytic expression
    that vanishes on the box vanishes everywhere, but Abs(x) - x, sqrt(x^2) - x or Max(0, x - 1) vanish
    on the box only: the mechanical-form detectors took such a gyroscopic term for 0 and dropped it."""
    import random
    e = sympy.sympify(e)
    if e == 0:
        return True
    rng = random.Random(271828)
    at = _point_evaluator(e)
    terms = [_point_evaluator(t) for t in sympy.Add.make_args(e)][:64]

    def value(pt):
        """|e| and the size of its terms at ``pt``, or None where it does not evaluate to a finite number."""
        pt.update(fixed or {})
        try:
            val = complex(sympy.N(at(pt), 40))
            scale = sum(abs(complex(sympy.N(t(pt), 20))) for t in terms)
        except (TypeError, ValueError, ZeroDivisionError, ArithmeticError):
            return None
        if not (math.isfinite(val.real) and math.isfinite(val.imag) and math.isfinite(scale)):
            return None
        return abs(val), scale
    tested = 0
    for _ in range(2 * points):
        got = value({x: sympy.Rational(rng.randint(300, 700), 1000) for x in syms})
        if got is None:
            continue
        if got[0] > 1e-25 * (1 + got[1]):
            return False
        tested += 1
        if tested == points:
            break
    if tested < 2:
        return False
    if signs and not box_decides(e):
        for pt in signed_points(syms, rng):
            got = value(pt)
            if got is not None and got[0] > 1e-25 * (1 + got[1]):
                return False
    return True


#: functions meromorphic in the whole plane: an expression built from them, +, * and integer powers
#: is meromorphic, analytic off a discrete set whose complement is connected, so an identity that
#: holds on a box holds at every point where it is defined (not atan: atan(1/x) + atan(x) = pi/2 for
#: x > 0 only, the branch points of atan met through the pole of 1/x)
_MEROMORPHIC = (sympy.sin, sympy.cos, sympy.tan, sympy.cot, sympy.sec, sympy.csc, sympy.exp, sympy.sinh,
                sympy.cosh, sympy.tanh, sympy.coth, sympy.sech, sympy.csch, sympy.erf, sympy.erfc, sympy.sinc)


def box_decides(*exprs) -> bool:
    """Whether equality on [0.3, 0.7] implies equality everywhere (the identity theorem): no node
    but +, *, integer powers and ``_MEROMORPHIC`` functions. Abs, Max, Piecewise, sqrt, asin, log
    and the like agree with another expression on a box and not beyond it (``signed_points``)."""
    for e in exprs:
        for node in sympy.preorder_traversal(e):
            if isinstance(node, sympy.Pow):
                if not node.exp.is_Integer:
                    return False
            elif node.args and not isinstance(node, (sympy.Add, sympy.Mul) + _MEROMORPHIC):
                return False        # Abs, Max (not a sympy Function), Piecewise, asin, log, ...
    return True


def signed_points(syms, rng, count: int = 8) -> list:
    """``count`` exact points {symbol: Rational} with magnitudes in [0.3, 10] and, for every three
    consecutive symbols, all eight sign patterns: where an identity tested on [0.3, 0.7] alone
    holds on the positive orthant only (Abs(x) = x), one of them tells."""
    return [{x: (-1 if (k >> (j % 3)) & 1 else 1) * sympy.Rational(rng.randint(300, 10000), 1000)
             for j, x in enumerate(syms)} for k in range(count)]


def _point_evaluator(e):
    """pt -> e at the exact point ``pt`` ({symbol: Rational}): substituted in symengine (C++;
    sympy's xreplace rebuilds the tree through its constructors, ~5x slower on a large L),
    returned as a sympy number or expression for ``sympy.N``; sympy's xreplace where symengine
    does not take the expression."""
    try:
        import symengine
        se = symengine.sympify(e)
    except Exception:                   # noqa: BLE001 - a function symengine does not know
        return e.xreplace

    def at(pt):
        try:
            r = se.subs({symengine.sympify(k): symengine.sympify(v) for k, v in pt.items()})
            return sympy.sympify(r)
        except Exception:               # noqa: BLE001 - evaluation symengine refuses: sympy's
            return e.xreplace(pt)
    return at


def _nonzero_entries(A) -> dict:
    """{(i, j): entry} of the structurally nonzero entries of a sympy matrix."""
    return {ij: e for ij, e in A.todok().items() if e != 0}


def _derived_nonzeros(system, name):
    """{(i, j): sympy entry} of the nonzero entries of the derived matrix ``name`` (``L_vv``, ...):
    from the sparse derivation unless the attribute was replaced since (then from the attribute);
    None when the system has neither."""
    d = system.__dict__.get("_derived")
    own = system.__dict__.get(name)
    if d is not None and name in d and (own is None or own is d._sympy.get(name)):
        return d.nonzeros(name)
    val = getattr(system, name, None)
    return None if val is None else _nonzero_entries(sympy.Matrix(val))


def _finite_param(x, p):
    """A parameter's value as a sympy number, checked: text through ``_param_value``, a number a
    finite real one (``_checked_param``: nan, inf, 1j, True refused). The scene builders' rule."""
    if not isinstance(x, str):
        _checked_param(p, x)
    return _param_value(x, p)


def _param_value(x, p):
    """A parameter's value as a sympy number: a string through the tableau entry parser
    (``numbers.parse_number``: "1/2", "sqrt(2)", "9.81"), never nsimplify or sympify of text."""
    from .numbers import parse_number
    if isinstance(x, str):
        return parse_number(x, f"parameter {p}", error=SystemDefinitionError)
    try:
        return sympy.sympify(x, strict=True)
    except (sympy.SympifyError, TypeError, ValueError):
        raise SystemDefinitionError(f"parameter {p}: {x!r} is not a number") from None


def _parse_strings(L, k, q, v, t, params, nonideal, psi, mechanical):
    """The arguments of LagrangianSystem with every string in them parsed (never evaluated):
    names of q, v, t, psi and params become Symbols, L, k, N and the mechanical parts go
    through ``numbers.parse_expression`` in the declared symbols, parameter values through
    ``numbers.parse_number``."""
    if isinstance(q, (str, bytes)) or isinstance(v, (str, bytes)):
        raise SystemDefinitionError("q and v must be lists of symbols (or of names), not strings")
    q = _symbol_list(q, "q")
    v = _symbol_list(v, "v")
    t = _time_symbol(t) if t is not None else None
    if isinstance(params, dict):
        params = {_symbol(p, "parameter"): (_param_value(x, p) if isinstance(x, str) else x)
                  for p, x in params.items()}
    elif isinstance(params, (list, tuple)):
        params = [_symbol(p, "parameter") for p in params]
    elif isinstance(params, str):
        raise SystemDefinitionError("params must be a list of symbols (or names) or a dict, not a string")
    if psi is not None:
        psi = _symbol_list(psi, "psi")
    m = len(k) if isinstance(k, (list, tuple, np.ndarray)) else getattr(k, "rows", 1)
    names = _names(q if isinstance(q, list) else [], v if isinstance(v, list) else [], [t or sympy.Symbol("t")],
                   list(params) if isinstance(params, (dict, list)) else [],
                   psi if isinstance(psi, list) else sympy.symbols(f"psi1:{m + 1}"))
    L = _exprs(L, names, "L")
    k = _exprs(k, names, "k")
    if nonideal is not None:
        if isinstance(nonideal, (str, bytes, dict)) or not hasattr(nonideal, "__iter__"):
            from .validate import _describe
            raise SystemDefinitionError(f"nonideal must be a list of n expressions, got {_describe(nonideal)}")
        nonideal = [_scalar_expr(e, f"nonideal[{i}]")
                    for i, e in enumerate(_exprs(list(nonideal), names, "nonideal"))]
    if isinstance(mechanical, dict):
        mechanical = {key: _exprs(val, names, f"mechanical[{key!r}]") for key, val in mechanical.items()}
    return L, k, q, v, t, params, nonideal, psi, mechanical


def _parse_params(params):
    """(tuple of parameter symbols, {symbol: default value})."""
    if params is None:
        return (), {}
    if not isinstance(params, (dict, list, tuple)):
        raise SystemDefinitionError(f"params must be a list of symbols (or names) or a dict, got "
                                    f"{type(params).__name__}")
    items = list(params.items()) if isinstance(params, dict) else [(p, None) for p in params]
    syms, vals = [], {}
    for p, val in items:
        p = sympy.Symbol(p) if isinstance(p, str) else p
        if not isinstance(p, sympy.Symbol):
            raise SystemDefinitionError(f"parameters must be sympy symbols, got {str(p)[:60]!r}")
        if p in syms:
            raise SystemDefinitionError(f"parameter {p} is listed twice")
        syms.append(p)
        if val is not None:
            vals[p] = _checked_param(p, val)
    return tuple(syms), vals


def _sympify_L_k(L, k):
    """L as a scalar sympy expression and k as an m x 1 Matrix (m = 0: a 0 x 1 Matrix), or a
    SystemDefinitionError saying what is wrong (not a TypeError from inside sympy)."""
    if L is None or k is None:
        raise SystemDefinitionError(f"L and k must be sympy expressions, got L = {L!r}, k = {k!r}")
    try:
        Ls = sympy.sympify(L, strict=not isinstance(L, str))
        ks = [sympy.sympify(e, strict=not isinstance(e, str))
              for e in (list(k) if isinstance(k, (list, tuple, sympy.MatrixBase)) else [k])]
    except (sympy.SympifyError, TypeError, ValueError, SyntaxError) as exc:
        raise SystemDefinitionError(f"L and k must be sympy expressions: {str(exc).splitlines()[0][:120]}") from None
    def scalar(e):
        return isinstance(e, sympy.Expr) and not getattr(e, "is_Matrix", False)
    if not scalar(Ls) or not all(scalar(e) for e in ks):
        raise SystemDefinitionError("L must be a scalar expression and k a list of scalar expressions")
    # m = 0 is allowed: (21) without its multipliers is the symplectic partitioned RK method
    # (A, A_hat) of the Lagrangian, which the same suite checks
    return Ls, sympy.Matrix(ks) if ks else sympy.zeros(0, 1)


_MPF_ONLY = {mpmath.mpf}


def _integer_entries(exprs):
    """Per output of a lambdified list (``LagrangianSystem._arrays``): [(flat index, mpf)] of
    its integer entries (exact whatever the precision)."""
    plan = []
    for e in exprs:
        flat = list(e) if isinstance(e, sympy.MatrixBase) else list(np.asarray(e, dtype=object).reshape(-1))
        plan.append([(i, mpmath.mpf(int(x))) for i, x in enumerate(map(sympy.sympify, flat))
                     if x.is_Integer and abs(int(x)) < 2 ** 53])
    return plan


def _keep_empty_shapes(f, shapes):
    """``f`` with its outputs of the given empty shapes (m = 0: k, K, ...) returned as empty
    arrays of that shape (lambdify prints them as [])."""
    def g(*args):
        return [np.zeros(sh) if sh is not None else out for out, sh in zip(f(*args), shapes)]
    return g


def _arr(x, backend):
    a = np.array(x, dtype=object if backend.is_mp else float)
    if backend.is_mp:
        flat = a.reshape(-1)
        for i, e in enumerate(flat):
            if not isinstance(e, mpmath.mpf):
                flat[i] = mpmath.mpf(e)
    return a
