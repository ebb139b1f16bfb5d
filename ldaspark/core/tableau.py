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

from .errors import InputError, TableauError

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

    The entries are c, b, A (21a), b_hat, A_hat (21b), b_tilde, A_tilde (21b, d) and the
    (s-1) x s matrix omega of (21e).

    Parameters
    ----------
    name : str
        The method's name.
    s : int
        Number of stages.
    exact : dict, optional
        Each entry name mapped to a sympy Matrix (vectors as s x 1, omega as (s-1) x s); None
        for tableaux known only numerically.
    builder : callable, optional
        ``builder(dps)`` returns the same entries as nested lists of mpf correct to ``dps``
        digits.
    source_digits : int, optional
        The precision of the input entries (None when exact or computable to any precision).
    claimed_order : int, optional
        The order the source claims (checked by the audit, not trusted).
    family : str, optional
        The family name (``gauss``, ``lobatto-iiia-iiib``, ..., ``custom``).
    sources : dict, optional
        The entries as given in a file (kept for the audit report).
    decimal_digits, decimal_digits_min : int, optional
        Largest and smallest number of digits of decimal-literal entries.
    _cache : dict
        Internal memo of derived arrays (not compared, not printed).

    See Also
    --------
    load_tableau : read a tableau file.
    gauss : a built-in family.

    Examples
    --------
    >>> import ldaspark
    >>> t = ldaspark.gauss(2)
    >>> t.arrays().A.shape
    (2, 2)
    """

    name: str
    s: int
    exact: dict | None = None
    builder: Callable[[int], dict] | None = None
    source_digits: int | None = None
    claimed_order: int | None = None
    family: str = "custom"
    #: the entries as the file gave them (name -> list, or list of lists, of JSON values: int,
    #: float, str; or (value, exact_delta) after ``with_entry``), None for built-ins: the
    #: precision the entries carry is read from these (``ball_entries``)
    sources: dict | None = None
    #: the largest number of significant digits of a decimal literal in a string entry (the
    #: "digits given"), None when no string entry has a decimal literal
    decimal_digits: int | None = None
    #: the fewest significant digits of a decimal literal of at least LONG_DECIMAL digits (None if
    #: there is none): below ``decimal_digits`` when the entries were printed to different precisions
    decimal_digits_min: int | None = None
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        # constructed directly (it is exported), a tableau gets the checks of its readers: a
        # bool or text s, no coefficients, or coefficients of another shape are one TableauError
        from .validate import MAX_STAGES_CEILING
        if not isinstance(self.name, str) or not 0 < len(self.name) <= 500:
            raise TableauError(f"tableau name must be a non-empty string, got {type(self.name).__name__}")
        s = self.s
        if isinstance(s, (bool, np.bool_)) or not isinstance(s, (int, np.integer)) \
                or not 1 <= s <= MAX_STAGES_CEILING:
            raise TableauError(f"{self.name}: s must be an integer between 1 and {MAX_STAGES_CEILING}, "
                               f"got {str(s)[:40]!r}")
        self.s = int(s)
        if (self.exact is None) == (self.builder is None):
            raise TableauError(f"{self.name}: give exactly one of exact= (a dict of sympy matrices) and builder=")
        if self.builder is not None and not callable(self.builder):
            raise TableauError(f"{self.name}: builder must be callable (dps -> entries)")
        if self.exact is not None:
            if not isinstance(self.exact, dict) or set(NAMES) - set(self.exact):
                raise TableauError(f"{self.name}: exact must be a dict with the keys {', '.join(NAMES)}")
            want = {k: ((self.s, 1) if k in VECTOR_NAMES else (self.s - 1, self.s) if k == "omega"
                        else (self.s, self.s)) for k in NAMES}
            for k in NAMES:
                shape = getattr(self.exact[k], "shape", None)
                if not isinstance(self.exact[k], sympy.MatrixBase) or (shape != want[k] and self.exact[k].rows):
                    raise TableauError(f"{self.name}: exact[{k!r}] must be a sympy Matrix of shape {want[k]}, "
                                       f"got {type(self.exact[k]).__name__} {shape}")

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
        """The entries are exact sympy numbers (decimal strings read as exact decimals)."""
        return self.exact is not None and self.source_digits is None

    @property
    def known_exactly(self) -> bool:
        """The entries are exact and carry no decimal literal: each is known exactly, not only
        to the digits printed (``precision_kind``)."""
        return self.is_exact and self.decimal_digits is None

    @property
    def json_numbers(self) -> bool:
        """Some entry is a JSON number read as its decimal text (``JsonNumber``)."""
        return self.sources is not None and any(
            isinstance(x[0] if isinstance(x, tuple) else x, JsonNumber)
            for v in self.sources.values() for x in _flatten(v))

    @property
    def has_float_entries(self) -> bool:
        """Some entry is a float64 (a JSON number with a point or an exponent)."""
        return self.sources is not None and any(
            _leaf_is_float(x) for v in self.sources.values() for x in _flatten(v))

    def precision_kind(self) -> str:
        """'exact', 'decimal' (string entries with decimal literals), 'float' (float64 entries),
        'decimal+float', or 'computed' (a built-in known to any precision, ``builder``)."""
        if self.exact is None:
            return "computed"
        dec = self.decimal_digits is not None and (self.sources is None or any(
            _leaf_is_decimal_string(x) for v in self.sources.values() for x in _flatten(v)))
        flt = self.has_float_entries or (self.sources is None and self.source_digits is not None)
        return "decimal+float" if dec and flt else "decimal" if dec else "float" if flt else "exact"

    def precision_text(self) -> str:
        """What the entries carry, in words (the audit's report)."""
        kind = self.precision_kind()
        D, Dmin = self.decimal_digits, self.decimal_digits_min
        if D and Dmin and Dmin < D:
            dec = (f"decimal literals with {Dmin} to {D} significant digits (one of {LONG_DECIMAL} or more "
                   f"digits known to half a unit in its last digit, a shorter one (a terminating expansion) "
                   f"to half a unit in the {_ordinal(D)} significant digit)")
        else:
            dec = (f"decimal literals with up to {D} significant digit{'s' if D != 1 else ''} (each taken as "
                   f"known to half a unit in its {_ordinal(D)} significant digit)") if D else ""
        flt = "float64 entries (each known to half a unit in the last place, 2^-53 ~ 1.1e-16 relative)"
        if self.json_numbers:
            flt = (f"JSON numbers read as decimal texts with up to {D} significant digits (each known to half "
                   f"a unit in its last digit, a short one (a terminating expansion) in the {_ordinal(D)}, and "
                   f"one of at most {FLOAT64_REPR_DIGITS} digits also to half an ulp of float64, 2^-53 ~ 1.1e-16 "
                   "relative: it may be a float64's shortest writing)")
        return {"exact": "exact entries (integers, fractions, radicals, sin/cos/pi expressions)",
                "computed": "built-in coefficients computed to any precision",
                "decimal": dec, "float": flt, "decimal+float": f"{dec}; {flt}"}[kind]

    def ball_entries(self, digits: int) -> dict:
        """The entries as arb balls at ``digits`` working digits that enclose the values the entries
        stand for: exact entries to the working precision; a decimal literal to half a unit in its
        ``decimal_digits``-th significant digit (a coefficient printed to D digits; a shorter literal
        is a terminating expansion, exact at D digits); a float64 to 2^-53 relative (half an ulp);
        a built-in's computed coefficient to 10^(5 - digits) (its builder is correct to the digits
        asked for). A literal of LONG_DECIMAL or more digits counts with its own digits (entries
        printed to different precisions). Vectors flat, matrices as lists of rows."""
        key = ("ball", digits)
        if key not in self._cache:
            import flint
            prec = int(digits * 3.33) + 16
            with flint.ctx.workprec(prec):
                if self.sources is not None:
                    ev = _BallEvaluator(self.decimal_digits)
                    out = {k: _map_nested(v, ev.leaf) for k, v in self.sources.items()}
                    if "omega" not in out:
                        out["omega"] = [[_sympy_ball(self.exact["omega"][i, j], digits, None)
                                         for j in range(self.s)] for i in range(self.s - 1)]
                elif self.exact is not None:
                    src = None if self.is_exact else (self.source_digits or 15)
                    out = {k: _matrix_to_json(M, k, lambda e: _sympy_ball(e, digits, src))
                           for k, M in self.exact.items()}
                else:
                    with mpmath.workdps(digits + 10):
                        raw = self.builder(digits + 10)
                    rad = flint.arb(10) ** (-digits + 5)
                    ball = lambda x: flint.arb(_mpf_to_fmpq(x)) + flint.arb(0, rad * max(1, abs(float(x))))
                    out = {k: _map_nested(v, ball) for k, v in raw.items()}
                    for k in VECTOR_NAMES:
                        out[k] = [x[0] if isinstance(x, list) else x for x in out[k]]
            self._cache[key] = out
        return self._cache[key]

    def _check_entry_change(self, name, i, j, delta) -> None:
        """``with_entry``'s arguments: a coefficient of the tableau, indices in its range (no
        negative ones: they would silently wrap to the last entry), a finite real delta."""
        from . import validate
        ent = self.exact if self.exact is not None else (self.builder(16) if self.builder is not None else None)
        if not isinstance(name, str) or ent is None or name not in ent:
            raise TableauError(f"with_entry: name must be one of {', '.join(sorted(ent or {}))}, got "
                               f"{validate._describe(name)}")
        shape = np.shape(np.asarray(sympy.Matrix(ent[name]).tolist() if self.exact is not None else ent[name],
                                    dtype=object))
        # the A family is s x s (1 x 1 at s = 1, where the shape alone cannot tell it from a vector)
        matrix = name in ("A", "A_hat", "A_tilde") or (len(shape) == 2 and shape[1] > 1)
        if (j is None) == matrix:
            raise TableauError(f"with_entry: {name} is a {'matrix: give i and j' if matrix else 'vector: give j=None'}")
        for nm, x, size in (("i", i, shape[0]), ("j", j, shape[1] if matrix else 1)):
            if nm == "j" and not matrix:
                continue
            if validate._is_bool(x) or not isinstance(x, (int, np.integer)) or not 0 <= x < size:
                raise TableauError(f"with_entry: {nm} must be an index in 0..{size - 1}, got {validate._describe(x)}")
        if not isinstance(delta, str):
            try:
                validate.real_number(delta, f"with_entry: delta of {name}")
            except InputError as exc:
                raise TableauError(str(exc)) from None

    def with_entry(self, name: str, i: int, j: int | None, delta) -> "SparkTableau":
        """A copy with one entry changed by ``delta`` (negative controls)."""
        self._check_entry_change(name, i, j, delta)
        if self.exact is not None:
            if isinstance(delta, str):          # text is parsed (bounded), never nsimplify'd or evaluated
                delta = parse_exact_string(delta, f"delta of {name}")
            ex = {k: sympy.Matrix(v) for k, v in self.exact.items()}
            if j is None:
                ex[name][i, 0] += sympy.nsimplify(delta)
            else:
                ex[name][i, j] += sympy.nsimplify(delta)
            src = None
            if self.sources is not None:
                src = {k: [list(r) if isinstance(r, list) else r for r in v] for k, v in self.sources.items()}
                d = sympy.nsimplify(delta)
                if j is None:
                    src[name][i] = (src[name][i], d)
                else:
                    src[name][i][j] = (src[name][i][j], d)
            return SparkTableau(f"{self.name}+d{name}[{i},{j}]", self.s, exact=ex,
                                source_digits=self.source_digits, claimed_order=None, family="perturbed",
                                sources=src, decimal_digits=self.decimal_digits,
                                decimal_digits_min=self.decimal_digits_min)
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


def _flatten(v):
    if isinstance(v, list):
        for x in v:
            yield from _flatten(x)
    else:
        yield v


def _leaf_is_float(x) -> bool:
    while isinstance(x, tuple):          # (value, exact delta) from with_entry
        x = x[0]
    return isinstance(x, (float, JsonNumber))


def _leaf_is_decimal_string(x) -> bool:
    """A string entry (not a JSON number) with a decimal literal in it."""
    while isinstance(x, tuple):
        x = x[0]
    if not isinstance(x, str) or isinstance(x, JsonNumber):
        return False
    import re
    return re.search(r"(^|[^A-Za-z_])[0-9_]*\.[0-9]|[0-9][eE][+-]?[0-9]", x) is not None


class JsonNumber(str):
    """A JSON number with a point or an exponent, kept as its text (``json.loads(...,
    parse_float=JsonNumber)``): a decimal known to its own digits. One of at most
    FLOAT64_REPR_DIGITS significant digits may also be the shortest writing of a float64, which
    stands for the intended coefficient only to half an ulp: its ball gets both radii
    (``_BallEvaluator.leaf``)."""
    __slots__ = ()


#: a float64 printed by a shortest round-trip printer has at most 17 significant digits
FLOAT64_REPR_DIGITS = 17


def _ordinal(n: int) -> str:
    return f"{n}{'th' if 10 <= n % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th')}"


def _mpf_to_fmpq(x):
    """An mpf as the exact rational flint.fmpq (its binary value)."""
    import flint
    # the raw tuple: mpmath.mpf(x) would round x to the current (default 53-bit) precision
    sign, man, exp, _ = x._mpf_ if hasattr(x, "_mpf_") else mpmath.mpf(x)._mpf_
    if not man:
        return flint.fmpq(0)
    man, exp = (-1) ** sign * int(man), int(exp)
    return flint.fmpq(man * 2 ** exp) if exp >= 0 else flint.fmpq(man, 2 ** -exp)


def _float_ball(x: float):
    """A float64 as the ball of the numbers it may stand for: its exact binary value, radius
    half an ulp (|x| 2^-53): the float nearest to the intended coefficient."""
    import flint
    from fractions import Fraction
    q = Fraction(x)
    return flint.arb(flint.fmpq(q.numerator, q.denominator)) + flint.arb(0, abs(flint.arb(x)) * flint.arb(2) ** -53)


def decimal_info(text: str):
    """(exact value as fmpq, significant digits, decimal exponent of the leading digit) of a
    decimal literal such as '0.2113', '2.5e-1', '1_000.0'. Significant digits count from the
    first nonzero digit and include trailing zeros ('0.50' has 2); zero has 0."""
    from decimal import Decimal
    import flint
    d = Decimal(text.replace("_", ""))
    sign, digits, exp = d.as_tuple()
    n = int("".join(map(str, digits)) or "0")
    if n == 0:
        return flint.fmpq(0), 0, 0
    sig = len(str(n))
    val = flint.fmpq(n * 10 ** exp) if exp >= 0 else flint.fmpq(n, 10 ** -exp)
    return (-val if sign else val), sig, d.adjusted()


def decimal_radius(adjusted: int, digits_given: int):
    """Half a unit in the ``digits_given``-th significant digit of a decimal whose leading digit
    has exponent ``adjusted``: 0.5 * 10^(adjusted - digits_given + 1), as an exact fmpq."""
    import flint
    e = adjusted - digits_given + 1
    return flint.fmpq(5 * 10 ** e, 10) if e >= 0 else flint.fmpq(5, 10 ** (1 - e))


#: A decimal literal with at least this many significant digits is known to half a unit in its own
#: last digit; a shorter one is read as a terminating expansion ("0.5", "0.25": printing to D digits
#: drops trailing zeros), known to the tableau's largest digit count D
LONG_DECIMAL = 8


class _BallEvaluator:
    """Encloses a tableau entry as the file gave it in an arb ball (at flint's current
    precision). String entries are walked from their AST once more (they were validated by
    ``parse_exact_string`` when the file was loaded; nothing is evaluated as Python), in complex
    ball arithmetic (acb) so that sqrt of a negative intermediate follows sympy's principal branch;
    the entry is real (checked at load), its real part is returned."""

    def __init__(self, digits_given: int | None):
        self.D = digits_given

    def leaf(self, x):
        import flint
        if isinstance(x, tuple):                      # (value, exact delta) from with_entry
            return self.leaf(x[0]) + _sympy_ball(x[1], int(flint.ctx.prec / 3.33), None)
        if isinstance(x, bool):
            raise TableauError(f"entry {x!r} is not a number")
        if isinstance(x, int):
            return flint.arb(x)
        if isinstance(x, float):
            return _float_ball(x)
        import ast
        src = x.strip()
        if isinstance(x, JsonNumber):
            # the decimal text to its digits (as a string entry), and, when it may be the shortest
            # writing of a float64, half an ulp on top (the float nearest the intended coefficient)
            ball = self.node(ast.parse(src, mode="eval").body, src).real
            # (not in a file whose longest number has more digits than a float64's writing: there a
            # short one such as 0.5 is a terminating expansion, as a string would be)
            if decimal_info(src.lstrip("-"))[1] <= FLOAT64_REPR_DIGITS and (self.D or 0) <= FLOAT64_REPR_DIGITS:
                ball = ball + flint.arb(0, abs(ball.mid()) * flint.arb(2) ** -53)
            return ball
        z = self.node(ast.parse(src, mode="eval").body, src)
        return z.real

    def node(self, n, src):
        import ast
        import flint
        acb = flint.acb
        if isinstance(n, ast.Constant):
            if isinstance(n.value, int):
                return acb(n.value)
            text = ast.get_source_segment(src, n) or repr(n.value)
            val, sig, adj = decimal_info(text)
            ball = flint.arb(val)
            if self.D is not None and sig > 0:
                known = sig if sig >= LONG_DECIMAL else self.D
                ball = ball + flint.arb(0, flint.arb(decimal_radius(adj, known)))
            return acb(ball)
        if isinstance(n, ast.UnaryOp):
            v = self.node(n.operand, src)
            return -v if isinstance(n.op, ast.USub) else v
        if isinstance(n, ast.BinOp):
            if isinstance(n.op, ast.Pow):
                ex = n.right
                k = -ex.operand.value if isinstance(ex, ast.UnaryOp) else ex.value
                return self.node(n.left, src) ** k
            a, b = self.node(n.left, src), self.node(n.right, src)
            if isinstance(n.op, ast.Add):
                return a + b
            if isinstance(n.op, ast.Sub):
                return a - b
            return a * b if isinstance(n.op, ast.Mult) else a / b
        if isinstance(n, ast.Name):                   # pi (the only constant of the whitelist)
            return acb.pi()
        if isinstance(n, ast.Call):
            f = n.func.id
            if f == "Rational":           # integer arguments (checked at load)
                args = [int(parse_exact_string(ast.get_source_segment(src, a) or "0")) for a in n.args]
                return acb(flint.fmpq(*args))
            v = self.node(n.args[0], src)
            return {"sqrt": v.sqrt, "sin": v.sin, "cos": v.cos}[f]()
        raise TableauError(f"entry {src!r}: unsupported syntax {type(n).__name__}")


def _sympy_ball(e, digits, float_digits):
    """A sympy number as an arb ball at flint's current precision: walked node by node (Add, Mul,
    Pow, Rational, sin, cos, pi) in acb; anything else through sympy.N with guard digits and a
    radius of 10^-(digits + 5) relative. A sympy Float stands for its binary value, known to half a
    unit in its ``float_digits``-th digit when given (a float-precision tableau)."""
    import flint
    acb = flint.acb

    def walk(x):
        if x.is_Integer:
            return acb(int(x))
        if x.is_Rational:
            return acb(flint.fmpq(int(x.p), int(x.q)))
        if x.is_Float:
            b = flint.arb(_mpf_to_fmpq(x))
            if float_digits:
                b = b + flint.arb(0, abs(b) * flint.arb(10) ** (1 - float_digits) / 2)
            return acb(b)
        if x is sympy.pi:
            return acb.pi()
        if x.is_Add:
            out = acb(0)
            for a in x.args:
                out += walk(a)
            return out
        if x.is_Mul:
            out = acb(1)
            for a in x.args:
                out *= walk(a)
            return out
        if x.is_Pow and x.exp.is_Integer:
            return walk(x.base) ** int(x.exp)
        if x.is_Pow and x.exp.is_Rational:
            base = walk(x.base)
            root = base.sqrt() if x.exp.q == 2 else base ** acb(flint.fmpq(1, int(x.exp.q)))
            return root ** int(x.exp.p)
        if isinstance(x, (sympy.sin, sympy.cos)):
            v = walk(x.args[0])
            return v.sin() if isinstance(x, sympy.sin) else v.cos()
        val = sympy.re(sympy.N(x, digits + 10))
        re = flint.arb(_mpf_to_fmpq(val) if val != 0 else 0)
        return acb(re + flint.arb(0, flint.arb(10) ** -(digits + 5) * max(1, abs(float(val)))))

    return walk(sympy.sympify(e)).real


def omega_rank(tab: "SparkTableau", dps: int | None = None, extra_rows=None) -> dict:
    """The rank of omega (21e) decided at the precision its entries carry, rank-revealing for
    Vandermonde-type matrices (the default rows b_j c_j^(i-1) lose ~0.7 digits per stage):

    singular values by mpmath's SVD at ``w`` digits (backward stable: each computed value is within
    ~s 10^-w sigma_max of the exact one of the matrix held), and the uncertainty of the matrix the
    entries stand for, ||Delta omega||_F, from the entries' balls (``ball_entries``; the default
    omega from the balls of b and c). Weyl: every matrix within that uncertainty has its singular
    values within ``bound`` = ||Delta omega||_F + s^2 10^(5-w) sigma_max of the computed ones, so a
    singular value above ``bound`` is nonzero for all of them, one at or below it is not decided
    nonzero. ``rank`` counts the singular values above the bound (exact entries: the uncertainty is
    that of the working precision only). ``extra_rows``: rows stacked under omega (mpf lists at
    ``w`` digits; ``check_omega_default``). Returns {"rank", "sigma" (descending floats), "bound",
    "dps", "radius"}."""
    import flint
    s = tab.s
    D = max(tab.decimal_digits or 0, tab.source_digits or 0)
    w = dps or max(60, D + 30, 3 * s + 30)
    ent = tab.mp_entries(w)
    digits = max(D + 20, 40)
    balls = tab.ball_entries(digits)
    given = tab.sources is not None and "omega" in tab.sources
    if tab.sources is not None and not given:
        with flint.ctx.workprec(int(digits * 3.33) + 16):
            bv, cv = balls["b"], balls["c"]
            obs = [[bv[j] * cv[j] ** i for j in range(s)] for i in range(s - 1)]
    else:
        obs = balls["omega"]
    rad2 = sum(float(x.rad()) ** 2 for r in obs for x in r)
    if tab.known_exactly or tab.exact is None:
        rad2 = 0.0                      # the entries stand for themselves
    with mpmath.workdps(w):
        rows = [list(r) for r in ent["omega"]] + [list(r) for r in (extra_rows or [])]
        sv = mpmath.svd_r(mpmath.matrix(rows), compute_uv=False) if rows else []
        sig = sorted((float(x) for x in sv), reverse=True)
    smax = sig[0] if sig else 0.0
    bound = math.sqrt(rad2) + s * s * 10.0 ** (5 - w) * max(smax, 1e-300)
    return {"rank": sum(x > bound for x in sig), "sigma": sig, "bound": bound, "dps": w,
            "radius": math.sqrt(rad2)}


def _default_omega_exact(b, c, s):
    return sympy.Matrix(max(s - 1, 0), s, lambda i, j: b[j] * c[j] ** i)


def _col(vals):
    return sympy.Matrix(len(vals), 1, list(vals))


# --- JSON input ---------------------------------------------------------------------------
# Every bound below keeps parsing a hostile file fast (each entry well under a millisecond to a
# few milliseconds) and memory-bounded; each violation is one TableauError line.
_MAX_ENTRY_LEN = 200          # characters of one string entry
_MAX_EXPONENT = 64            # product of the literal exponents of nested '**'
_MAX_SCI_EXPONENT = 400       # |e| of scientific notation 1.5e-30 (float64 spans 1e-324 .. 1e308)
_MAX_DEPTH = 32               # depth of the expression tree
_MAX_BITS = 8192              # numerator / denominator of an intermediate rational
_MAX_TRIG_ARG = 1e6           # |x| in sin(x), cos(x)
MAX_MAGNITUDE = 1e300         # |entry|: every entry converts to a finite float64
MAX_STAGES = 20               # s, unless raised (max_stages=, --max-stages)
_FUNCTIONS = {"sqrt": sympy.sqrt, "Rational": sympy.Rational, "cos": sympy.cos, "sin": sympy.sin}
_CONSTANTS = {"pi": sympy.pi}
# expressions of the Python API (parse_expression): more functions, longer and deeper text
_MAX_EXPR_LEN = 4000
_MAX_EXPR_DEPTH = 64
_SYMBOLIC_FUNCTIONS = dict(_FUNCTIONS, tan=sympy.tan, exp=sympy.exp, log=sympy.log, asin=sympy.asin,
                           acos=sympy.acos, atan=sympy.atan, sinh=sympy.sinh, cosh=sympy.cosh, tanh=sympy.tanh)
_SYMBOLIC_CONSTANTS = {"E": sympy.E}


def _bits(e) -> int:
    """Bit size of a rational (0 for other numbers: radicals keep their rational parts small)."""
    if getattr(e, "is_Rational", False):
        return max(int(e.p).bit_length(), int(e.q).bit_length())
    return 0


def _sci_exponent(text: str) -> int:
    """The decimal exponent of a float literal's text ('1.5e-30' -> -30; 0 without one)."""
    import re
    m = re.search(r"[eE]([+-]?[0-9_]+)$", text)
    if not m:
        return 0
    digits = m.group(1).replace("_", "")
    if len(digits.lstrip("+-")) > 6:
        return 10 ** 6
    return int(digits)


#: binary precision at which a denominator that is not a plain rational is tested for zero: a
#: ball that still contains 0 at ~3600 digits is an exact zero (sqrt(2)**2 - 2, sin(1)**2 + cos(1)**2 - 1)
#: or so small that the entry would exceed MAX_MAGNITUDE
_ZERO_TEST_BITS = 12000


def _parse_source(x, where, max_len, error, shown):
    """(stripped text, ``ast`` expression tree) of the string ``x``, the first step shared by
    ``parse_exact_string`` (an entry of the coefficients of (21): ``max_len`` = 200, TableauError)
    and ``parse_expression`` (L, k and the other strings of the Python API: 4000, the caller's
    ``error``). Raises ``error`` naming ``where`` when ``x`` is not a string, is longer than
    ``max_len`` characters or does not parse as one Python expression (``shown(x)`` in the message)."""
    import ast
    if not isinstance(x, str):
        raise error(f"{where}: expected a string, got {type(x).__name__}")
    if len(x) > max_len:
        raise error(f"{where}: expression longer than {max_len} characters")
    src = x.strip()
    try:
        tree = ast.parse(src, mode="eval")
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        raise error(f"{where}: cannot parse {shown(x)}") from None
    return src, tree


def parse_exact_string(x: str, where: str = "entry", info: dict | None = None):
    """An exact tableau entry such as "1/4 - sqrt(3)/6" as a sympy number.

    Parsed with Python's ``ast`` and built node by node (never evaluated as Python): numbers
    (decimals read as exact decimals), + - * /, ** with a literal integer exponent, sqrt,
    Rational, sin, cos and pi. Bounded so that no entry can hang or exhaust memory: at most
    200 characters, tree depth 32, the product of nested '**' exponents at most 64, scientific
    exponents |e| <= 400, intermediate rationals of at most 8192 bits, |x| <= 1e6 inside sin/cos.
    Anything else is a TableauError naming the entry, and so is a denominator (or the base of a
    negative power) that is zero, also when sympy does not reduce it (``sin(1)**2 + cos(1)**2 - 1``):
    it is tested in ball arithmetic at 12000 bits. ``info``, when given, receives ``digits``: the
    largest number of significant digits of a decimal literal in the entry (0 if none)."""
    src, tree = _parse_source(x, where, _MAX_ENTRY_LEN, TableauError, repr)
    b = _EntryBuilder(x, src, where)
    e = b.build(tree.body, 0, 1)
    if not getattr(e, "is_number", False):
        raise b.bad("not a number")
    if info is not None:
        info["digits"] = max(info.get("digits", 0), b.digits)
        info.setdefault("counts", set()).update(b.counts)
    return e


class _EntryBuilder:
    """Builds the sympy number of one entry from its AST, enforcing the bounds as it goes.
    ``power`` is the product of the exponents of the '**' nodes above the current node.
    ``names`` (``parse_expression``): the symbols an expression may use, by name; with them the
    builder also takes the functions of _SYMBOLIC_FUNCTIONS, rational exponents p/q and long
    sums and products (a chain a + b + c counts as one level of depth, not one per term)."""

    def __init__(self, x, src, where, names=None, error=TableauError):
        self.x, self.src, self.where = x, src, where
        self.names, self.error = names, error
        self.symbolic = names is not None
        self.depth_limit = _MAX_EXPR_DEPTH if self.symbolic else _MAX_DEPTH
        self.digits = 0         # most significant digits of a decimal literal seen
        self.counts = set()     # the significant digits of every nonzero decimal literal

    def zero(self, value, node) -> bool:
        """Whether a (validated) denominator is zero: exactly for a rational, else by its ball at
        _ZERO_TEST_BITS bits (decimals read as exact), which contains 0 for every exact zero."""
        if value == 0:
            return True
        if getattr(value, "is_Rational", False):
            return False
        import flint
        with flint.ctx.workprec(_ZERO_TEST_BITS):
            z = _BallEvaluator(None).node(node, self.src)
            return bool(z.real.contains(0) and z.imag.contains(0))

    def bad(self, why):
        what = "an expression" if self.symbolic else "a number"
        return self.error(f"{self.where}: {_shown(self.x) if self.symbolic else repr(self.x)} is not {what} ({why})")

    def build(self, node, depth, power):
        import ast
        if depth > self.depth_limit:
            raise self.bad(f"nested deeper than {self.depth_limit} levels")
        if isinstance(node, ast.Constant):
            return self.constant(node, power)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
            v = self.build(node.operand, depth + 1, power)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.BinOp):
            if isinstance(node.op, ast.Pow):
                return self.pow(node, depth, power)
            return self.binop(node, depth, power)
        if isinstance(node, ast.Name) and self.symbolic and node.id in self.names:
            return self.names[node.id]
        if isinstance(node, ast.Name) and node.id in _CONSTANTS:
            return _CONSTANTS[node.id]
        if isinstance(node, ast.Name) and self.symbolic and node.id in _SYMBOLIC_CONSTANTS:
            return _SYMBOLIC_CONSTANTS[node.id]
        functions = _SYMBOLIC_FUNCTIONS if self.symbolic else _FUNCTIONS
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in functions
                and not node.keywords and 1 <= len(node.args) <= 2):
            return self.call(node, depth, power)
        name = getattr(node, "id", None) or getattr(getattr(node, "func", None), "id", None)
        raise self.bad(f"unknown name {name!r}" if name else f"unsupported syntax {type(node).__name__}")

    def constant(self, node, power):
        import ast
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise self.bad(f"literal {node.value!r}")
        text = ast.get_source_segment(self.src, node) or repr(node.value)
        if isinstance(node.value, int):
            e = sympy.Integer(node.value)
        else:
            if abs(_sci_exponent(text)) > _MAX_SCI_EXPONENT:
                raise self.bad(f"exponent of scientific notation beyond +-{_MAX_SCI_EXPONENT}")
            if not math.isfinite(node.value):
                raise self.bad("not finite")
            e = sympy.Rational(text.replace("_", ""))
            if e != 0:
                sig = decimal_info(text)[1]
                self.digits = max(self.digits, sig)
                self.counts.add(sig)
        if _bits(e) * power > _MAX_BITS:
            raise self.bad(f"a power of it exceeds {_MAX_BITS} bits")
        return e

    def pow(self, node, depth, power):
        import ast
        ex = node.right
        neg = isinstance(ex, ast.UnaryOp) and isinstance(ex.op, ast.USub)
        lit = ex.operand if neg else ex
        if self.symbolic and isinstance(lit, ast.BinOp) and isinstance(lit.op, ast.Div):
            return self.rational_pow(node, lit, neg, depth, power)
        if not (isinstance(lit, ast.Constant) and type(lit.value) is int and lit.value <= _MAX_EXPONENT):
            raise self.bad(f"'**' needs a literal integer exponent <= {_MAX_EXPONENT}")
        if lit.value * power > _MAX_EXPONENT:
            raise self.bad(f"nested '**' with exponents multiplying to more than {_MAX_EXPONENT}")
        base = self.build(node.left, depth + 1, power * max(lit.value, 1))
        if neg and lit.value != 0 and self.zero(base, node.left):
            raise self.bad("division by zero")
        r = base ** (-lit.value if neg else lit.value)
        if _bits(r) > _MAX_BITS:
            raise self.bad(f"a power exceeds {_MAX_BITS} bits")
        return r

    def rational_pow(self, node, frac, neg, depth, power):
        """base ** (p/q) with literal integers 1 <= p, q <= _MAX_EXPONENT (expressions only)."""
        import ast
        p, q = frac.left, frac.right
        if not all(isinstance(x, ast.Constant) and type(x.value) is int and 1 <= x.value <= _MAX_EXPONENT
                   for x in (p, q)):
            raise self.bad(f"'**' needs a literal integer or p/q exponent with 1 <= p, q <= {_MAX_EXPONENT}")
        e = sympy.Rational(p.value, q.value)
        up = max(int(sympy.ceiling(e)), 1)
        if up * power > _MAX_EXPONENT:
            raise self.bad(f"nested '**' with exponents multiplying to more than {_MAX_EXPONENT}")
        base = self.build(node.left, depth + 1, power * up)
        if neg and base == 0:
            raise self.bad("division by zero")
        return base ** (-e if neg else e)

    def binop(self, node, depth, power):
        import ast
        ops = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
               ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b}
        f = ops.get(type(node.op))
        if f is None:
            raise self.bad(f"operator {type(node.op).__name__}")
        chain = [node]
        if self.symbolic:                     # a + b + c + ...: the left spine at one level of depth
            group = (ast.Add, ast.Sub) if isinstance(node.op, (ast.Add, ast.Sub)) else (ast.Mult, ast.Div)
            while isinstance(chain[-1].left, ast.BinOp) and isinstance(chain[-1].left.op, group):
                chain.append(chain[-1].left)
        if self.symbolic:                     # one Add / Mul of all terms: linear in their number
            terms = [self.build(chain[-1].left, depth + 1, power)]
            for nd in reversed(chain):
                b = self.build(nd.right, depth + 1, power)
                if isinstance(nd.op, ast.Div) and b == 0:
                    raise self.bad("division by zero")
                op = type(nd.op)
                terms.append(b if op in (ast.Add, ast.Mult) else (-b if op is ast.Sub else 1 / b))
            r = sympy.Add(*terms) if isinstance(node.op, (ast.Add, ast.Sub)) else sympy.Mul(*terms)
            if _bits(r) > _MAX_BITS or _coeff_bits(r) > _MAX_BITS:
                raise self.bad(f"a rational coefficient exceeds {_MAX_BITS} bits")
            return r
        a, b = self.build(node.left, depth + 1, power), self.build(node.right, depth + 1, power)
        if isinstance(node.op, ast.Div) and self.zero(b, node.right):
            raise self.bad("division by zero")
        r = f(a, b)
        if _bits(r) > _MAX_BITS:
            raise self.bad(f"an intermediate rational exceeds {_MAX_BITS} bits")
        return r

    def call(self, node, depth, power):
        fname = node.func.id
        args = [self.build(a, depth + 1, power) for a in node.args]
        if fname == "Rational":
            if not all(a.is_Integer for a in args) or (len(args) == 2 and args[1] == 0):
                raise self.bad("Rational needs integer arguments and a nonzero denominator")
        elif len(args) != 1:
            raise self.bad(f"{fname} takes one argument")
        elif fname in ("sin", "cos") and not _small(args[0], _MAX_TRIG_ARG):
            if not (self.symbolic and not args[0].is_number):
                raise self.bad(f"argument of {fname} is not a real number of modulus <= {_MAX_TRIG_ARG:g}")
        elif self.symbolic and args[0].is_number and not _small(args[0], _MAX_TRIG_ARG):
            raise self.bad(f"argument of {fname} is not a real number of modulus <= {_MAX_TRIG_ARG:g}")
        return (_SYMBOLIC_FUNCTIONS if self.symbolic else _FUNCTIONS)[fname](*args)


