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

This module holds ``SparkTableau`` (the coefficients and their float64, mpf, exact-field and ball
views), ``TableauArrays`` and ``omega_rank`` (the rank of omega in (21e), decided at the precision
the entries carry). The entry language, its limits and the ball arithmetic are in
``ldaspark.core.numbers``; the JSON tableau file loader (``load_tableau``, ``from_json_dict``,
``check_stages``) in ``ldaspark.core.tableau_file``. The names that moved there keep their old
dotted names here (``__getattr__`` below, docs/changelog.md).
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass, field
from typing import Callable

import mpmath
import numpy as np
import sympy
from sympy import QQ

from .errors import InputError, TableauError
from .numbers import (FLOAT64_REPR_DIGITS, LONG_DECIMAL, JsonNumber, _BallEvaluator, _leaf_is_decimal_string,
                      decimal_info,
                      _leaf_is_float, _mpf_to_fmpq, _ordinal, _sympy_ball, parse_exact_string)



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
    decimal_places : int, optional
        The places of a file printed in fixed point (None: no sign of one).
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
    #: F, the decimal places of a file printed in fixed point (``numbers.fixed_places``; None when
    #: nothing shows a fixed-point writing): its literals have fewer digits than D at full length
    decimal_places: int | None = None
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        # constructed directly (it is exported), a tableau gets the checks of its readers: a
        # bool or text s, no coefficients, or coefficients of another shape are one TableauError
        from .validate import MAX_STAGES_CEILING
        if not isinstance(self.name, str) or not 0 < len(self.name) <= 500 or not self.name.isprintable():
            # a 100000-character name was "must be a non-empty string, got str": say which rule failed.
            # The name is printed (the CLI's line, the audit's heading, result files): a newline or
            # an escape sequence from a tableau file would forge lines there
            got = (f"a string of {len(self.name)} characters" if isinstance(self.name, str)
                   and not 0 < len(self.name) <= 500 else repr(self.name[:40]) if isinstance(self.name, str)
                   else type(self.name).__name__)
            raise TableauError(f"tableau name must be a non-empty printable string of at most 500 characters, "
                               f"got {got}")
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
            self._check_exact_values()

    def _check_exact_values(self) -> None:
        """Every exact entry a finite real number, as the file reader requires (``numbers._parse_entry``):
        given directly, 1/2 + I/10 was silently its real part (``_sympy_to_mp`` takes re() of a
        numerically complex value), nan and zoo NaN coefficients, oo and a Symbol a ValueError."""
        from .numbers import MAX_MAGNITUDE
        for k in NAMES:
            M = self.exact[k]
            for i in range(M.rows):
                for j in range(M.cols):
                    e = M[i, j]
                    ok = bool(getattr(e, "is_number", False)) and e.is_real is not False
                    if ok:
                        try:
                            val = complex(sympy.N(e, 30))
                        except (TypeError, ValueError, OverflowError):
                            ok = False
                        else:
                            # a real number written with I (casus irreducibilis) evaluates with a
                            # round-off imaginary part: the reader's bound
                            ok = (math.isfinite(val.real) and abs(val.imag) <= 1e-25 * (1 + abs(val.real))
                                  and abs(val.real) <= MAX_MAGNITUDE)
                    if not ok:
                        at = f"[{i}]" if k in VECTOR_NAMES else f"[{i}][{j}]"
                        shown = str(e) if len(str(e)) <= 40 else f"{str(e)[:37]}..."   # 10**308 is not 10**39
                        raise TableauError(f"{self.name}: exact[{k!r}]{at} = {shown} is not a finite real "
                                           f"number of modulus <= {MAX_MAGNITUDE:g}")

    def _built(self, dps: int) -> dict:
        """``builder(dps)``, checked as ``exact`` is in ``__post_init__``: a dict with every name of
        NAMES, vectors of s numbers (flat or s x 1), A, A_hat, A_tilde s x s, omega (s-1) x s, each
        entry a finite real number (an exported class: a builder of another shape was a numpy
        reshape ValueError, one returning NaN a NaN trajectory)."""
        raw = self.builder(dps)
        s = self.s
        if not isinstance(raw, dict) or set(NAMES) - set(raw):
            raise TableauError(f"{self.name}: builder(dps) must return a dict with the keys {', '.join(NAMES)}, "
                               f"got {type(raw).__name__}")
        for k in NAMES:
            v = raw[k]
            rows = s if k != "omega" else s - 1
            if k in VECTOR_NAMES:
                ok = isinstance(v, list) and len(v) == s and all(
                    not isinstance(x, list) or len(x) == 1 for x in v)
                leaves = [x[0] if isinstance(x, list) else x for x in v] if ok else []
            else:
                ok = isinstance(v, list) and len(v) == rows and all(isinstance(r, list) and len(r) == s for r in v)
                leaves = [x for r in v for x in r] if ok else []
            if not ok:
                want = f"a list of {s} numbers" if k in VECTOR_NAMES else f"a {rows} x {s} list of lists"
                raise TableauError(f"{self.name}: builder(dps)[{k!r}] must be {want}")
            for x in leaves:
                try:
                    good = not isinstance(x, (bool, str)) and mpmath.isfinite(mpmath.mpf(x))
                except (TypeError, ValueError):
                    good = False
                if not good:
                    raise TableauError(f"{self.name}: builder(dps)[{k!r}] has the entry {str(x)[:40]!r}, "
                                       "not a finite real number")
        return raw

    # --- numeric views ---------------------------------------------------------------
    def mp_entries(self, dps: int) -> dict:
        """Entries as nested lists of mpf, correct to ``dps`` digits (or to the input
        precision for tableaux read from floats)."""
        key = ("mp", dps)
        if key not in self._cache:
            if self.builder is not None:
                with mpmath.workdps(dps):
                    raw = self._built(dps)
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

    @property
    def has_float64_values(self) -> bool:
        """Some entry may be a float64 value (``_may_be_float64``): its array is then known only to
        the rounding of a float64 computation (``float_computation_ulps``). Not so a file of
        30-digit JSON numbers whose only short ones are terminating expansions (0.5, 1.0, 0.0)."""
        long_file = (self.decimal_digits or 0) > FLOAT64_REPR_DIGITS
        return self.sources is not None and any(
            _may_be_float64(x, long_file) for v in self.sources.values() for x in _flatten(v))

    @property
    def float_like_digits(self) -> bool:
        """Some decimal literal has LONG_DECIMAL to FLOAT64_REPR_DIGITS significant digits: it may be a
        float64's writing (repr, %.17g), so each literal of at most that many digits is also known only
        to half an ulp of float64 (``numbers.literal_radius``)."""
        return self.decimal_digits_min is not None and self.decimal_digits_min <= FLOAT64_REPR_DIGITS

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
        D, Dmin, F = self.decimal_digits, self.decimal_digits_min, self.decimal_places
        place = f" or the {_ordinal(F)} decimal place, the larger" if F is not None and F > 0 else ""
        if D and Dmin and Dmin < D:
            dec = (f"decimal literals with {Dmin} to {D} significant digits (one of {LONG_DECIMAL} or more "
                   f"digits known to half a unit in its last digit, a shorter one (a terminating expansion) "
                   f"to half a unit in the {_ordinal(D)} significant digit{place})")
        else:
            dec = (f"decimal literals with up to {D} significant digit{'s' if D != 1 else ''} (each taken as "
                   f"known to half a unit in its {_ordinal(D)} significant digit{place})") if D else ""
        if D and self.float_like_digits:
            dec += (f"; one of at most {FLOAT64_REPR_DIGITS} digits also to half an ulp of float64 (it may be a "
                    "float64's writing)")
        flt = "float64 entries (each known to half a unit in the last place, 2^-53 ~ 1.1e-16 relative)"
        if self.json_numbers and not D:
            # every JSON number is a zero ("0.0" beside exact strings): exact, no digits to quote
            flt = "JSON numbers that are all zeros (exact: a zero coefficient is zero by structure)"
        elif self.json_numbers:
            flt = (f"JSON numbers read as decimal texts with up to {D} significant digits (each known to half "
                   f"a unit in its last digit, a short one (a terminating expansion) in the {_ordinal(D)}, and "
                   f"one of at most {FLOAT64_REPR_DIGITS} digits also to half an ulp of float64, 2^-53 ~ 1.1e-16 "
                   "relative: it may be a float64's shortest writing)")
        if self.has_float64_values and (D or not self.json_numbers):
            flt += (f"; a float64 value also to {self.float_computation_ulps():.3g} ulps of its array's largest "
                    "entry, cond(V) of the nodes' Vandermonde matrix: the rounding a float64 computation of the "
                    "coefficients leaves, which is not correct rounding")
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
                    ev = _BallEvaluator(self.decimal_digits, self.decimal_places, self.float_like_digits)
                    out = {k: _map_nested(v, ev.leaf) for k, v in self.sources.items()}
                    ulps = self.float_computation_ulps() if self.has_float64_values else 0.0
                    if ulps > 0:
                        # omega is chosen, not computed by the solves of the coefficients: half an ulp
                        long_file = (self.decimal_digits or 0) > FLOAT64_REPR_DIGITS
                        for k in [k for k in self.sources if k != "omega"]:
                            out[k] = _widen_floats(out[k], self.sources[k], ulps, long_file)
                    if "omega" not in out:
                        out["omega"] = [[_sympy_ball(self.exact["omega"][i, j], digits, None)
                                         for j in range(self.s)] for i in range(self.s - 1)]
                elif self.exact is not None:
                    src = None if self.is_exact else (self.source_digits or 15)
                    out = {k: _matrix_to_json(M, k, lambda e: _sympy_ball(e, digits, src))
                           for k, M in self.exact.items()}
                else:
                    with mpmath.workdps(digits + 10):
                        raw = self._built(digits + 10)
                    rad = flint.arb(10) ** (-digits + 5)
                    ball = lambda x: flint.arb(_mpf_to_fmpq(x)) + flint.arb(0, rad * max(1, abs(float(x))))
                    out = {k: _map_nested(v, ball) for k, v in raw.items()}
                    for k in VECTOR_NAMES:
                        out[k] = [x[0] if isinstance(x, list) else x for x in out[k]]
            self._cache[key] = out
        return self._cache[key]

    def float_computation_ulps(self) -> float:
        """How far a float64 entry may miss the coefficient it stands for, in ulps of the largest
        entry of its array: a float64 tableau is computed (nodes from eigenvalues or Newton, A and
        b from s x s solves with the Vandermonde matrix V of the nodes c), not rounded from the
        true values, and such a computation leaves errors of up to ~cond(V) ulps, normwise
        (measured: numpy's Gauss s = 2..8, leggauss and a Vandermonde solve, 0.3 / 6.5 / 26 / 252
        / 800 / 2482 / 13952 ulps of max |A| against cond_inf(V) = 6 / 36 / 280 / 1.9e3 / 1.1e4 /
        7.3e4 / 4.8e5); taken as cond_inf(V) of the distinct nodes (at least 1). Half an ulp
        (correct rounding) judged a float64 Gauss-3 computed by numpy to violate (22b) by 8e-17,
        Theorem 1 to fail, and the method not to be symmetric."""
        key = ("float-ulps",)
        if key not in self._cache:
            c = _one_per_node(np.asarray(self.arrays(None).c, dtype=float).ravel())
            V = np.vander(np.array(c), len(c), increasing=True)
            with np.errstate(all="ignore"):
                cond = float(np.linalg.cond(V, np.inf)) if len(c) > 1 else 1.0
            self._cache[key] = max(1.0, cond) if math.isfinite(cond) else 1.0 / np.finfo(float).eps
        return self._cache[key]

    def _check_entry_change(self, name, i, j, delta) -> None:
        """``with_entry``'s arguments: a coefficient of the tableau, indices in its range (no
        negative ones: they would silently wrap to the last entry), a finite real delta."""
        from . import validate
        ent = self.exact if self.exact is not None else (self._built(16) if self.builder is not None else None)
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
        # one sympy number for both kinds of tableau, read before anything is built (a computed
        # tableau added mpmath.mpf(delta) in its builder: "sqrt(2)/1000", a Fraction or a NumPy
        # scalar were accepted here and raised ValueError / TypeError at the first arrays())
        if isinstance(delta, str):              # text is parsed (bounded), never nsimplify'd or evaluated
            d = parse_exact_string(delta, f"delta of {name}")
        else:
            d = sympy.nsimplify(delta)
        if self.exact is not None:
            ex = {k: sympy.Matrix(v) for k, v in self.exact.items()}
            if j is None:
                ex[name][i, 0] += d
            else:
                ex[name][i, j] += d
            src = None
            if self.sources is not None:
                src = {k: [list(r) if isinstance(r, list) else r for r in v] for k, v in self.sources.items()}
                if j is None:
                    src[name][i] = (src[name][i], d)
                else:
                    src[name][i][j] = (src[name][i][j], d)
            return SparkTableau(f"{self.name}+d{name}[{i},{j}]", self.s, exact=ex,
                                source_digits=self.source_digits, claimed_order=None, family="perturbed",
                                sources=src, decimal_digits=self.decimal_digits,
                                decimal_digits_min=self.decimal_digits_min, decimal_places=self.decimal_places)
        return SparkTableau(f"{self.name}+d{name}[{i},{j}]", self.s, builder=_PerturbedBuilder(self.builder, name, i, j, d),
                            source_digits=self.source_digits, family="perturbed")

    # --- JSON ----------------------------------------------------------------------
    def to_json_dict(self, dps: int = 40) -> dict:
        """Entries as exact strings when exact, else decimal strings with ``dps`` significant
        digits each (trailing zeros kept: a reader takes a literal as known to the digits it
        shows), ``dps`` an integer in 1..DPS_MAX."""
        from . import validate
        dps = validate.count(dps, "dps", 1, validate.DPS_MAX)
        out = {"name": self.name}
        if self.exact is not None:
            for k, M in self.exact.items():
                out[k] = _matrix_to_json(M, k, str)
        else:
            # every literal with dps significant digits (trailing zeros kept): a reader takes a
            # literal as known to its digits (numbers.literal_radius), and "0.5" for a computed 1/2
            # read back as known to +-0.05; computed 10 digits beyond, so that the written digits
            # are the correctly rounded ones (half a unit in the last), not a double rounding
            ent = self.mp_entries(dps + 10)
            with mpmath.workdps(dps + 10):
                for k, v in ent.items():
                    out[k] = _map_nested(v, lambda x: mpmath.nstr(x, dps, strip_zeros=False))
        return out

    def save(self, path, dps: int = 40) -> None:
        from .io import atomic_write_json
        atomic_write_json(path, self.to_json_dict(dps))


