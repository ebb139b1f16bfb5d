"""The derived expressions of a Lagrangian system (1): grad_q L, grad_v L, the Hessians, K = k_v,
k_q, k_t, h R = -K^T lam and its partials, the energy (8) and the partials of a nonideal term N.

Two things make this scale with the model, not with n^2 times its size:

* structural sparsity: an expression is differentiated only with respect to the symbols it
  contains, and a sum only term by term, each term with respect to its own symbols (so grad L
  costs the size of L, not n times it); structural zeros are never computed, and a symmetric
  Hessian's lower triangle is the upper one's entry (the same object);
* a C++ engine: L, k and N are converted once to symengine, where differentiation is one to two
  orders of magnitude faster than sympy's, when every node of them is one that symengine
  differentiates exactly as sympy does (``SE_FUNCTIONS``: the elementary functions; numbers
  kept exact, Floats carried as placeholder symbols so that no precision is lost, symbols with
  assumptions or clashing names carried as placeholders too). Anything else (Abs, sign,
  Piecewise, Min, user functions, ...) is differentiated by sympy, with the same sparse
  algorithm.

The results stay in the engine's objects until someone asks for them: ``Derived.get(name)`` turns
one whole matrix into a sympy Matrix (what the generic mpmath engine, the audit and the claims use,
exact as before), ``Derived.nonzeros(name)`` only its nonzero entries (what code generation
needs). The symengine results equal sympy's derivatives up to simplification;
``tests/core/test_derive.py`` checks that numerically on every scene and on random systems.
"""
from __future__ import annotations

import threading

import sympy

try:                   # speed only: without it every derivative is sympy's (same algorithm)
    import symengine as _se
except ImportError:    # pragma: no cover - symengine is a dependency
    _se = None

#: sympy functions that symengine converts, differentiates and converts back as sympy does
#: (checked against sympy's derivatives at random points in tests/core/test_derive.py)
SE_FUNCTIONS = tuple(getattr(sympy, f) for f in (
    "sin", "cos", "tan", "cot", "sec", "csc", "asin", "acos", "atan", "acot", "sinh", "cosh", "tanh", "coth",
    "asinh", "acosh", "atanh", "exp", "log", "atan2"))
_SE_NODES = (sympy.Add, sympy.Mul, sympy.Pow, sympy.Symbol, sympy.Integer, sympy.Rational, sympy.Float) + SE_FUNCTIONS
_SE_CONSTANTS = (sympy.pi, sympy.E)

#: the names of ``Derived`` (the attributes LagrangianSystem exposes) and their shapes
#: (rows, cols); None: a scalar
NAMES = ("L_q", "L_v", "L_vv", "L_vq", "L_qq", "L_vt", "L_t", "k_q", "k_v", "k_t", "R_lam", "R_q", "R_v",
         "energy_expr", "N_q", "N_v", "N_psi")


class _SympyEngine:
    name = "sympy"
    zero = sympy.S.Zero

    @staticmethod
    def add(terms):
        return sympy.Add(*terms)

    @staticmethod
    def to_sympy(e):
        return e


class _SymengineEngine:
    name = "symengine"

    def __init__(self, back: dict):
        self.zero = _se.Integer(0)
        self.back = back                  # placeholder sympy symbol -> original symbol or Float

    @staticmethod
    def add(terms):
        return _se.Add(*terms)

    def to_sympy(self, e):
        s = e._sympy_()
        return s.xreplace(self.back) if self.back else s


def _is_zero(e):
    return e == 0


def _partials(e, wrt: dict, engine) -> dict:
    """{j: d e / d x} for the symbols x of ``wrt`` (x -> j) that ``e`` contains, structural
    zeros left out. A sum is differentiated term by term, each term only with respect to the
    symbols in it."""
    fs = [x for x in e.free_symbols if x in wrt]
    if not fs:
        return {}
    if len(fs) > 1 and e.is_Add:
        groups: dict = {}
        for a in e.args:
            for x in a.free_symbols:
                if x in wrt:
                    groups.setdefault(x, []).append(a)
        out = {wrt[x]: engine.add([a.diff(x) for a in terms]) for x, terms in groups.items()}
    else:
        out = {wrt[x]: e.diff(x) for x in fs}
    return {j: d for j, d in out.items() if not _is_zero(d)}


def _jacobian(f: dict, wrt: dict, engine, symmetric=False) -> dict:
    """The nonzero entries {(i, j): d f_i / d x_j} of a sparse vector f = {i: expr}; with
    ``symmetric`` (f a gradient, wrt its own variables) only j >= i is differentiated and the
    entry (j, i) is the same object as (i, j)."""
    J = {}
    for i, e in f.items():
        for j, d in _partials(e, wrt, engine).items():
            if symmetric and j < i:
                continue
            J[i, j] = d
            if symmetric:
                J[j, i] = d
    return J