def _coeff_bits(e) -> int:
    """Bit size of the rational coefficient of a product or constant term of a sum."""
    try:
        c = e.as_coeff_Mul()[0] if e.is_Mul else (e.as_coeff_Add()[0] if e.is_Add else e)
    except AttributeError:
        return 0
    return _bits(c)


def _shown(x) -> str:
    """A string in an error message: its repr, shortened."""
    r = repr(x)
    return r if len(r) <= 80 else r[:60] + "...'"


def parse_expression(x, names: dict, where: str = "expression", error=TableauError):
    """A symbolic expression such as "vx**2/2 + m*g*z" as a sympy expression in the given symbols.

    The strings a user gives the Python API (L, k, N, the mechanical parts, parameter values)
    come here, never to sympify or eval: parsed with Python's ``ast`` and built node by node as
    ``parse_exact_string`` does, with ``names`` (name -> sympy Symbol: the system's declared
    t, q, v, psi and parameters) as the only names besides pi and E, the functions sqrt, sin, cos,
    tan, exp, log, asin, acos, atan, sinh, cosh, tanh, Rational, literal integer or p/q exponents
    (the product of nested exponents at most 64), at most 4000 characters, depth 64 (a chain
    a + b + c ... counts as one level), rational coefficients of at most 8192 bits, numeric
    function arguments of modulus at most 1e6. Anything else raises ``error`` naming ``where``."""
    src, tree = _parse_source(x, where, _MAX_EXPR_LEN, error, _shown)
    b = _EntryBuilder(x, src, where, names=dict(names), error=error)
    try:
        e = b.build(tree.body, 0, 1)
    except RecursionError:
        raise b.bad("nested too deeply") from None
    if not isinstance(e, sympy.Expr):
        raise b.bad("not an expression")
    return e


