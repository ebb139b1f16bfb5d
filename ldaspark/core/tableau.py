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


def parse_exact_string(x: str, where: str = "entry"):
    """An exact tableau entry such as "1/4 - sqrt(3)/6" as a sympy number.

    Parsed with Python's ``ast`` and built node by node (never evaluated as Python): numbers
    (decimals read as exact decimals), + - * /, ** with a literal integer exponent, sqrt,
    Rational, sin, cos and pi. Bounded so that no entry can hang or exhaust memory: at most
    200 characters, tree depth 32, the product of nested '**' exponents at most 64, scientific
    exponents |e| <= 400, intermediate rationals of at most 8192 bits, |x| <= 1e6 inside sin/cos.
    Anything else is a TableauError naming the entry."""
    import ast
    if not isinstance(x, str):
        raise TableauError(f"{where}: expected a string, got {type(x).__name__}")
    if len(x) > _MAX_ENTRY_LEN:
        raise TableauError(f"{where}: expression longer than {_MAX_ENTRY_LEN} characters")
    src = x.strip()
    try:
        tree = ast.parse(src, mode="eval")
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        raise TableauError(f"{where}: cannot parse {x!r}") from None
    b = _EntryBuilder(x, src, where)
    e = b.build(tree.body, 0, 1)
    if not getattr(e, "is_number", False):
        raise b.bad("not a number")
    return e


class _EntryBuilder:
    """Builds the sympy number of one entry from its AST, enforcing the bounds as it goes.
    ``power`` is the product of the exponents of the '**' nodes above the current node."""

    def __init__(self, x, src, where):
        self.x, self.src, self.where = x, src, where

    def bad(self, why):
        return TableauError(f"{self.where}: {self.x!r} is not a number ({why})")

    def build(self, node, depth, power):
        import ast
        if depth > _MAX_DEPTH:
            raise self.bad(f"nested deeper than {_MAX_DEPTH} levels")
        if isinstance(node, ast.Constant):
            return self.constant(node, power)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
            v = self.build(node.operand, depth + 1, power)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.BinOp):
            if isinstance(node.op, ast.Pow):
                return self.pow(node, depth, power)
            return self.binop(node, depth, power)
        if isinstance(node, ast.Name) and node.id in _CONSTANTS:
            return _CONSTANTS[node.id]
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _FUNCTIONS
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
        if _bits(e) * power > _MAX_BITS:
            raise self.bad(f"a power of it exceeds {_MAX_BITS} bits")
        return e

    def pow(self, node, depth, power):
        import ast
        ex = node.right
        neg = isinstance(ex, ast.UnaryOp) and isinstance(ex.op, ast.USub)
        lit = ex.operand if neg else ex
        if not (isinstance(lit, ast.Constant) and type(lit.value) is int and lit.value <= _MAX_EXPONENT):
            raise self.bad(f"'**' needs a literal integer exponent <= {_MAX_EXPONENT}")
        if lit.value * power > _MAX_EXPONENT:
            raise self.bad(f"nested '**' with exponents multiplying to more than {_MAX_EXPONENT}")
        base = self.build(node.left, depth + 1, power * max(lit.value, 1))
        if neg and base == 0:
            raise self.bad("division by zero")
        r = base ** (-lit.value if neg else lit.value)
        if _bits(r) > _MAX_BITS:
            raise self.bad(f"a power exceeds {_MAX_BITS} bits")
        return r

    def binop(self, node, depth, power):
        import ast
        ops = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
               ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b}
        f = ops.get(type(node.op))
        if f is None:
            raise self.bad(f"operator {type(node.op).__name__}")
        a, b = self.build(node.left, depth + 1, power), self.build(node.right, depth + 1, power)
        if isinstance(node.op, ast.Div) and b == 0:
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
            raise self.bad(f"argument of {fname} is not a real number of modulus <= {_MAX_TRIG_ARG:g}")
        return _FUNCTIONS[fname](*args)


def _small(e, bound) -> bool:
    """|e| <= bound for a real number e (numerically, at 15 digits: e is already size-bounded)."""
    try:
        val = complex(sympy.N(e, 15))
    except (TypeError, ValueError, OverflowError):
        return False
    return val.imag == 0 and abs(val.real) <= bound


def _parse_entry(x, where):
    """An entry: int (exact), string (exact expression, decimals read as exact decimals) or
    float (approximate, 53 bits). Returns (sympy number, is_exact)."""
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
        e = parse_exact_string(x, where)
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
    if isinstance(limit, bool) or not isinstance(limit, int) or not 1 <= limit <= MAX_STAGES_CEILING:
        # --max-stages 10**6 was a MemoryError, 10**8 an OverflowError (issue 25, H)
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


def max_file_bytes(max_stages: int | None = None) -> int:
    """Largest tableau file read: 4000 bytes per coefficient slot (s^2 of them), at least 1 MiB."""
    s = MAX_STAGES if max_stages is None else max_stages
    check_stages(1, max_stages)          # max_stages itself in range before it sizes anything
    return max(2 ** 20, 4000 * s * s)


def load_tableau(path, max_stages: int | None = None) -> SparkTableau:
    """Read a tableau JSON file; errors name the problem (TableauError). Only regular files of at
    most ``max_file_bytes(max_stages)`` bytes are read (never /dev/zero, a FIFO or a directory)."""
    import os
    import stat
    limit = max_file_bytes(max_stages)
    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode):
            raise TableauError(f"tableau file {path} is not a regular file")
        if st.st_size > limit:
            raise TableauError(f"tableau file {path} has {st.st_size} bytes, more than {limit}")
        with open(path, "rb") as f:
            raw = f.read(limit + 1)
        if len(raw) > limit:
            raise TableauError(f"tableau file {path} has more than {limit} bytes")
        d = json.loads(raw.decode("utf-8"))
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