class Derived:
    """The derived expressions of one system, sparse ({(i, j): expr}, zeros left out) in the
    engine's objects, each converted to sympy when it is first asked for (then kept)."""

    def __init__(self, engine, shapes: dict, entries: dict):
        self.engine = engine.name
        self._engine = engine
        self.shapes = shapes
        self._entries = entries
        self._sympy: dict = {}
        self._nz: dict = {}
        self._lock = threading.Lock()

    def __contains__(self, name):
        return name in self.shapes

    def get(self, name):
        """The sympy Matrix (a scalar: the sympy expression) ``name``."""
        hit = self._sympy.get(name)
        if hit is not None:
            return hit
        shape = self.shapes[name]
        nz = self.nonzeros(name)
        if shape is None:
            val = nz.get((0, 0), sympy.S.Zero)
        else:
            val = sympy.zeros(*shape)
            for (i, j), e in nz.items():
                val[i, j] = e
        with self._lock:
            return self._sympy.setdefault(name, val)

    def nonzeros(self, name) -> dict:
        """{(i, j): sympy expression} of the structurally nonzero entries of ``name`` (a scalar:
        key (0, 0)); a symmetric Hessian's mirrored entries are one sympy object."""
        hit = self._nz.get(name)
        if hit is not None:
            return hit
        out = _back(self._entries[name], self._engine)
        with self._lock:
            return self._nz.setdefault(name, out)

    def positions(self, name) -> set:
        """The (i, j) of the structurally nonzero entries of ``name``, without converting them."""
        return set(self._entries[name])

    def count(self, name) -> int:
        """Number of structurally nonzero entries of ``name``."""
        return len(self._entries[name])

    def xreplaced(self, rule: dict) -> "Derived":
        """A sympy Derived with ``rule`` applied to every entry."""
        entries = {}
        for name in self.shapes:
            conv = {}
            for key, e in self.nonzeros(name).items():
                if id(e) not in conv:
                    conv[id(e)] = e.xreplace(rule)
                entries.setdefault(name, {})[key] = conv[id(e)]
            entries.setdefault(name, {})
        return Derived(_SympyEngine(), dict(self.shapes), entries)

    def all_sympy(self) -> dict:
        return {name: self.get(name) for name in self.shapes}

    def __getstate__(self):              # picklable whatever the engine: as sympy
        return {"shapes": self.shapes, "sympy": self.all_sympy()}

    def __setstate__(self, state):
        self.engine = "sympy"
        self._engine = _SympyEngine()
        self.shapes = state["shapes"]
        self._sympy = dict(state["sympy"])
        self._entries = {name: _sparse_of(val) for name, val in self._sympy.items()}
        self._nz = {}
        self._lock = threading.Lock()


def _sparse_of(val) -> dict:
    if isinstance(val, sympy.MatrixBase):
        return {(i, j): val[i, j] for i in range(val.rows) for j in range(val.cols) if not val[i, j].is_zero}
    return {} if val == 0 else {(0, 0): val}


def _engine_for(exprs, symbols):
    """(engine, convert) for the sympy ``exprs`` in the ``symbols`` the derivatives are taken
    in: symengine when every node of every expression is in ``_SE_NODES`` or a constant pi, E,
    else sympy. ``convert`` maps a sympy expression (and a symbol) to the engine's."""
    scan = _scan(exprs) if _se is not None else None
    if scan is None:
        return _SympyEngine(), (lambda e: e)
    free, floats = scan
    free |= set(symbols)
    names = [getattr(s, "name", None) for s in free]
    plain = all(type(s) is sympy.Symbol and s.assumptions0 == {"commutative": True} for s in free) \
        and len(set(names)) == len(names)
    rep = {}
    taken = set(names)

    def fresh(stem):
        i = len(rep)
        while f"{stem}{i}" in taken:
            i += 1
        taken.add(f"{stem}{i}")
        return sympy.Symbol(f"{stem}{i}")
    if not plain:
        for s in sorted(free, key=sympy.default_sort_key):
            rep[s] = fresh("_lda_s")
    for x in sorted(floats, key=sympy.default_sort_key):
        rep[x] = fresh("_lda_f")
    back = {p: s for s, p in rep.items()}
    engine = _SymengineEngine(back)
    cache: dict = {}

    def convert(e):
        e = sympy.sympify(e)
        hit = cache.get(e)
        if hit is None:
            hit = cache[e] = _se.sympify(e.xreplace(rep) if rep else e)
        return hit
    return engine, convert


def _all_se_nodes(exprs) -> bool:
    return _scan(exprs) is not None