def parse_number(x, where: str = "value", error=TableauError):
    """A number given as a string ("1/2", "sqrt(2)/3", "9.81") as an exact sympy number: the
    tableau entry parser (``parse_exact_string``), with a finite real value of modulus at most
    1e300; ``error`` instead of TableauError."""
    try:
        e, _ = _parse_entry(x, where)
    except TableauError as exc:
        raise error(str(exc)) from None
    return e


def _small(e, bound) -> bool:
    """|e| <= bound for a real number e (numerically, at 15 digits: e is already size-bounded)."""
    try:
        val = complex(sympy.N(e, 15))
    except (TypeError, ValueError, OverflowError):
        return False
    return val.imag == 0 and abs(val.real) <= bound


def _parse_entry(x, where, info: dict | None = None):
    """An entry: int (exact), string (exact expression, decimals read as exact decimals) or
    float (approximate, 53 bits). Returns (sympy number, is_exact). ``info`` collects the most
    significant digits of a decimal literal (``parse_exact_string``)."""
    if isinstance(x, bool) or x is None:
        raise TableauError(f"{where}: entry {x!r} is not a number")
    if isinstance(x, int):
        if x.bit_length() > 1000:                     # |x| > 1e300: not a float64, not a coefficient
            raise TableauError(f"{where}: integer with {len(str(abs(x)))} digits exceeds {MAX_MAGNITUDE:g}")
        return sympy.Integer(x), True
    if isinstance(x, float):
        if not math.isfinite(x):
            raise TableauError(f"{where}: entry {x!r} is not finite")
        return sympy.Float(x, 17), False
    if isinstance(x, str):
        e = parse_exact_string(x, where, info)
        if isinstance(x, JsonNumber):
            # known to its digits (and half an ulp), not exactly: the tableau is not exact
            sig = decimal_info(x.strip().lstrip("-"))[1]
            if info is not None and sig >= LONG_DECIMAL:      # short ones are terminating expansions
                info["json"] = min(info.get("json", 10 ** 6), 15 if sig <= FLOAT64_REPR_DIGITS else sig)
            return e, False
        if e.is_real is False:                        # sqrt(-1) * tiny: exactly non-real, however small
            raise TableauError(f"{where}: {x!r} is not a real number")
        try:
            num = sympy.N(e, 30)
            if bool(abs(num) > MAX_MAGNITUDE):
                raise TableauError(f"{where}: {x!r} exceeds {MAX_MAGNITUDE:g} in modulus")
            val = complex(num)
        except (TypeError, ValueError, OverflowError):
            raise TableauError(f"{where}: {x!r} is not a finite real number") from None
        if not (math.isfinite(val.real) and abs(val.imag) <= 1e-25 * (1 + abs(val.real))):
            raise TableauError(f"{where}: {x!r} is not a finite real number")
        if abs(val.real) > MAX_MAGNITUDE:
            raise TableauError(f"{where}: {x!r} exceeds {MAX_MAGNITUDE:g} in modulus")
        return e, True
    raise TableauError(f"{where}: entry {x!r} is not a number")


