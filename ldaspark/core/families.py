"""The built-in tableau families and the method registry (section 7 and [26, 27]).

* ``gauss(s)``: A = A_hat = A_tilde = Gauss collocation, order 2s.
* ``lobatto_iiia_iiib(s)``: A = IIIA, A_hat = A_tilde = IIIB, order 2s-2.
* ``lobatto_iiia_iiib_iiid(s)``: A = IIIA, A_hat = IIIB, A_tilde = IIID = (IIIC + IIIC*)/2.
* ``euler_i()``, ``euler_ii()``: the "symplectic" Euler SPARK methods of 7.1-7.2, order 1.
* ``get_method(name)``: the registry of names ``gauss-S``, ``lobatto-iiia-iiib-S``, ...

Each coefficient matrix is built from its own defining conditions (IIIA from C(s), IIIB from
D(s), IIIC from a_i1 = b_1 and C(s-1), IIIC* from a_is = 0 and C(s-1)), never from (22b), so
that checking (22b) on them is a real test.
"""
from __future__ import annotations

import mpmath
import numpy as np
import sympy
from sympy import QQ
from sympy.polys.matrices import DomainMatrix
from sympy.polys.numberfields.subfield import primitive_element

from .errors import TableauError
from .tableau import SparkTableau, guard_digits
from .tableau_file import check_stages

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
    """Q(numbers) with the numbers themselves as known elements.

    The field is built from a primitive element of half the nodes (the symmetric families' nodes
    come in pairs c, 1 - c), and each node is mapped by the representation the primitive-element
    search returns: sympy's generic ``from_sympy`` would redo a field isomorphism per node
    (Gauss s = 4: 3.6 s against 0.2 s)."""

    def __init__(self, numbers):
        irr = [sympy.sympify(r) for r in numbers if not sympy.sympify(r).is_rational]
        self.known = {}
        if not irr:
            self.K = QQ
            return
        half = [r for r in irr if sympy.N(r, 30) < sympy.Rational(1, 2)]
        paired = {sympy.nsimplify(1 - r) for r in half} | set(half)
        gens = half + [r for r in irr if r not in paired and sympy.simplify(1 - r) not in half]
        x = sympy.Dummy("x")
        f, coeffs, reps = primitive_element(gens, x, ex=True)
        theta = sum(c * g for c, g in zip(coeffs, gens))
        self.K = QQ.algebraic_field((sympy.Poly(f, x), theta))
        for g, rep in zip(gens, reps):
            el = self.K([QQ(c) for c in rep])
            self.known[g] = el
            self.known[sympy.expand(1 - g)] = self.K.one - el

    def __call__(self, e):
        e = sympy.sympify(e)
        hit = self.known.get(e)
        if hit is None:
            hit = self.known.get(sympy.expand(e))
        return hit if hit is not None else self.K.from_sympy(e)

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


_MP_BUILT: dict = {}
#: tables kept by ``_mp_family`` (oldest dropped first): a job uses a few (family, s, dps)
_MP_BUILT_MAX = 64


def _mp_family(kind):
    def builder(dps, s):
        """The entries at ``dps`` digits, computed once per process: every ``get_method`` makes a
        new tableau, and rebuilding the nodes and collocation solves was 7% of a convergence
        job. Callers copy before changing an entry (``SparkTableau.mp_entries`` rounds into new
        lists, ``with_entry`` copies the rows)."""
        key = (kind, int(s), int(dps))
        hit = _MP_BUILT.get(key)
        if hit is None:
            hit = _build(dps, s)
            # bounded: a sweep over dps or s would otherwise keep every table for the process's life
            while len(_MP_BUILT) >= _MP_BUILT_MAX:
                _MP_BUILT.pop(next(iter(_MP_BUILT)))
            _MP_BUILT[key] = hit
        return hit

    def _build(dps, s):
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
    _check_s(s, None, "lobatto_coefficients")      # an integer ("3" was a TypeError, 2.5 a sympy error)
    s = int(s)
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
    if isinstance(s, bool) or not isinstance(s, (int, np.integer)):
        raise TableauError(f"{kind}: the number of stages s must be an integer, got {s!r}")
    s = int(s)
    if s < (1 if kind == "gauss" else 2):
        raise TableauError(f"{kind} needs s >= {1 if kind == 'gauss' else 2}, got s = {s}")
    if exact:
        return SparkTableau(label, s, exact=_exact_family(kind, s), claimed_order=order, family=kind)
    return SparkTableau(label, s, builder=_FamilyBuilder(kind, s), claimed_order=order, family=kind)


class _FamilyBuilder:
    """The mpmath builder of a family's s-stage tableau: a module-level callable (not a lambda),
    so that a tableau pickles into the worker processes of an ensemble or a cluster."""

    def __init__(self, kind, s):
        self.kind, self.s = kind, s

    def __call__(self, dps):
        return _mp_family(self.kind)(dps, self.s)


