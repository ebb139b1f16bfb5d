"""SPARK tableaux: the coefficients c, A, A_hat, A_tilde, b, b_hat, b_tilde, omega of (21).

A tableau is data. It is held either exactly (sympy numbers: rationals, radicals, CRootOf) or
as a builder that computes the coefficients at any requested precision with guard digits
(mpmath). Both give float64 arrays (``arrays(None)``) or mpf object arrays
(``arrays(dps)``) to the integrator through the same call.

Families (section 7 and [26, 27]):

* ``gauss(s)``: A = A_hat = A_tilde = Gauss collocation, order 2s.
* ``lobatto_iiia_iiib(s)``: A = IIIA, A_hat = A_tilde = IIIB, order 2s-2.
* ``lobatto_iiia_iiib_iiid(s)``: A = IIIA, A_hat = IIIB, A_tilde = IIID = (IIIC + IIIC*)/2.
* ``euler_i()``, ``euler_ii()``: the "symplectic" Euler SPARK methods of 7.1-7.2, order 1.

Each coefficient matrix is built from its own defining conditions (IIIA from C(s), IIIB from
D(s), IIIC from a_i1 = b_1 and C(s-1), IIIC* from a_is = 0 and C(s-1)), never from (22b), so
that checking (22b) on them is a real test.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Callable

import mpmath
import numpy as np
import sympy
from sympy import QQ
from sympy.polys.matrices import DomainMatrix

from .errors import TableauError

NAMES = ("c", "A", "A_hat", "A_tilde", "b", "b_hat", "b_tilde", "omega")
MATRIX_NAMES = ("A", "A_hat", "A_tilde", "omega")
VECTOR_NAMES = ("c", "b", "b_hat", "b_tilde")


def guard_digits(s: int) -> int:
    """Extra digits for building s-stage coefficients: Vandermonde systems on [0, 1] lose
    about 0.6 s digits, node polishing a few more."""
    return 15 + 2 * s


@dataclass
class SparkTableau:
    """Coefficients of an s-stage SPARK method (21).

    ``exact`` maps each name in NAMES to a sympy Matrix (vectors as s x 1, omega as
    (s-1) x s); it is None for tableaux known only numerically. ``builder(dps)`` returns the
    same entries as nested lists of mpf correct to ``dps`` digits. ``source_digits`` is the
    precision of the input entries (None when exact or computable to any precision).
    """

    name: str
    s: int
    exact: dict | None = None
    builder: Callable[[int], dict] | None = None
    source_digits: int | None = None
    claimed_order: int | None = None
    family: str = "custom"
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    # --- numeric views ---------------------------------------------------------------
    def mp_entries(self, dps: int) -> dict:
        """Entries as nested lists of mpf, correct to ``dps`` digits (or to the input
        precision for tableaux read from floats)."""
        key = ("mp", dps)
        if key not in self._cache:
            if self.builder is not None:
                with mpmath.workdps(dps):
                    raw = self.builder(dps)
            else:
                with mpmath.workdps(dps + 10):
                    raw = {k: _sympy_to_mp(v, dps) for k, v in self.exact.items()}
            with mpmath.workdps(dps):
                self._cache[key] = {k: _round_nested(v) for k, v in raw.items()}
        return self._cache[key]

    def arrays(self, dps: int | None = None) -> "TableauArrays":
        """Coefficients as numpy arrays: float64 when ``dps`` is None, else mpf objects."""
        key = ("arr", dps)
        if key not in self._cache:
            ent = self.mp_entries(max(dps or 0, 20))
            if dps is None:
                conv = {k: np.array(_nested_float(v), dtype=float) for k, v in ent.items()}
            else:
                conv = {k: np.array(v, dtype=object) for k, v in ent.items()}
            s = self.s
            for k in VECTOR_NAMES:
                conv[k] = conv[k].reshape(s)
            conv["omega"] = conv["omega"].reshape(max(s - 1, 0), s)
            for k in ("A", "A_hat", "A_tilde"):
                conv[k] = conv[k].reshape(s, s)
            self._cache[key] = TableauArrays(dps=dps, **conv)
        return self._cache[key]

    def field_entries(self):
        """(K, entries) with every exact entry converted into one algebraic number field K,
        where equality is decidable: the basis for exact checks of (22) and (23)."""
        if not self.is_exact:
            raise TableauError(f"tableau {self.name} is not exact")
        if "field" not in self._cache:
            from sympy.polys.constructor import construct_domain
            flat = [(k, i, j) for k, M in self.exact.items() for i in range(M.rows) for j in range(M.cols)]
            vals = [self.exact[k][i, j] for k, i, j in flat]
            K, elems = construct_domain(vals, extension=True) if vals else (QQ, [])
            out = {k: [[None] * M.cols for _ in range(M.rows)] for k, M in self.exact.items()}
            for (k, i, j), e in zip(flat, elems):
                out[k][i][j] = K.convert(e)
            for k in VECTOR_NAMES:
                out[k] = [row[0] for row in out[k]]
            self._cache["field"] = (K, out)
        return self._cache["field"]

    @property
    def is_exact(self) -> bool:
        return self.exact is not None and self.source_digits is None

    def with_entry(self, name: str, i: int, j: int | None, delta) -> "SparkTableau":
        """A copy with one entry changed by ``delta`` (negative controls)."""
        if self.exact is not None:
            ex = {k: sympy.Matrix(v) for k, v in self.exact.items()}
            if j is None:
                ex[name][i, 0] += sympy.nsimplify(delta)
            else:
                ex[name][i, j] += sympy.nsimplify(delta)
            return SparkTableau(f"{self.name}+d{name}[{i},{j}]", self.s, exact=ex,
                                claimed_order=None, family="perturbed")
        base = self.builder

        def builder(dps, base=base):
            ent = {k: [list(r) if isinstance(r, list) else r for r in v] for k, v in base(dps).items()}
            if j is None:
                ent[name][i] = ent[name][i] + mpmath.mpf(delta)
            else:
                ent[name][i][j] = ent[name][i][j] + mpmath.mpf(delta)
            return ent
        return SparkTableau(f"{self.name}+d{name}[{i},{j}]", self.s, builder=builder,
                            source_digits=self.source_digits, family="perturbed")

    # --- JSON ----------------------------------------------------------------------
    def to_json_dict(self, dps: int = 40) -> dict:
        """Entries as exact strings when exact, else decimal strings with ``dps`` digits."""
        out = {"name": self.name}
        if self.exact is not None:
            for k, M in self.exact.items():
                out[k] = _matrix_to_json(M, k, str)
        else:
            ent = self.mp_entries(dps)
            for k, v in ent.items():
                out[k] = _map_nested(v, lambda x: mpmath.nstr(x, dps))
        return out

    def save(self, path, dps: int = 40) -> None:
        from .io import atomic_write_json
        atomic_write_json(path, self.to_json_dict(dps))


@dataclass
class TableauArrays:
    """Numeric coefficients for one precision (float64 when dps is None)."""

    dps: int | None
    c: np.ndarray
    A: np.ndarray
    A_hat: np.ndarray
    A_tilde: np.ndarray
    b: np.ndarray
    b_hat: np.ndarray
    b_tilde: np.ndarray
    omega: np.ndarray


# --- helpers ---------------------------------------------------------------------------
def _sympy_to_mp(M, dps):
    prec_digits = dps + 10
    rows = []
    for i in range(M.rows):
        row = []
        for j in range(M.cols):
            val = sympy.N(M[i, j], prec_digits)
            if not val.is_real and val.is_number:
                val = sympy.re(val)
            row.append(mpmath.mpf(str(val)) if val != 0 else mpmath.mpf(0))
        rows.append(row)
    return rows


def _round_nested(v):
    if isinstance(v, list):
        return [_round_nested(x) for x in v]
    return +mpmath.mpf(v)


def _nested_float(v):
    if isinstance(v, list):
        return [_nested_float(x) for x in v]
    return float(v)


def _map_nested(v, f):
    if isinstance(v, list):
        return [_map_nested(x, f) for x in v]
    return f(v)


def _matrix_to_json(M, name, fmt):
    if name in VECTOR_NAMES:
        return [fmt(M[i, 0]) for i in range(M.rows)]
    return [[fmt(M[i, j]) for j in range(M.cols)] for i in range(M.rows)]


def _default_omega_exact(b, c, s):
    return sympy.Matrix(max(s - 1, 0), s, lambda i, j: b[j] * c[j] ** i)


def _col(vals):
    return sympy.Matrix(len(vals), 1, list(vals))


# --- exact construction ------------------------------------------------------------------
# Exact coefficients are computed in the algebraic number field Q(c_1, ..., c_s) with sympy's
# DomainMatrix: exact, fast, and its results convert back to radicals.
def _exact_roots(poly_expr, x):
    """Real roots of a polynomial, as radicals where sympy finds them, else CRootOf; sorted."""
    P = sympy.Poly(sympy.expand(poly_expr), x)
    rts = sympy.roots(P)
    if sum(rts.values()) != P.degree() or any(r.has(sympy.I) for r in rts):
        # casus irreducibilis (Gauss s = 6, Lobatto s = 8, ...): the real nodes have no real
        # radical form, and the algebraic field of their CRootOf forms is too large to be useful
        raise TableauError(f"exact nodes need real radicals, which the degree-{P.degree()} node polynomial "
                           "does not have (exact families go up to Gauss s = 5, Lobatto s = 7); "
                           "use exact=False: coefficients at any precision")
    return sorted(rts, key=lambda r: float(sympy.N(r, 30)))


class _Field:
    def __init__(self, numbers):
        gens = [r for r in numbers if not r.is_rational]
        self.K = QQ.algebraic_field(*gens) if gens else QQ

    def __call__(self, e):
        return self.K.from_sympy(sympy.sympify(e))

    def solve(self, rows, rhs):
        n = len(rows)
        M = DomainMatrix(rows, (n, len(rows[0])), self.K)
        r = DomainMatrix([[v] for v in rhs], (n, 1), self.K)
        sol = M.lu_solve(r).to_list()
        return [row[0] for row in sol]

    def to_sympy(self, rows):
        return sympy.Matrix([[self.K.to_sympy(v) for v in row] for row in rows])


def _exact_weights(F, c):
    s = len(c)
    return F.solve([[cj ** k for cj in c] for k in range(s)], [F(sympy.Rational(1, k + 1)) for k in range(s)])


def _exact_collocation(F, c, nconds, fixed=None):
    """Rows of A from C(nconds): sum_j a_ij c_j^(k-1) = c_i^k / k, k = 1..nconds, with
    ``fixed`` = (column, value) prescribing one column (IIIC: a_i1 = b_1; IIIC*: a_is = 0)."""
    s = len(c)
    A = [[F(0)] * s for _ in range(s)]
    free = list(range(s))
    if fixed is not None:
        free.remove(fixed[0])
    V = [[c[j] ** k for j in free] for k in range(nconds)]
    for i in range(s):
        rhs = [c[i] ** (k + 1) * F(sympy.Rational(1, k + 1)) for k in range(nconds)]
        if fixed is not None:
            rhs = [rhs[k] - fixed[1] * c[fixed[0]] ** k for k in range(nconds)]
            A[i][fixed[0]] = fixed[1]
        for jj, v in zip(free, F.solve(V, rhs)):
            A[i][jj] = v
    return A


def _exact_iiib(F, c, b):
    """IIIB from D(s): sum_i b_i c_i^(k-1) a_ij = b_j (1 - c_j^k) / k, k = 1..s."""
    s = len(c)
    W = [[b[i] * c[i] ** k for i in range(s)] for k in range(s)]
    A = [[None] * s for _ in range(s)]
    for j in range(s):
        col = F.solve(W, [b[j] * (F(1) - c[j] ** (k + 1)) * F(sympy.Rational(1, k + 1)) for k in range(s)])
        for i in range(s):
            A[i][j] = col[i]
    return A


# --- numeric construction at any precision ---------------------------------------------
def _gauss_nodes_mp(s):
    x, _ = mpmath.mp.gauss_quadrature(s, "legendre")
    f = lambda t: mpmath.legendre(s, t)
    nodes = [mpmath.findroot(f, xi) for xi in x]
    return sorted((1 + xi) / 2 for xi in nodes)


def _lobatto_nodes_mp(s):
    if s < 2:
        raise TableauError("Lobatto methods need s >= 2")
    interior = []
    if s > 2:
        x, _ = mpmath.mp.gauss_quadrature(s - 2, "jacobi", 1, 1)
        n = s - 1
        # P'_n(x) = n (x P_n(x) - P_{n-1}(x)) / (x^2 - 1)
        f = lambda t: t * mpmath.legendre(n, t) - mpmath.legendre(n - 1, t)
        interior = [mpmath.findroot(f, xi) for xi in x]
    return [mpmath.mpf(0)] + sorted((1 + xi) / 2 for xi in interior) + [mpmath.mpf(1)]


def _mp_solve(M, rhs):
    return list(mpmath.lu_solve(mpmath.matrix(M), mpmath.matrix(rhs)))


def _mp_weights(c):
    s = len(c)
    return _mp_solve([[cj ** k for cj in c] for k in range(s)],
                     [mpmath.mpf(1) / (k + 1) for k in range(s)])


def _mp_collocation(c, nconds, fixed=None):
    s = len(c)
    A = [[mpmath.mpf(0)] * s for _ in range(s)]
    free = list(range(s))
    if fixed is not None:
        free.remove(fixed[0])
    V = [[c[j] ** k for j in free] for k in range(nconds)]
    for i in range(s):
        rhs = [c[i] ** (k + 1) / (k + 1) for k in range(nconds)]
        if fixed is not None:
            rhs = [rhs[k] - fixed[1] * c[fixed[0]] ** k for k in range(nconds)]
            A[i][fixed[0]] = fixed[1]
        sol = _mp_solve(V, rhs)
        for jj, j in enumerate(free):
            A[i][j] = sol[jj]
    return A


def _mp_iiib(c, b):
    s = len(c)
    W = [[b[i] * c[i] ** k for i in range(s)] for k in range(s)]
    A = [[None] * s for _ in range(s)]
    for j in range(s):
        col = _mp_solve(W, [b[j] * (1 - c[j] ** (k + 1)) / (k + 1) for k in range(s)])
        for i in range(s):
            A[i][j] = col[i]
    return A


def _assemble(c, A, A_hat, A_tilde, b, omega=None):
    s = len(c)
    if omega is None:
        omega = [[b[j] * c[j] ** i for j in range(s)] for i in range(s - 1)]
    return {"c": list(c), "A": A, "A_hat": A_hat, "A_tilde": A_tilde, "b": list(b),
            "b_hat": list(b), "b_tilde": list(b), "omega": omega}


def _mp_family(kind):
    def builder(dps, s):
        with mpmath.workdps(dps + guard_digits(s)):
            if kind == "gauss":
                c = _gauss_nodes_mp(s)
                b = _mp_weights(c)
                A = _mp_collocation(c, s)
                return _assemble(c, A, A, A, b)
            c = _lobatto_nodes_mp(s)
            b = _mp_weights(c)
            A = _mp_collocation(c, s)
            B = _mp_iiib(c, b)
            if kind == "lobatto-iiia-iiib":
                return _assemble(c, A, B, B, b)
            C = _mp_collocation(c, s - 1, fixed=(0, b[0]))
            Cs = _mp_collocation(c, s - 1, fixed=(s - 1, mpmath.mpf(0)))
            D = [[(C[i][j] + Cs[i][j]) / 2 for j in range(s)] for i in range(s)]
            return _assemble(c, A, B, D, b)
    return builder


def lobatto_coefficients(s: int) -> dict:
    """Exact Lobatto coefficients for s stages: c, b and the matrices IIIA (C(s)), IIIB (D(s)),
    IIIC (a_i1 = b_1, C(s-1)), IIIC* (a_is = 0, C(s-1)) and IIID = (IIIC + IIIC*)/2, as sympy
    Matrices."""
    if s < 2:
        raise TableauError(f"Lobatto coefficients need s >= 2, got {s}")
    F, c, b = _exact_nodes_weights("lobatto", s)
    C = _exact_collocation(F, c, s - 1, fixed=(0, b[0]))
    Cs = _exact_collocation(F, c, s - 1, fixed=(s - 1, F(0)))
    half = F(sympy.Rational(1, 2))
    D = [[(C[i][j] + Cs[i][j]) * half for j in range(s)] for i in range(s)]
    return {"c": F.to_sympy([[e] for e in c]), "b": F.to_sympy([[e] for e in b]),
            "IIIA": F.to_sympy(_exact_collocation(F, c, s)), "IIIB": F.to_sympy(_exact_iiib(F, c, b)),
            "IIIC": F.to_sympy(C), "IIIC_star": F.to_sympy(Cs), "IIID": F.to_sympy(D)}


def _exact_nodes_weights(kind, s):
    x = sympy.Symbol("x")
    if kind == "gauss":
        nodes = _exact_roots(sympy.legendre(s, 2 * x - 1), x)
    else:
        inner = _exact_roots(sympy.diff(sympy.legendre(s - 1, 2 * x - 1), x), x) if s > 2 else []
        nodes = [sympy.Integer(0)] + inner + [sympy.Integer(1)]
    F = _Field(nodes)
    c = [F(r) for r in nodes]
    return F, c, _exact_weights(F, c)


def _exact_family(kind, s):
    F, c, b = _exact_nodes_weights(kind, s)
    A = _exact_collocation(F, c, s)
    if kind == "gauss":
        Ah = At = A
    else:
        Ah = _exact_iiib(F, c, b)
        if kind == "lobatto-iiia-iiib":
            At = Ah
        else:
            C = _exact_collocation(F, c, s - 1, fixed=(0, b[0]))
            Cs = _exact_collocation(F, c, s - 1, fixed=(s - 1, F(0)))
            half = F(sympy.Rational(1, 2))
            At = [[(C[i][j] + Cs[i][j]) * half for j in range(s)] for i in range(s)]
    omega = [[b[j] * c[j] ** i for j in range(s)] for i in range(s - 1)]
    col = lambda v: F.to_sympy([[e] for e in v])
    return {"c": col(c), "A": F.to_sympy(A), "A_hat": F.to_sympy(Ah), "A_tilde": F.to_sympy(At),
            "b": col(b), "b_hat": col(b), "b_tilde": col(b),
            "omega": F.to_sympy(omega) if s > 1 else sympy.zeros(0, 1)}


def _family(kind, s, exact, order, label):
    if s < (1 if kind == "gauss" else 2):
        raise TableauError(f"{kind} needs s >= {1 if kind == 'gauss' else 2}, got s = {s}")
    if exact:
        return SparkTableau(label, s, exact=_exact_family(kind, s), claimed_order=order, family=kind)
    b = _mp_family(kind)
    return SparkTableau(label, s, builder=lambda dps, b=b: b(dps, s), claimed_order=order,
                        family=kind)


def gauss(s: int, exact: bool = False) -> SparkTableau:
    """s-stage Gauss SPARK (SRK-DAE2) method [27]: A = A_hat = A_tilde Gauss, order 2s."""
    return _family("gauss", s, exact, 2 * s, f"gauss-{s}")


def lobatto_iiia_iiib(s: int, exact: bool = False) -> SparkTableau:
    """s-stage Lobatto IIIA-B SPARK method [26]: A = IIIA, A_hat = A_tilde = IIIB, order 2s-2."""
    return _family("lobatto-iiia-iiib", s, exact, 2 * s - 2, f"lobatto-iiia-iiib-{s}")


def lobatto_iiia_iiib_iiid(s: int, exact: bool = False) -> SparkTableau:
    """s-stage Lobatto IIIA-B-D SPARK method: A = IIIA, A_hat = IIIB, A_tilde = IIID."""
    return _family("lobatto-iiia-iiib-iiid", s, exact, 2 * s - 2, f"lobatto-iiia-iiib-iiid-{s}")


def _one_stage(name, c, a, ah):
    one = sympy.Integer(1)
    ex = {"c": sympy.Matrix([[c]]), "A": sympy.Matrix([[a]]), "A_hat": sympy.Matrix([[ah]]),
          "A_tilde": sympy.Matrix([[ah]]), "b": sympy.Matrix([[one]]),
          "b_hat": sympy.Matrix([[one]]), "b_tilde": sympy.Matrix([[one]]),
          "omega": sympy.zeros(0, 1)}
    return SparkTableau(name, 1, exact=ex, claimed_order=1, family=name)


def euler_i(exact: bool = True) -> SparkTableau:
    """"Symplectic" Euler SPARK method I (7.1): c = 0, A = 0, A_hat = A_tilde = 1."""
    return _one_stage("euler-i", 0, 0, 1)


def euler_ii(exact: bool = True) -> SparkTableau:
    """"Symplectic" Euler SPARK method II (7.2): c = 1, A = 1, A_hat = A_tilde = 0."""
    return _one_stage("euler-ii", 1, 1, 0)


# --- method names ----------------------------------------------------------------------
def get_method(name: str, exact: bool = False) -> SparkTableau:
    """Tableau for a built-in method name (``gauss-S``, ``lobatto-iiia-iiib-S``,
    ``lobatto-iiia-iiib-iiid-S``, ``euler-i``, ``euler-ii``)."""
    if name == "euler-i":
        return euler_i()
    if name == "euler-ii":
        return euler_ii()
    for prefix, fn in (("lobatto-iiia-iiib-iiid-", lobatto_iiia_iiib_iiid),
                       ("lobatto-iiia-iiib-", lobatto_iiia_iiib), ("gauss-", gauss)):
        if name.startswith(prefix):
            tail = name[len(prefix):]
            if not tail.isdigit():
                break
            return fn(int(tail), exact=exact)
    raise TableauError(f"unknown method {name!r}; expected gauss-S, lobatto-iiia-iiib-S, "
                       "lobatto-iiia-iiib-iiid-S, euler-i, euler-ii or custom")


def builtin_method_names(max_s: int = 4) -> list[str]:
    names = [f"gauss-{s}" for s in range(1, max_s + 1)]
    names += [f"lobatto-iiia-iiib-{s}" for s in range(2, max_s + 1)]
    names += [f"lobatto-iiia-iiib-iiid-{s}" for s in range(2, max_s + 1)]
    return names + ["euler-i", "euler-ii"]


# --- JSON input ---------------------------------------------------------------------------
_MAX_ENTRY_LEN = 200
_MAX_EXPONENT = 64
_FUNCTIONS = {"sqrt": sympy.sqrt, "Rational": sympy.Rational, "cos": sympy.cos, "sin": sympy.sin}
_CONSTANTS = {"pi": sympy.pi}


def parse_exact_string(x: str, where: str = "entry"):
    """An exact tableau entry such as "1/4 - sqrt(3)/6" as a sympy number.

    Parsed with Python's ``ast`` and built node by node (never evaluated as Python): numbers
    (decimals read as exact decimals), + - * /, ** with a literal integer exponent of at most 64,
    sqrt, Rational, sin, cos and pi. Anything else is a TableauError naming the entry."""
    import ast
    if len(x) > _MAX_ENTRY_LEN:
        raise TableauError(f"{where}: expression longer than {_MAX_ENTRY_LEN} characters")
    try:
        tree = ast.parse(x.strip(), mode="eval")
    except SyntaxError:
        raise TableauError(f"{where}: cannot parse {x!r}") from None
    src = x.strip()

    def bad(why):
        return TableauError(f"{where}: {x!r} is not a number ({why})")

    def build(node):
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise bad(f"literal {node.value!r}")
            text = ast.get_source_segment(src, node) or repr(node.value)
            if isinstance(node.value, int):
                return sympy.Integer(node.value)
            if not math.isfinite(node.value):
                raise bad("not finite")
            return sympy.Rational(text.replace("_", ""))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
            v = build(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.BinOp):
            if isinstance(node.op, ast.Pow):
                ex = node.right
                neg = isinstance(ex, ast.UnaryOp) and isinstance(ex.op, ast.USub)
                lit = ex.operand if neg else ex
                if not (isinstance(lit, ast.Constant) and type(lit.value) is int and lit.value <= _MAX_EXPONENT):
                    raise bad(f"'**' needs a literal integer exponent <= {_MAX_EXPONENT}")
                return build(node.left) ** (-lit.value if neg else lit.value)
            ops = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
                   ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b}
            f = ops.get(type(node.op))
            if f is None:
                raise bad(f"operator {type(node.op).__name__}")
            a, b = build(node.left), build(node.right)
            if f is ops[ast.Div] and b == 0:
                raise bad("division by zero")
            return f(a, b)
        if isinstance(node, ast.Name) and node.id in _CONSTANTS:
            return _CONSTANTS[node.id]
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _FUNCTIONS
                and not node.keywords and 1 <= len(node.args) <= 2):
            args = [build(a) for a in node.args]
            if node.func.id == "Rational":
                if not all(a.is_Integer for a in args) or (len(args) == 2 and args[1] == 0):
                    raise bad("Rational needs integer arguments and a nonzero denominator")
            elif len(args) != 1:
                raise bad(f"{node.func.id} takes one argument")
            return _FUNCTIONS[node.func.id](*args)
        name = getattr(node, "id", None) or getattr(getattr(node, "func", None), "id", None)
        raise bad(f"unknown name {name!r}" if name else f"unsupported syntax {type(node).__name__}")

    e = build(tree.body)
    if not getattr(e, "is_number", False):
        raise bad("not a number")
    return e


def _parse_entry(x, where):
    """An entry: int (exact), string (exact expression, decimals read as exact decimals) or
    float (approximate, 53 bits). Returns (sympy number, is_exact)."""
    if isinstance(x, bool) or x is None:
        raise TableauError(f"{where}: entry {x!r} is not a number")
    if isinstance(x, int):
        return sympy.Integer(x), True
    if isinstance(x, float):
        if not math.isfinite(x):
            raise TableauError(f"{where}: entry {x!r} is not finite")
        return sympy.Float(x, 17), False
    if isinstance(x, str):
        e = parse_exact_string(x, where)
        val = complex(sympy.N(e, 30))
        if not (math.isfinite(val.real) and abs(val.imag) <= 1e-25 * (1 + abs(val.real))):
            raise TableauError(f"{where}: {x!r} is not a finite real number")
        return e, True
    raise TableauError(f"{where}: entry {x!r} is not a number")


def from_json_dict(d: dict, name: str | None = None) -> SparkTableau:
    """Tableau from the JSON format (keys c, A, A_hat, A_tilde, b, b_hat, b_tilde, optional
    omega and name). Exact when every entry is an int or string, else float precision."""
    if not isinstance(d, dict):
        raise TableauError("tableau JSON must be an object with keys c, A, A_hat, A_tilde, b, b_hat, b_tilde")
    missing = [k for k in NAMES if k != "omega" and k not in d]
    if missing:
        raise TableauError(f"tableau is missing key(s): {', '.join(missing)}")
    c = d["c"]
    if not isinstance(c, list) or not c:
        raise TableauError("c must be a non-empty list")
    s = len(c)
    all_exact = True
    ex = {}
    for k in NAMES:
        if k not in d:
            continue
        val = d[k]
        if k in VECTOR_NAMES:
            if not isinstance(val, list) or len(val) != s or any(isinstance(v, list) for v in val):
                raise TableauError(f"{k} must be a list of {s} numbers")
            ent = [_parse_entry(v, f"{k}[{i}]") for i, v in enumerate(val)]
            ex[k] = _col([e for e, _ in ent])
        else:
            rows = s - 1 if k == "omega" else s
            if (not isinstance(val, list) or len(val) != rows
                    or any(not isinstance(r, list) or len(r) != s for r in val)):
                raise TableauError(f"{k} must be a {rows} x {s} list of lists")
            ent = [[_parse_entry(v, f"{k}[{i}][{j}]") for j, v in enumerate(r)] for i, r in enumerate(val)]
            ex[k] = sympy.Matrix(rows, s, [e for r in ent for e, _ in r]) if rows else sympy.zeros(0, s)
            ent = [e for r in ent for e in r]
        all_exact = all_exact and all(flag for _, flag in ent)
    if "omega" not in ex:
        ex["omega"] = _default_omega_exact([ex["b"][j] for j in range(s)], [ex["c"][j] for j in range(s)], s)
    if s > 1:
        om = ex["omega"].evalf(30)
        if om.rank(iszerofunc=lambda e: abs(e) < 1e-20) < s - 1:
            raise TableauError("omega is singular (rank < s-1): (21e) would not determine the multipliers")
    label = name or d.get("name") or "custom"
    if all_exact:
        return SparkTableau(str(label), s, exact=ex, family="custom")
    return SparkTableau(str(label), s, exact=ex, source_digits=15, family="custom")


def load_tableau(path) -> SparkTableau:
    """Read a tableau JSON file; errors name the problem (TableauError)."""
    try:
        with open(path) as f:
            d = json.load(f)
    except FileNotFoundError:
        raise TableauError(f"tableau file {path} not found") from None
    except json.JSONDecodeError as exc:
        raise TableauError(f"tableau file {path} is not valid JSON: {exc.msg} at line {exc.lineno}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TableauError(f"cannot read tableau file {path}: {exc}") from None
    return from_json_dict(d)