def check_stages(s: int, max_stages: int | None = None, what: str = "tableau") -> None:
    """s <= max_stages (default MAX_STAGES = 20): building, auditing and integrating cost grows
    like s^3 and beyond, so larger s must be asked for explicitly."""
    from .validate import MAX_STAGES_CEILING
    limit = MAX_STAGES if max_stages is None else max_stages
    if type(limit).__module__ == "numpy" and hasattr(limit, "dtype") and limit.dtype.kind in "iu":
        limit = int(limit)                   # np.int64(3) is an integer like 3
    if isinstance(limit, bool) or not isinstance(limit, int) or not 1 <= limit <= MAX_STAGES_CEILING:
        # --max-stages 10**6 was a MemoryError, 10**8 an OverflowError
        raise TableauError(f"max_stages must be an integer between 1 and {MAX_STAGES_CEILING}, got "
                           f"{limit if abs(limit) < 10 ** 12 else f'{float(limit):.3g}'}"
                           if isinstance(limit, int) else f"max_stages must be an integer, got {type(limit).__name__}")
    if s > limit:
        raise TableauError(f"{what} has s = {s} stages, more than the limit {limit} "
                           "(raise it with --max-stages / max_stages=)")


def from_json_dict(d: dict, name: str | None = None, max_stages: int | None = None) -> SparkTableau:
    """Tableau from the JSON format (keys c, A, A_hat, A_tilde, b, b_hat, b_tilde, optional
    omega and name). Exact when every entry is an int or string, else float precision.
    At most ``max_stages`` (default MAX_STAGES) stages."""
    if not isinstance(d, dict):
        raise TableauError("tableau JSON must be an object with keys c, A, A_hat, A_tilde, b, b_hat, b_tilde")
    missing = [k for k in NAMES if k != "omega" and k not in d]
    if missing:
        raise TableauError(f"tableau is missing key(s): {', '.join(missing)}")
    c = d["c"]
    if not isinstance(c, list) or not c:
        raise TableauError("c must be a non-empty list")
    s = len(c)
    check_stages(s, max_stages)
    all_exact = True
    ex = {}
    info = {"digits": 0}
    for k in NAMES:
        if k not in d:
            continue
        val = d[k]
        if k in VECTOR_NAMES:
            if not isinstance(val, list) or len(val) != s or any(isinstance(v, list) for v in val):
                raise TableauError(f"{k} must be a list of {s} numbers")
            ent = [_parse_entry(v, f"{k}[{i}]", info) for i, v in enumerate(val)]
            ex[k] = _col([e for e, _ in ent])
        else:
            rows = s - 1 if k == "omega" else s
            if (not isinstance(val, list) or len(val) != rows
                    or any(not isinstance(r, list) or len(r) != s for r in val)):
                raise TableauError(f"{k} must be a {rows} x {s} list of lists")
            ent = [[_parse_entry(v, f"{k}[{i}][{j}]", info) for j, v in enumerate(r)] for i, r in enumerate(val)]
            ex[k] = sympy.Matrix(rows, s, [e for r in ent for e, _ in r]) if rows else sympy.zeros(0, s)
            ent = [e for r in ent for e in r]
        all_exact = all_exact and all(flag for _, flag in ent)
    if "omega" not in ex:
        ex["omega"] = _default_omega_exact([ex["b"][j] for j in range(s)], [ex["c"][j] for j in range(s)], s)
    label = name or d.get("name") or "custom"
    # the entries as given, so that the audit decides at the precision they carry
    sources = {k: [list(r) if isinstance(r, list) else r for r in d[k]] for k in NAMES if k in d}
    digits = info["digits"] or None
    longs = [n for n in info.get("counts", ()) if n >= LONG_DECIMAL]
    kw = dict(family="custom", sources=sources, decimal_digits=digits, decimal_digits_min=min(longs) if longs else None)
    if all_exact:
        return _rank_checked(SparkTableau(str(label), s, exact=ex, **kw))
    # float64 entries carry ~15 digits; JSON numbers longer than a float64's writing their own
    pyfloat = any(isinstance(x, float) for v in sources.values() for x in _flatten(v))
    jd = info.get("json")
    digits_carried = jd if jd is not None and jd > FLOAT64_REPR_DIGITS and not pyfloat else 15
    return _rank_checked(SparkTableau(str(label), s, exact=ex, source_digits=digits_carried, **kw))