# s <= MAX_STAGES (20) unless max_stages raises it: the mpmath builders cost grows steeply with s
# (gauss-100 does not finish in minutes)
def gauss(s: int, exact: bool = False, max_stages: int | None = None) -> SparkTableau:
    """s-stage Gauss SPARK (SRK-DAE2) method: A = A_hat = A_tilde Gauss, order 2s.

    All three matrices A, A_hat, A_tilde of (21) are the Gauss-Legendre collocation matrix; b = b_hat =
    b_tilde and omega as in section 6. The method is symmetric (23) and of order 2s.

    Parameters
    ----------
    s : int
        Number of stages, 1 <= s <= ``max_stages``.
    exact : bool, optional
        True: the entries as exact sympy numbers (in one algebraic number field, so that (22)
        and (23) are decided exactly); False (default): computed to any requested precision.
    max_stages : int, optional
        Stage limit (default 20): the mpmath builders' cost grows steeply with s.

    Returns
    -------
    SparkTableau
        The coefficients of (21), ``claimed_order`` = 2s.

    Raises
    ------
    TableauError
        When s is not an integer in range.

    Examples
    --------
    >>> import ldaspark
    >>> t = ldaspark.gauss(2)
    >>> t.name, t.s, t.claimed_order
    ('gauss-2', 2, 4)
    """
    _check_s(s, max_stages, "gauss")
    return _family("gauss", s, exact, 2 * s, f"gauss-{s}")


def lobatto_iiia_iiib(s: int, exact: bool = False, max_stages: int | None = None) -> SparkTableau:
    """s-stage Lobatto IIIA-B SPARK method: A = IIIA, A_hat = A_tilde = IIIB, order 2s-2.

    A is the Lobatto IIIA matrix and A_hat = A_tilde the Lobatto IIIB matrix; order 2s-2, symmetric (23).

    Parameters
    ----------
    s : int
        Number of stages, 1 <= s <= ``max_stages`` (s >= 2).
    exact : bool, optional
        True: the entries as exact sympy numbers (in one algebraic number field, so that (22)
        and (23) are decided exactly); False (default): computed to any requested precision.
    max_stages : int, optional
        Stage limit (default 20): the mpmath builders' cost grows steeply with s.

    Returns
    -------
    SparkTableau
        The coefficients of (21), ``claimed_order`` = 2s-2.

    Raises
    ------
    TableauError
        When s is not an integer in range.

    Examples
    --------
    >>> import ldaspark
    >>> t = ldaspark.lobatto_iiia_iiib(3)
    >>> t.name, t.s, t.claimed_order
    ('lobatto-iiia-iiib-3', 3, 4)
    """
    _check_s(s, max_stages, "lobatto-iiia-iiib")
    return _family("lobatto-iiia-iiib", s, exact, 2 * s - 2, f"lobatto-iiia-iiib-{s}")


def lobatto_iiia_iiib_iiid(s: int, exact: bool = False, max_stages: int | None = None) -> SparkTableau:
    """s-stage Lobatto IIIA-B-D SPARK method: A = IIIA, A_hat = IIIB, A_tilde = IIID.

    A is the Lobatto IIIA matrix, A_hat the Lobatto IIIB matrix and A_tilde the Lobatto IIID
    matrix; order 2s-2.

    Parameters
    ----------
    s : int
        Number of stages, 1 <= s <= ``max_stages`` (s >= 2).
    exact : bool, optional
        True: the entries as exact sympy numbers (in one algebraic number field, so that (22)
        and (23) are decided exactly); False (default): computed to any requested precision.
    max_stages : int, optional
        Stage limit (default 20): the mpmath builders' cost grows steeply with s.

    Returns
    -------
    SparkTableau
        The coefficients of (21), ``claimed_order`` = 2s-2.

    Raises
    ------
    TableauError
        When s is not an integer in range.

    Examples
    --------
    >>> import ldaspark
    >>> t = ldaspark.lobatto_iiia_iiib_iiid(2)
    >>> t.name, t.s, t.claimed_order
    ('lobatto-iiia-iiib-iiid-2', 2, 2)
    """
    _check_s(s, max_stages, "lobatto-iiia-iiib-iiid")
    return _family("lobatto-iiia-iiib-iiid", s, exact, 2 * s - 2, f"lobatto-iiia-iiib-iiid-{s}")


def _check_s(s, max_stages, kind):
    if isinstance(s, bool) or not isinstance(s, (int, np.integer)):
        raise TableauError(f"{kind}: the number of stages s must be an integer, got {s!r}")
    check_stages(int(s), max_stages, what=kind)