def _scan(exprs):
    """(free symbols, Floats) of sympy expressions whose every node is in ``_SE_NODES`` or a
    constant pi, E, else None: one walk of the expression graph (free_symbols and atoms(Float)
    walked it twice more: a second of the bicycle's code generation). Such expressions bind no
    variables, so their Symbol nodes are their free symbols."""
    seen, todo, syms, floats = set(), list(exprs), set(), set()
    while todo:
        e = todo.pop()
        if e in seen:
            continue
        seen.add(e)
        if not isinstance(e, _SE_NODES) and e not in _SE_CONSTANTS:
            return None
        if isinstance(e, sympy.Symbol):
            syms.add(e)
        elif isinstance(e, sympy.Float):
            if not e.is_finite:
                return None
            floats.add(e)
        elif isinstance(e, sympy.Function) and len(e.args) != (2 if isinstance(e, sympy.atan2) else 1):
            return None
        todo.extend(e.args)
    return syms, floats


def derive(L, k, q, v, t, lam, N=None, psi=None, engine: str = "auto") -> Derived:
    """The derived expressions (``NAMES``) of L(t, q, v), the constraints k (a list or Matrix of
    m expressions) and the nonideal term N(t, q, v, psi) (n expressions, or None). ``engine``:
    "auto" (symengine where it differentiates every node, else sympy) or "sympy"."""
    k = list(k)
    N = None if N is None else list(N)
    n, m = len(q), len(k)
    exprs = [sympy.sympify(L)] + [sympy.sympify(e) for e in k] + ([sympy.sympify(e) for e in N] if N else [])
    syms = list(q) + list(v) + [t] + list(lam) + (list(psi) if N else [])
    if engine == "sympy":
        eng, conv = _SympyEngine(), (lambda e: sympy.sympify(e))
    else:
        eng, conv = _engine_for(exprs, syms)
    Q = {conv(x): j for j, x in enumerate(q)}
    Vs = [conv(x) for x in v]
    V = {x: j for j, x in enumerate(Vs)}
    T = {conv(t): 0}
    lam_e = [conv(x) for x in lam]
    L = conv(L)
    K = {i: conv(e) for i, e in enumerate(k) if not sympy.sympify(e).is_zero}
    # grad L by terms: one pass over L for q and v together
    grad = _partials(L, {**{x: ("q", j) for x, j in Q.items()}, **{x: ("v", j) for x, j in V.items()}}, eng)
    Lq = {j: d for (w, j), d in grad.items() if w == "q"}
    Lv = {j: d for (w, j), d in grad.items() if w == "v"}
    Lvv = _jacobian(Lv, V, eng, symmetric=True)
    Lvq = _jacobian(Lv, Q, eng)                        # d(grad_v L)/dq
    Lqq = _jacobian(Lq, Q, eng, symmetric=True)
    Lvt = {i: d for i, e in Lv.items() for d in _partials(e, T, eng).values()}
    Lt = {0: d for d in _partials(L, T, eng).values()}
    kq = _jacobian(K, Q, eng)
    kv = _jacobian(K, V, eng)                          # K of (1d)
    kt = {i: d for i, e in K.items() for d in _partials(e, T, eng).values()}
    # h R_i = -K_i^T (h Psi_i): R_lam[j] = -sum_i K[i, j] lam_i
    cols: dict = {}
    for (i, j), e in sorted(kv.items()):
        cols.setdefault(j, []).append(e * lam_e[i])
    R = {j: -eng.add(terms) for j, terms in cols.items()}
    Rq = _jacobian(R, Q, eng)
    Rv = _jacobian(R, V, eng)
    energy = eng.add([Lv[j] * Vs[j] for j in sorted(Lv)]) - L      # (8): E = L_v v - L
    vec = lambda d: {(i, 0): e for i, e in d.items()}            # noqa: E731
    entries = {"L_q": vec(Lq), "L_v": vec(Lv), "L_vv": Lvv, "L_vq": Lvq, "L_qq": Lqq, "L_vt": vec(Lvt),
               "L_t": vec(Lt), "k_q": kq, "k_v": kv, "k_t": vec(kt), "R_lam": vec(R), "R_q": Rq, "R_v": Rv,
               "energy_expr": {} if _is_zero(energy) else {(0, 0): energy}}
    shapes = {"L_q": (n, 1), "L_v": (n, 1), "L_vv": (n, n), "L_vq": (n, n), "L_qq": (n, n), "L_vt": (n, 1),
              "L_t": None, "k_q": (m, n), "k_v": (m, n), "k_t": (m, 1), "R_lam": (n, 1), "R_q": (n, n),
              "R_v": (n, n), "energy_expr": None}
    if N is not None:
        P = {conv(x): j for j, x in enumerate(psi)}
        Nd = {i: conv(e) for i, e in enumerate(N) if not sympy.sympify(e).is_zero}
        entries.update(N_q=_jacobian(Nd, Q, eng), N_v=_jacobian(Nd, V, eng), N_psi=_jacobian(Nd, P, eng))
        shapes.update(N_q=(n, n), N_v=(n, n), N_psi=(n, len(psi)))
    return Derived(eng, shapes, entries)