def _rank_checked(tab: SparkTableau) -> SparkTableau:
    """``tab`` when omega has rank s-1 at the precision its entries carry (``omega_rank``), else a
    TableauError: (21e) with (21f) would not determine the s multipliers."""
    if tab.s > 1:
        r = omega_rank(tab)
        if r["rank"] < tab.s - 1:
            sig = r["sigma"][tab.s - 2] if len(r["sigma"]) >= tab.s - 1 else 0.0
            raise TableauError(f"omega is singular (rank {r['rank']} < s-1 = {tab.s - 1}: its smallest singular "
                               f"value {sig:.2e} is within {r['bound']:.1e}, the uncertainty of the entries and "
                               f"of {r['dps']}-digit arithmetic): (21e) would not determine the multipliers")
    return tab


def _json_number(text: str):
    """``parse_float`` of the tableau loader: the text of a JSON number (JsonNumber); one that is
    not finite as a float64 (1e999) stays a float, refused by ``_parse_entry`` as before."""
    return JsonNumber(text) if math.isfinite(float(text)) else float(text)


def max_file_bytes(max_stages: int | None = None) -> int:
    """Largest tableau file read: 4000 bytes per coefficient slot (s^2 of them), at least 1 MiB."""
    s = MAX_STAGES if max_stages is None else max_stages
    check_stages(1, max_stages)          # max_stages itself in range before it sizes anything
    return max(2 ** 20, 4000 * s * s)