class _PerturbedBuilder:
    """The builder of ``with_entry`` on a computed tableau: the source's entries with ``d`` (a sympy
    number) added to entry (i, j) of ``name`` at the digits asked for. A module-level class, not a
    closure, so that the tableau pickles into the worker processes of an ensemble (as
    ``families._FamilyBuilder``; a closure was "Can't pickle local object")."""

    def __init__(self, base, name, i, j, d):
        self.base, self.name, self.i, self.j, self.d = base, name, i, j, d

    def __call__(self, dps):
        base, name, i, j = self.base, self.name, self.i, self.j
        ent = {k: [list(r) if isinstance(r, list) else r for r in v] for k, v in base(dps).items()}
        dm = _sympy_to_mp(sympy.Matrix([[self.d]]), dps)[0][0]      # d at the builder's digits
        if j is None:
            x = ent[name][i]
            ent[name][i] = [x[0] + dm] if isinstance(x, list) else x + dm      # a vector flat or s x 1
        else:
            ent[name][i][j] = ent[name][i][j] + dm
        return ent


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


def _one_per_node(c) -> list:
    """The distinct nodes of ``c`` (sorted), nodes within 2^-40 relative counted once: a node a
    float64 computation returns twice with different last bits (Tsit5's FSAL 1.0 and
    0.9999999999999998) is one node; as two, cond(V) was 5.3e17 and every float64 entry was known
    to ~1e2 only. Two distinct nodes that close would make cond(V) > 1e12, beyond what float64
    entries carry."""
    out = []
    for x in sorted(float(v) for v in c):
        if not out or abs(x - out[-1]) > 2.0 ** -40 * max(1.0, abs(x)):
            out.append(x)
    return out