def sparse_jacobian(f, xs, symmetric=False) -> dict:
    """{(i, j): d f_i / d x_j} (sympy) of the nonzero entries, for sympy expressions f and
    symbols xs, with the algorithm and engine of ``derive``; ``symmetric``: f is a gradient in
    xs, only j >= i is differentiated and (j, i) is the same object."""
    f = [sympy.sympify(e) for e in f]
    eng, conv = _engine_for([e for e in f if not e.is_zero] or [sympy.S.Zero], xs)
    X = {conv(x): j for j, x in enumerate(xs)}
    J = _jacobian({i: conv(e) for i, e in enumerate(f) if not e.is_zero}, X, eng, symmetric)
    return _back(J, eng)


def sparse_gradient_hessian(U, xs) -> tuple[dict, dict]:
    """({j: dU/dx_j}, {(i, j): d^2 U / dx_i dx_j}) (sympy, nonzero entries only) of a sympy
    expression U."""
    U = sympy.sympify(U)
    eng, conv = _engine_for([U], xs)
    X = {conv(x): j for j, x in enumerate(xs)}
    g = _partials(conv(U), X, eng)
    H = _jacobian(g, X, eng, symmetric=True)
    return _back(g, eng), _back(H, eng)


def _back(entries: dict, eng) -> dict:
    conv, out = {}, {}
    for key, e in entries.items():
        if id(e) not in conv:
            conv[id(e)] = eng.to_sympy(e)
        out[key] = conv[id(e)]
    return out


def _real_dummies(system) -> dict:
    """{symbol: real Dummy} when L, k or N contain Abs, sign, re, im or arg (whose derivatives
    with respect to a complex symbol are unprintable Derivative(re(x), x) terms), else {}."""
    fns = (sympy.Abs, sympy.sign, sympy.re, sympy.im, sympy.arg)
    exprs = [system.L, system.k] + ([system.N] if system.N is not None else [])
    if not any(e.has(*fns) for e in exprs):
        return {}
    syms = [x for x in list(system.q) + list(system.v) + [system.t]
            if isinstance(x, sympy.Symbol) and not x.is_real]
    return {x: sympy.Dummy(x.name, real=True) for x in syms}


def real_jacobian(exprs, wrt, symbols):
    """``exprs.jacobian(wrt)`` with Abs, sign, re, im, arg differentiated as functions of real
    variables (``symbols``: every symbol of exprs that is a coordinate), as ``_derive`` does."""
    exprs = sympy.Matrix(exprs)
    fns = (sympy.Abs, sympy.sign, sympy.re, sympy.im, sympy.arg)
    if not exprs.has(*fns):
        return exprs.jacobian(list(wrt))
    reps = {x: sympy.Dummy(x.name, real=True) for x in symbols if isinstance(x, sympy.Symbol) and not x.is_real}
    J = exprs.xreplace(reps).jacobian([reps.get(x, x) for x in wrt])
    return J.xreplace({d: x for x, d in reps.items()})


def install(system, engine: str = "auto") -> Derived:
    """Derive the expressions of ``system`` (a LagrangianSystem: L, k, q, v, t, lam, N, psi) and
    keep them in ``system._derived``; ``LagrangianSystem`` turns each into its sympy attribute
    (``system.L_vv``, ...) when it is first read. With Abs, sign, re, im or arg in L, k or N the
    coordinates are real Dummies while differentiating (their derivatives with respect to a
    complex symbol are unprintable Derivative(re(x), x) terms), by sympy."""
    reps = _real_dummies(system)
    if reps:
        X = lambda e: None if e is None else e.xreplace(reps)      # noqa: E731
        d = derive(X(system.L), X(system.k), [reps.get(x, x) for x in system.q], [reps.get(x, x) for x in system.v],
                   reps.get(system.t, system.t), system.lam, N=X(system.N),
                   psi=system.psi if system.N is not None else None, engine="sympy")
        d = d.xreplaced({dm: x for x, dm in reps.items()})
    else:
        d = derive(system.L, system.k, system.q, system.v, system.t, system.lam,
                   N=system.N, psi=system.psi if system.N is not None else None, engine=engine)
    system.__dict__["_derived"] = d
    for name in NAMES:                   # a new derivation replaces what an old one left
        system.__dict__.pop(name, None)
    return d