def load_tableau(path, max_stages: int | None = None) -> SparkTableau:
    """Read a tableau JSON file (the format of ``ldaspark audit``).

    Entries may be exact strings ("1/2", "sqrt(3)/6", parsed by a whitelist, never evaluated),
    decimal strings (their digits are recorded) or float64 numbers.

    Parameters
    ----------
    path : str or os.PathLike
        A regular file of at most ``max_file_bytes(max_stages)`` bytes (never /dev/zero, a
        FIFO or a directory).
    max_stages : int, optional
        Stage limit (default 20).

    Returns
    -------
    SparkTableau
        The tableau, with ``precision_kind`` telling what its entries carry.

    Raises
    ------
    TableauError
        Naming the problem (a missing entry, a wrong shape, an unparsable string).

    Examples
    --------
    >>> import json, os, tempfile, ldaspark
    >>> midpoint = {"name": "midpoint", "c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]],
    ...             "A_tilde": [["1/2"]], "b": ["1"], "b_hat": ["1"], "b_tilde": ["1"]}
    >>> path = os.path.join(tempfile.mkdtemp(), "midpoint.json")
    >>> with open(path, "w") as f:
    ...     json.dump(midpoint, f)
    >>> ldaspark.load_tableau(path).s
    1
    """
    import os
    if isinstance(path, bool) or not isinstance(path, (str, bytes, os.PathLike)) \
            or "\0" in (path if isinstance(path, str) else os.fsdecode(path)):
        raise TableauError(f"a tableau path must be a file name (str or os.PathLike, no NUL), got "
                           f"{type(path).__name__} {str(path)[:60]!r}")
    from .validate import read_regular
    limit = max_file_bytes(max_stages)
    try:
        # the one checked opener: a regular file of bounded size, checked again on the descriptor
        if not os.path.exists(path):
            raise FileNotFoundError(path)
        raw = read_regular(path, limit, "tableau file", TableauError)
        # a JSON number is a decimal text with its digits (JsonNumber): 0.1127016653792583 is known
        # to its 16 digits and half an ulp, a published 15-digit coefficient to its 15 digits
        d = json.loads(raw.decode("utf-8"), parse_float=_json_number)
    except FileNotFoundError:
        raise TableauError(f"tableau file {path} not found") from None
    except json.JSONDecodeError as exc:
        raise TableauError(f"tableau file {path} is not valid JSON: {exc.msg} at line {exc.lineno}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TableauError(f"cannot read tableau file {path}: {exc}") from None
    except ValueError as exc:       # e.g. an integer of more than 4300 digits
        why = ("an integer literal has too many digits" if "integer string conversion" in str(exc)
               else str(exc).splitlines()[0][:120])
        raise TableauError(f"tableau file {path} is not valid JSON: {why}") from None
    except RecursionError:
        raise TableauError(f"tableau file {path} is not valid JSON: nested too deeply") from None
    return from_json_dict(d, max_stages=max_stages)