def _widen_floats(balls, src, ulps, long_file: bool = False):
    """``balls`` (an array's entries, nested as ``src``) with ``ulps`` * 2^-53 * (the largest
    midpoint of the array) added to the radius of every entry that ``src`` gives as a float64
    (``SparkTableau.float_computation_ulps``; ``long_file``: see ``_may_be_float64``)."""
    import flint

    def mids(v):
        return [m for x in v for m in mids(x)] if isinstance(v, list) else [abs(float(v.mid()))]
    scale = max(mids(balls), default=0.0)
    rad = flint.arb(ulps) * flint.arb(2) ** -53 * flint.arb(scale)

    def walk(b, x):
        if isinstance(b, list):
            return [walk(bi, xi) for bi, xi in zip(b, x if isinstance(x, list) else [x] * len(b))]
        return b + flint.arb(0, rad) if _may_be_float64(x, long_file) else b
    return walk(balls, src)


def _may_be_float64(x, long_file: bool = False) -> bool:
    """A float entry, or a JSON number short enough to be a float64's writing (at most
    FLOAT64_REPR_DIGITS significant digits; a longer one was not computed in float64). In a
    ``long_file`` (a literal of more than FLOAT64_REPR_DIGITS digits) a JSON number of fewer than
    LONG_DECIMAL digits (0.5, 1.0, 0.0 beside 30-digit ones) is a terminating expansion, known to
    the file's digits as ``numbers.literal_radius`` reads it: as a float64 value its zeros were
    +- 2.2e-15 and a_hat_13 = 1e-20 in Lobatto IIIB passed (22b)."""
    while isinstance(x, tuple):
        x = x[0]
    if isinstance(x, float):
        return True
    if not isinstance(x, JsonNumber):
        return False
    sig = decimal_info(x.strip().lstrip("+-"))[1]
    return sig <= FLOAT64_REPR_DIGITS and not (long_file and sig < LONG_DECIMAL)


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
    s = tab.s
    D = max(tab.decimal_digits or 0, tab.source_digits or 0)
    w = dps or max(60, D + 30, 3 * s + 30)
    ent = tab.mp_entries(w)
    digits = max(D + 20, 40)
    balls = tab.ball_entries(digits)
    given = tab.sources is not None and "omega" in tab.sources
    if tab.sources is not None and not given:
        obs = _default_omega_balls(balls, s, digits)
    else:
        obs = balls["omega"]
    rad = _frobenius_radius(tab, obs)
    with mpmath.workdps(w):
        rows = [list(r) for r in ent["omega"]] + [list(r) for r in (extra_rows or [])]
        sv = mpmath.svd_r(mpmath.matrix(rows), compute_uv=False) if rows else []
        sig = sorted((float(x) for x in sv), reverse=True)
    smax = sig[0] if sig else 0.0
    bound = rad + s * s * 10.0 ** (5 - w) * max(smax, 1e-300)
    return {"rank": sum(x > bound for x in sig), "sigma": sig, "bound": bound, "dps": w,
            "radius": rad}


