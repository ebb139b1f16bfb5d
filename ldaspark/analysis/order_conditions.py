"""Classical order conditions of the coefficient matrices of a SPARK method (21).

* Rooted trees (one colour) and bi-coloured trees (two colours: the pair (A, A_hat) acting on
  q' = v and p' = F) are generated programmatically up to order 8, with their density gamma(t).
* The elementary weight Phi(t) of an RK method (A, b), or of a partitioned pair
  ((A, b), (A_hat, b_hat)), is evaluated recursively; the order condition is
  Phi(t) = 1 / gamma(t) (Butcher; Hairer-Norsett-Wanner II.2, III.2 for the pair).
* Simplifying assumptions B(p), C(q), D(r), and the stability function
  R(z) = 1 + z b^T (I - z A)^{-1} 1 = det(I - z(A - 1 b^T)) / det(I - z A) with R(inf).

All of it runs on one small arithmetic interface (``Arith``) so the same code gives exact
answers in an algebraic number field (``SparkTableau.field_entries()``: == is decidable),
answers at the precision the entries carry in ball arithmetic (arb, ``ball_arith``: a condition
holds when its ball contains 0, is violated when it excludes 0), and tolerance-based answers
with mpmath (``mp_arith``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import mpmath

MAX_ORDER = 8


# --- trees ---------------------------------------------------------------------------------
# A coloured rooted tree is (colour, children) with children a sorted tuple of trees, so that
# equal trees have equal representations. Plain rooted trees are the one-colour case.

@lru_cache(maxsize=None)
def trees(order: int, colours: int = 1) -> tuple:
    """All (coloured) rooted trees with ``order`` vertices, each once, in canonical form.

    Counts (checked in tests): 1, 1, 2, 4, 9, 20, 48, 115 for one colour; 2, 4, 14, 52, 214,
    916, 4116, 18996 for two colours (OEIS A000081, A038055)."""
    if order < 1:
        return ()
    out = []
    for forest in _forests(order - 1, colours):
        for col in range(colours):
            out.append((col, forest))
    return tuple(out)


@lru_cache(maxsize=None)
def _forests(total: int, colours: int) -> tuple:
    """Multisets of trees with ``total`` vertices in all, as sorted tuples."""
    if total == 0:
        return ((),)
    pool = [t for n in range(1, total + 1) for t in trees(n, colours)]
    sizes = {t: tree_order(t) for t in pool}
    res = []

    def rec(remaining, max_idx, acc):
        if remaining == 0:
            res.append(tuple(sorted(acc)))
            return
        for i in range(max_idx, -1, -1):
            t = pool[i]
            if sizes[t] <= remaining:
                acc.append(t)
                rec(remaining - sizes[t], i, acc)
                acc.pop()

    rec(total, len(pool) - 1, [])
    return tuple(res)


@lru_cache(maxsize=None)
def tree_order(t) -> int:
    return 1 + sum(tree_order(u) for u in t[1])


@lru_cache(maxsize=None)
def density(t) -> int:
    """gamma(t) = |t| * prod gamma(children); the order condition is Phi(t) = 1/gamma(t)."""
    g = tree_order(t)
    for u in t[1]:
        g *= density(u)
    return g


def tree_str(t, names=("", "")) -> str:
    """Bracket notation: a leaf is 'o' (or the colour name), [u v] a root with children u, v."""
    col, ch = t
    root = names[col] if names[col] else "o"
    if not ch:
        return root
    return root + "[" + " ".join(tree_str(u, names) for u in ch) + "]"


# --- arithmetic ----------------------------------------------------------------------------
class ExactBudgetExceeded(Exception):
    """An exact decision ran past its time budget (``Arith.deadline``): decide numerically."""


@dataclass
class Arith:
    """Numbers of one kind: exact elements of an algebraic number field K, arb balls, or mpf.

    ``tol`` is the absolute tolerance for zero tests in the mp case (None otherwise). In the ball
    case (``kind == "ball"``, ``dps`` working digits) a number is zero when its ball contains 0:
    the ball encloses every value the entries may stand for, so a condition is "violated" only
    when no such value satisfies it. ``deadline`` (time.monotonic()) bounds an exact decision:
    past it ``is_zero`` raises ExactBudgetExceeded."""

    kind: str                 # "exact", "ball" or "mp"
    K: object = None
    dps: int = 30
    tol: float | None = None
    deadline: float | None = None
    #: what decided (for the report): "exact in QQ<sqrt(3)>", "arb balls at 60 digits", ...
    label: str = ""
    #: to what a numerical "holds" refers: "the 40 digits given", "float64 precision", ...
    scope: str = ""
    _q: dict = field(default_factory=dict, repr=False)

    @property
    def exact(self) -> bool:
        return self.kind == "exact"

    @property
    def ball(self) -> bool:
        return self.kind == "ball"

    @property
    def prec(self) -> int:
        """Binary precision of the ball arithmetic (guard bits above dps digits)."""
        return int(self.dps * 3.33) + 16

    def num(self, p: int, q: int = 1):
        """The rational number p/q in this arithmetic."""
        key = (p, q)
        if key not in self._q:
            if self.exact:
                from sympy import Rational
                self._q[key] = self.K.from_sympy(Rational(p, q))
            elif self.ball:
                import flint
                with flint.ctx.workprec(self.prec):
                    self._q[key] = flint.arb(flint.fmpq(p, q))
            else:
                with mpmath.workdps(self.dps):
                    self._q[key] = mpmath.mpf(p) / q
        return self._q[key]

    def is_zero(self, x) -> bool:
        if self.exact:
            if self.deadline is not None:
                import time
                if time.monotonic() > self.deadline:
                    raise ExactBudgetExceeded()
            return x == self.K.zero
        if self.ball:
            if not x.is_finite():    # a NaN ball "contains" 0: never let it pass as a zero
                from ..core.errors import NonFiniteError
                raise NonFiniteError("ball arithmetic produced a non-finite value: condition not decidable")
            return bool(x.contains(0))
        return abs(x) <= self.tol

    def pow(self, x, n: int):
        """x^n for an integer n >= 0 (arb's ** is NaN on a ball containing 0: repeated products)."""
        if not self.ball:
            return x ** n
        out = self.num(1)
        for _ in range(n):
            out = out * x
        return out

    def radius(self, x) -> float:
        """The uncertainty of x: the ball's radius (0 when exact, tol for mp)."""
        if self.ball:
            return float(x.rad())
        return 0.0 if self.exact else float(self.tol)

    def to_float(self, x) -> float:
        """The double nearest x. Exact values: a rational by Python's correctly rounded int / int
        (rounding first to 20 digits, then to a double, rounds twice: 1.00000000000000011103 gave
        1.0); an algebraic one through 40 digits (a double rounding needs x within 1e-40
        relative of a midpoint between two doubles)."""
        if self.exact:
            from sympy import N
            v = self.K.to_sympy(x)
            if v.is_Rational:
                return int(v.p) / int(v.q)
            return float(N(v, 40))
        if self.ball:
            return float(x.mid())
        return float(x)

    def to_str(self, x) -> str:
        if self.exact:
            from sympy import nsimplify, sstr
            e = self.K.to_sympy(x)
            try:
                e = nsimplify(e) if not e.is_rational else e
            except Exception:  # nsimplify gives up on some algebraic numbers
                pass
            return sstr(e)
        if self.ball:
            return mpmath.nstr(mpmath.mpf(x.mid().str(20, radius=False)), 17)
        return mpmath.nstr(x, 17)

    def context(self):
        import contextlib
        if self.ball:
            import flint
            return flint.ctx.workprec(self.prec)
        return mpmath.workdps(self.dps) if not self.exact else contextlib.nullcontext()


def exact_arith(tab) -> tuple[Arith, dict]:
    """Arithmetic and entries for an exact tableau (field elements; vectors flat)."""
    K, ent = tab.field_entries()
    if not K.is_Field:  # integer tableaux come back over ZZ; order conditions need 1/gamma
        F = K.get_field()
        conv = lambda v: [conv(x) for x in v] if isinstance(v, list) else F.convert_from(v, K)
        ent = {k: conv(v) for k, v in ent.items()}
        K = F
    return Arith("exact", K=K, label=f"exact in {K}"), ent


def mp_arith(tab, dps: int) -> tuple[Arith, dict]:
    """Arithmetic and mpf entries at ``dps`` digits. The zero tolerance follows the precision
    of the entries: 10^(3 - digits), digits = min(dps, source digits of the input)."""
    ent = tab.mp_entries(dps)
    s = tab.s
    ent = dict(ent)
    for k in ("c", "b", "b_hat", "b_tilde"):
        v = ent[k]
        ent[k] = [x[0] if isinstance(x, list) else x for x in v]
    digits = min(dps, tab.source_digits or dps)
    tol = 10.0 ** (3 - digits) * max(1, s)
    return Arith("mp", dps=dps, tol=tol), ent


def ball_arith(tab, dps: int, reason: str = "") -> tuple[Arith, dict]:
    """Ball arithmetic at ``dps`` working digits on balls enclosing what the entries stand for
    (``SparkTableau.ball_entries``: decimals to the digits given, float64 to half an ulp and the
    rounding of a float64 computation (``float_computation_ulps``), exact entries to the working
    precision). ``reason``: why no exact decision (for the label)."""
    ent = tab.ball_entries(dps)
    ent = {k: [list(r) if isinstance(r, list) else r for r in v] for k, v in ent.items()}
    kind, D, Dmin = tab.precision_kind(), tab.decimal_digits, tab.decimal_digits_min
    given = f"the {Dmin} to {D} digits given" if Dmin and Dmin < D else f"the {D} digits given"
    scope = {"decimal": given,
             "float": (f"the {D} digits given as JSON numbers" + (
                           f" (and the rounding of a float64 computation, {tab.float_computation_ulps():.3g} ulps)"
                           if tab.has_float64_values else "") if tab.json_numbers and D
                       # JSON numbers that are all zeros carry no digits: exact, as the other entries
                       else f"{dps} digits, numerically (exact entries, zeros written as JSON numbers)"
                       if tab.json_numbers else "the float64 precision of the entries (~16 digits, and the rounding "
                       f"of a float64 computation, {tab.float_computation_ulps():.3g} ulps)"),
             "decimal+float": f"{given} and float64 precision",
             "exact": f"{dps} digits, numerically (exact entries; no exact decision, see the arithmetic)",
             "computed": f"{dps} digits, numerically"}[kind]
    label = (f"arb ball arithmetic at {dps} digits; entries: {tab.precision_text()}"
             + (f"; not exact because {reason}" if kind == "exact" and reason else ""))
    return Arith("ball", dps=dps, label=label, scope=scope), ent


#: Exact decisions are attempted only in an algebraic number field of degree at most this bound
#: (the product of the root orders of the distinct radicals and CRootOfs in the entries, an upper
#: bound of the degree): sympy's primitive element for ten square roots (degree 1024) does not
#: finish in minutes, for three (degree 8) in under a second.
EXACT_MAX_DEGREE = 8
#: seconds an exact decision may take (all algebraic checks together) before it is abandoned for
#: the numerical decision; a safety net behind the static degree bound
EXACT_SECONDS = 20.0


def exact_budget(tab, max_degree: int | None = EXACT_MAX_DEGREE) -> tuple[bool, str]:
    """Whether an exact decision is possible and cheap for ``tab``: (ok, reason). Possible when the
    entries are exact (no float64) and algebraic (rationals, radicals, CRootOf: no sin, cos, pi,
    which sympy cannot decide in general); cheap when the degree bound of their number field is at
    most ``max_degree`` (None: no bound)."""
    import sympy
    if not tab.is_exact:
        return False, "the entries are float64 numbers"
    vals = [M[i, j] for M in tab.exact.values() for i in range(M.rows) for j in range(M.cols)]
    gens, trans = {}, set()
    for v in vals:
        v = sympy.sympify(v)
        for a in v.atoms(sympy.Pow):
            if a.exp.is_Rational and not a.exp.is_Integer:
                gens[(a.base, int(a.exp.q))] = int(a.exp.q)
        for a in v.atoms(sympy.CRootOf):
            gens[a] = int(sympy.degree(a.poly))
        trans |= {type(f).__name__ for f in v.atoms(sympy.Function) if not isinstance(f, sympy.CRootOf)}
        if v.has(sympy.pi):
            trans.add("pi")
        if v.has(sympy.E):
            trans.add("E")
    if trans:
        return False, (f"the entries involve {', '.join(sorted(trans))}: no algebraic number field "
                       "holds them, equality is not decidable exactly")
    deg = 1
    for q in gens.values():
        deg *= q
    if max_degree is not None and deg > max_degree:
        return False, (f"{len(gens)} distinct radicals: number field of degree up to {deg} > {max_degree}, "
                       "beyond the budget of an exact decision")
    return True, f"number field of degree <= {deg}"


def arith_for(tab, dps: int = 30) -> tuple[Arith, dict]:
    """The audit's automatic choice (without its time budget): exact arithmetic when the entries
    are known exactly and the exact decision is cheap (``exact_budget``), else ball arithmetic at
    the precision the entries carry (working digits max(2 dps, digits given + 20))."""
    ok, why = exact_budget(tab) if tab.known_exactly else (False, "")
    if ok:
        ar, e = exact_arith(tab)
        if _decidable(ar.K):
            return ar, e
        why = f"sympy puts the entries in {ar.K}, where equality is not decidable exactly"
    return ball_arith(tab, ball_digits(tab, dps), why)


def ball_digits(tab, dps: int) -> int:
    """Working digits of a numerical decision: twice the audit's dps (so that an exact zero shows
    as zero to many more digits than any coefficient of interest), and 20 guard digits above the
    digits given."""
    return max(2 * dps, (tab.decimal_digits or 0) + 20, 40)


def _decidable(K) -> bool:
    """== decides equality in K: the rationals or an algebraic number field (not sympy's EX or a
    polynomial ring over transcendental generators such as sin(1), where == is structural)."""
    return bool(K.is_QQ or K.is_ZZ or getattr(K, "is_AlgebraicField", False))


# --- linear algebra on lists --------------------------------------------------------------
def _matvec(ar, M, x):
    s = len(x)
    z = ar.num(0)
    out = []
    for i in range(s):
        acc = z
        row = M[i]
        for j in range(s):
            acc = acc + row[j] * x[j]
        out.append(acc)
    return out


def _dot(ar, u, v):
    acc = ar.num(0)
    for a, b in zip(u, v):
        acc = acc + a * b
    return acc


# --- order conditions ----------------------------------------------------------------------
@dataclass
class OrderResult:
    """Order of an RK method or partitioned pair from the tree conditions.

    ``order`` is the largest p <= max_order with every condition of order <= p satisfied;
    ``failing`` names the worst tree of order p+1 (None when order == max_order);
    ``counts`` the number of trees checked per order."""

    order: int
    max_order: int
    failing: str | None = None
    residual: float = 0.0
    counts: dict = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        return self.order >= self.max_order


def _order_from_trees(ar, mats, weights, colours, max_order, names):
    """Check Phi(t) = 1/gamma(t) for coloured trees order by order, stopping at the first
    order with a violated condition. mats[col] and weights[col] are the coefficients used
    for a vertex of that colour."""
    s = len(weights[0])
    stage = {}   # tree -> stage vector g(t): product over children u of (A^{col u} g(u))
    lifted = {}  # tree -> A^{col t} g(t)
    one = [ar.num(1)] * s
    counts = {}
    with ar.context():
        for p in range(1, max_order + 1):
            worst, worst_t = None, None
            ts = trees(p, colours)
            counts[p] = len(ts)
            for t in ts:
                col, ch = t
                g = one
                for u in ch:
                    hu = lifted[u]
                    g = [a * b for a, b in zip(g, hu)]
                stage[t] = g
                if p < max_order:
                    lifted[t] = _matvec(ar, mats[col], g)
                r = _dot(ar, weights[col], g) - ar.num(1, density(t))
                if not ar.is_zero(r):
                    mag = ar.to_float(r)
                    if worst is None or abs(mag) > abs(worst):
                        worst, worst_t = mag, t
            if worst_t is not None:
                return OrderResult(p - 1, max_order, tree_str(worst_t, names), abs(worst), counts)
    return OrderResult(max_order, max_order, None, 0.0, counts)


def rk_order(ar, A, b, max_order: int = MAX_ORDER) -> OrderResult:
    """Classical order of the RK method (A, b) from the rooted-tree conditions."""
    return _order_from_trees(ar, [A], [b], 1, max_order, ("", ""))


def pair_order(ar, A, b, A_hat, b_hat, max_order: int | None = None) -> OrderResult:
    """Order of the partitioned RK pair: (A, b) for q' = v, (A_hat, b_hat) for p' = F
    (bi-coloured trees: 'q' vertices use A, 'p' vertices use A_hat). When both tableaux are
    identical the pair conditions reduce to the one-colour ones (a P-series of one method),
    which we use then: it is the same set of equations and 40x fewer trees."""
    return additive_order(ar, [(A, b), (A_hat, b_hat)], max_order, ["q", "p"])


def _same(ar, A1, b1, A2, b2) -> bool:
    return all(ar.is_zero(x - y) for x, y in zip(b1, b2)) and all(
        ar.is_zero(x - y) for r1, r2 in zip(A1, A2) for x, y in zip(r1, r2))


def additive_order(ar, parts, max_order: int | None = None, names=None) -> OrderResult:
    """Order of an additive partitioned RK method with coefficient sets ``parts`` =
    [(A_1, b_1), ..., (A_k, b_k)] (one per vector-field part; N-trees with k colours).
    Parts with identical coefficients are merged into one colour first: the conditions of
    the merged system are exactly the conditions with fewer colours. ``max_order`` defaults
    to 8 for one or two colours and 6 for three (62625 three-coloured trees at order 7)."""
    uniq, labels = [], []
    names = names or [str(i) for i in range(len(parts))]
    for (A, b), nm in zip(parts, names):
        for k, (A2, b2) in enumerate(uniq):
            if _same(ar, A, b, A2, b2):
                labels[k] += "=" + nm
                break
        else:
            uniq.append((A, b))
            labels.append(nm)
    if max_order is None:
        max_order = MAX_ORDER if len(uniq) <= 2 else 6
    if len(uniq) == 1:
        return rk_order(ar, uniq[0][0], uniq[0][1], max_order)
    return _order_from_trees(ar, [A for A, _ in uniq], [b for _, b in uniq], len(uniq), max_order,
                             tuple(labels))


def spark_ode_order(ar, e, max_order: int | None = None) -> OrderResult:
    """Order of (A; A_hat, A_tilde) applied to the forced ODE (6) q' = v, p' = F + R with the
    multiplier treated as a given smooth function of t: 3-coloured trees ('q' vertices use
    (A, b), 'F' vertices (A_hat, b_hat), 'R' vertices (A_tilde, b_tilde)). Identical parts merge
    (Gauss: one colour, Lobatto IIIA-B: two); three colours are capped at order 6."""
    return additive_order(ar, [(e["A"], e["b"]), (e["A_hat"], e["b_hat"]), (e["A_tilde"], e["b_tilde"])],
                          max_order, ["q", "F", "R"])


# --- simplifying assumptions ---------------------------------------------------------------
def _worst(ar, residuals):
    bad = [(abs(ar.to_float(r)), where) for r, where in residuals if not ar.is_zero(r)]
    return max(bad) if bad else None


def check_B(ar, b, c, p):
    """B(p): sum_i b_i c_i^(k-1) = 1/k, k = 1..p. Returns (holds, worst (residual, where))."""
    with ar.context():
        res = []
        for k in range(1, p + 1):
            r = _dot(ar, b, [ar.pow(ci, k - 1) for ci in c]) - ar.num(1, k)
            res.append((r, f"k={k}"))
        w = _worst(ar, res)
    return w is None, w


def check_C(ar, A, c, q):
    """C(q): sum_j a_ij c_j^(k-1) = c_i^k / k, i = 1..s, k = 1..q."""
    with ar.context():
        res = []
        for k in range(1, q + 1):
            ck = [ar.pow(cj, k - 1) for cj in c]
            Ac = _matvec(ar, A, ck)
            for i, ci in enumerate(c):
                res.append((Ac[i] - ar.pow(ci, k) * ar.num(1, k), f"k={k}, i={i + 1}"))
        w = _worst(ar, res)
    return w is None, w


def check_D(ar, A, b, c, r):
    """D(r): sum_i b_i c_i^(k-1) a_ij = b_j (1 - c_j^k) / k, j = 1..s, k = 1..r."""
    s = len(b)
    with ar.context():
        res = []
        for k in range(1, r + 1):
            w = [b[i] * ar.pow(c[i], k - 1) for i in range(s)]
            for j in range(s):
                lhs = _dot(ar, w, [A[i][j] for i in range(s)])
                res.append((lhs - b[j] * (ar.num(1) - ar.pow(c[j], k)) * ar.num(1, k), f"k={k}, j={j + 1}"))
        wst = _worst(ar, res)
    return wst is None, wst


def largest(check, cap):
    """Largest n in 0..cap with check(n) true (the conditions are nested)."""
    n = 0
    while n < cap and check(n + 1)[0]:
        n += 1
    return n


def simplifying_assumptions(ar, A, b, c, cap: int | None = None) -> dict:
    """Largest p, q, r with B(p), C(q), D(r) (capped at 2s for B, s for C and D... plus one, so
    that a degenerate method exceeding the generic bound is still seen)."""
    s = len(b)
    capB = cap or 2 * s + 1
    capCD = cap or s + 1
    return {"B": largest(lambda p: check_B(ar, b, c, p), capB),
            "C": largest(lambda q: check_C(ar, A, c, q), capCD),
            "D": largest(lambda r: check_D(ar, A, b, c, r), capCD)}


# --- stability function ------------------------------------------------------------------
def char_coeffs(ar, M):
    """Coefficients d_0..d_s of det(I - z M) = sum_k d_k z^k (Faddeev-LeVerrier; exact in
    any field of characteristic 0)."""
    s = len(M)
    with ar.context():
        zero, one = ar.num(0), ar.num(1)
        # det(x I - M) = x^s + c_1 x^(s-1) + ... + c_s; det(I - z M) = sum_k c_k z^k
        Mk = [[zero] * s for _ in range(s)]   # M_0 = 0
        coeffs = [one]
        prev_c = one
        for k in range(1, s + 1):
            # M_k = M M_{k-1} + c_{k-1} I ; c_k = -tr(M M_k) / k
            MM = [[sum((M[i][l] * Mk[l][j] for l in range(s)), zero) for j in range(s)] for i in range(s)]
            Mk = [[MM[i][j] + (prev_c if i == j else zero) for j in range(s)] for i in range(s)]
            AM = [[sum((M[i][l] * Mk[l][j] for l in range(s)), zero) for j in range(s)] for i in range(s)]
            tr = sum((AM[i][i] for i in range(s)), zero)
            ck = -tr * ar.num(1, k)
            coeffs.append(ck)
            prev_c = ck
    return coeffs


@dataclass
class Stability:
    """R(z) = P(z)/Q(z); ``r_inf`` the limit at infinity (float, inf for |R| unbounded);
    ``r_inf_str`` exact when available; ``A_singular`` whether 1 - b^T A^{-1} 1 is unusable."""

    P: list
    Q: list
    r_inf: float
    r_inf_str: str
    A_singular: bool
    note: str


def stability(ar, A, b) -> Stability:
    """Stability function of (A, b): R(z) = det(I - z(A - 1 b^T)) / det(I - z A); R(inf) is
    the ratio of leading coefficients (= 1 - b^T A^{-1} 1 when A is invertible)."""
    s = len(b)
    with ar.context():
        Ab = [[A[i][j] - b[j] for j in range(s)] for i in range(s)]
        P = char_coeffs(ar, Ab)
        Q = char_coeffs(ar, A)

        def deg(c):
            d = len(c) - 1
            while d > 0 and ar.is_zero(c[d]):
                d -= 1
            return d

        dP, dQ = deg(P), deg(Q)
        A_singular = ar.is_zero(Q[s])  # det(I - zA) has degree s iff det A != 0
        if dP > dQ:
            r, rs = float("inf"), "inf"
        elif dP < dQ:
            r, rs = 0.0, "0"
        else:
            # balls: the ratio of the midpoints (the entries as written); the quotient ball of two
            # wide balls is centred elsewhere
            ratio = P[dP].mid() / Q[dQ].mid() if ar.ball else P[dP] / Q[dQ]
            r, rs = ar.to_float(ratio), ar.to_str(ratio)
        note = ("A singular: 1 - b^T A^{-1} 1 undefined; R(inf) is the limit of P/Q"
                if A_singular else "R(inf) = 1 - b^T A^{-1} 1")
    return Stability(P, Q, r, rs, A_singular, note)