def _one_stage(name, c, a, ah):
    one = sympy.Integer(1)
    ex = {"c": sympy.Matrix([[c]]), "A": sympy.Matrix([[a]]), "A_hat": sympy.Matrix([[ah]]),
          "A_tilde": sympy.Matrix([[ah]]), "b": sympy.Matrix([[one]]),
          "b_hat": sympy.Matrix([[one]]), "b_tilde": sympy.Matrix([[one]]),
          "omega": sympy.zeros(0, 1)}
    return SparkTableau(name, 1, exact=ex, claimed_order=1, family=name)


def euler_i(exact: bool = True) -> SparkTableau:
    """The "symplectic" Euler SPARK method I (7.1): c = 0, A = 0, A_hat = A_tilde = 1.

    The one-stage SPARK method (7.1) of section 7: c = 0, A = 0, A_hat = A_tilde = 1; order 1.

    Parameters
    ----------
    exact : bool, optional
        Kept for a uniform interface with the families: the entries are always exact.

    Returns
    -------
    SparkTableau
        The one-stage tableau, ``claimed_order`` = 1.

    Examples
    --------
    >>> import ldaspark
    >>> t = ldaspark.euler_i()
    >>> t.name, t.s, t.claimed_order
    ('euler-i', 1, 1)
    """
    return _one_stage("euler-i", 0, 0, 1)


def euler_ii(exact: bool = True) -> SparkTableau:
    """The "symplectic" Euler SPARK method II (7.2): c = 1, A = 1, A_hat = A_tilde = 0.

    The one-stage SPARK method (7.2) of section 7: c = 1, A = 1, A_hat = A_tilde = 0; order 1.

    Parameters
    ----------
    exact : bool, optional
        Kept for a uniform interface with the families: the entries are always exact.

    Returns
    -------
    SparkTableau
        The one-stage tableau, ``claimed_order`` = 1.

    Examples
    --------
    >>> import ldaspark
    >>> t = ldaspark.euler_ii()
    >>> t.name, t.s, t.claimed_order
    ('euler-ii', 1, 1)
    """
    return _one_stage("euler-ii", 1, 1, 0)


# --- method names ----------------------------------------------------------------------
def get_method(name: str, exact: bool = False, max_stages: int | None = None) -> SparkTableau:
    """Tableau for a built-in method name.

    Parameters
    ----------
    name : str
        ``gauss-S``, ``lobatto-iiia-iiib-S``, ``lobatto-iiia-iiib-iiid-S``, ``euler-i`` or
        ``euler-ii``, with S the number of stages in ASCII digits.
    exact : bool, optional
        Exact sympy entries (see `gauss`).
    max_stages : int, optional
        Upper bound of S (default 20).

    Returns
    -------
    SparkTableau
        The tableau of the named family.

    Raises
    ------
    TableauError
        For an unknown name or S beyond the stage limit.

    Examples
    --------
    >>> import ldaspark
    >>> ldaspark.get_method("gauss-3").claimed_order
    6
    """
    if not isinstance(name, str):
        raise TableauError(f"method name must be a string such as 'gauss-2', got {type(name).__name__}")
    if not isinstance(exact, (bool, np.bool_)):     # 'yes' or 'no' would both be truthy
        raise TableauError(f"exact must be True or False, got {type(exact).__name__} {str(exact)[:40]!r}")
    exact = bool(exact)
    if name == "euler-i":
        return euler_i()
    if name == "euler-ii":
        return euler_ii()
    for prefix, fn in (("lobatto-iiia-iiib-iiid-", lobatto_iiia_iiib_iiid),
                       ("lobatto-iiia-iiib-", lobatto_iiia_iiib), ("gauss-", gauss)):
        if name.startswith(prefix):
            tail = name[len(prefix):]
            # ASCII digits only: str.isdigit accepts '²' and other digits int() refuses
            if not (tail.isascii() and tail.isdigit()) or len(tail) > 6:
                if tail.isascii() and tail.isdigit():
                    raise TableauError(f"{name}: s has {len(tail)} digits, beyond the stage limit "
                                       "(raise it with --max-stages / max_stages=)")
                break
            if len(tail) > 1 and tail[0] == "0":
                # one spelling per method, the one its tableau carries (``gauss-irk-02`` is refused
                # too): "gauss-02" would run as "gauss-2" under another name in results and reports
                raise TableauError(f"unknown method {name!r}: write S without leading zeros "
                                   f"({prefix}{int(tail)})")
            return fn(int(tail), exact=exact, max_stages=max_stages)
    raise TableauError(f"unknown method {name!r}; expected gauss-S, lobatto-iiia-iiib-S, "
                       "lobatto-iiia-iiib-iiid-S, euler-i, euler-ii or custom")


def builtin_method_names(max_s: int = 4) -> list[str]:
    names = [f"gauss-{s}" for s in range(1, max_s + 1)]
    names += [f"lobatto-iiia-iiib-{s}" for s in range(2, max_s + 1)]
    names += [f"lobatto-iiia-iiib-iiid-{s}" for s in range(2, max_s + 1)]
    return names + ["euler-i", "euler-ii"]