def _default_omega_balls(balls, s: int, digits: int) -> list:
    """The rows b_j c_j^(i-1), i < s, as arb balls from the balls of b and c (``ball_entries``)."""
    import flint
    with flint.ctx.workprec(int(digits * 3.33) + 16):
        bv, cv = balls["b"], balls["c"]
        # b_j c_j^i by repeated products: arb's ** is NaN on a ball containing 0 ("0.0000000")
        obs, row = [], list(bv)
        for i in range(s - 1):
            obs.append(row)
            row = [row[j] * cv[j] for j in range(s)]
    return obs


def _frobenius_radius(tab, rows) -> float:
    """||Delta||_F of the balls ``rows``, 0 when the entries stand for themselves (exact, or a
    built-in computed to any precision)."""
    if tab.known_exactly or tab.exact is None:
        return 0.0
    # by hypot: the squares of radii of entries up to MAX_MAGNITUDE overflow
    return math.hypot(*(float(x.rad()) for r in rows for x in r))


def default_rows_radius(tab) -> float:
    """||Delta||_F of the rows b_j c_j^(i-1), i < s, made from the entries b and c as the file
    gives them (what ``check_omega_default`` stacks under omega)."""
    D = max(tab.decimal_digits or 0, tab.source_digits or 0)
    digits = max(D + 20, 40)
    if tab.sources is None:
        return 0.0
    return _frobenius_radius(tab, _default_omega_balls(tab.ball_entries(digits), tab.s, digits))


def _default_omega_exact(b, c, s):
    return sympy.Matrix(max(s - 1, 0), s, lambda i, j: b[j] * c[j] ** i)


def _col(vals):
    return sympy.Matrix(len(vals), 1, list(vals))


#: the names that moved out of this module in round 5 (issue 46) -> their module now, looked up on
#: first use (PEP 562) so that ``from ldaspark.core.tableau import load_tableau`` keeps working for
#: code outside the package. The package and its tests import them from their new modules
#: (tests/core/test_tableau_reexports.py): ``tableau_file`` imports this module, so reaching it from
#: here is a lazy circle, kept for old callers only.
_MOVED = dict.fromkeys(("MAX_MAGNITUDE", "MAX_STAGES", "decimal_info", "decimal_radius", "parse_expression",
                        "parse_number", "_parse_entry"), ".numbers")
_MOVED.update(dict.fromkeys(("check_stages", "from_json_dict", "load_tableau", "max_file_bytes", "_json_number"),
                            ".tableau_file"))


def __getattr__(name: str):
    module = _MOVED.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    # the module's name from the table, as the package facade's lazy names (ldaspark.__getattr__)
    return getattr(importlib.import_module(module, __package__), name)
