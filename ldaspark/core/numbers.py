"""The numbers of a SPARK tableau: the entry language of the coefficients of (21), its limits,
and the ball (interval) arithmetic that encloses what an entry stands for.

The lower layer of the tableau modules (``tableau`` and ``tableau_file`` import it, it imports
neither):

* the entry language: an entry of c, A, A_hat, A_tilde, b, b_hat, b_tilde (21a-d) or omega (21e)
  is an integer (exact), a string parsed by a bounded whitelist (``parse_exact_string``: rationals,
  radicals, sin/cos/pi; decimal texts read as exact decimals, their digits recorded), a float64
  or a JSON number kept as its decimal text (``JsonNumber``); ``_parse_entry`` reads one entry,
  ``parse_number`` / ``parse_expression`` are the same parser for the strings of the Python API
  (L, k and parameter values of (1)), never sympify or eval;
* the limits that keep parsing a hostile entry fast and memory-bounded (length, depth, exponents,
  bits, ``MAX_MAGNITUDE``, ``MAX_STAGES``);
* ball arithmetic (python-flint arb/acb): a decimal literal known to half a unit in its last given
  digit (``decimal_info``, ``decimal_radius``, ``LONG_DECIMAL``), a float64 to half an ulp
  (``_float_ball``), a file entry walked from its AST (``_BallEvaluator``), an exact sympy entry
  (``_sympy_ball``): the enclosures with which the audit decides (22), (23) and the rank of omega
  in (21e) at the precision the entries carry (``SparkTableau.ball_entries``, ``omega_rank``).
"""
from __future__ import annotations

import math

import mpmath
import sympy

from .errors import TableauError


# --- entries as a file gives them: float64 leaves, decimal texts, JSON numbers ---------------
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


# --- ball (interval) arithmetic: what an entry stands for ------------------------------------
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
#: last digit; so is one as long as the tableau's longest writing (its D significant digits, or its F
#: decimal places: "0.0416667" in a file printed to 7 places). A shorter one may be a terminating
#: expansion ("0.5", "0.25": printing to D digits or F places drops trailing zeros): known to half a
#: unit in the D-th significant digit or the F-th place, whichever is larger (``literal_radius``)
LONG_DECIMAL = 8


def decimal_places(text: str) -> int:
    """Decimal places of a decimal literal ('0.0416667' 7, '2.5e-1' 2, '1.5e3' -2, '0.0' 1)."""
    from decimal import Decimal
    return -Decimal(text.replace("_", "")).as_tuple().exponent


def _kept_trailing_zero(text: str) -> bool:
    """A literal of 2 or more decimal places ending in 0 ("0.50", "1.0000000"): a shortest or %g
    writer drops such zeros (repr and mpmath.nstr keep one, "1.0"), a fixed-point one keeps them."""
    mant = text.lower().split("e")[0].replace("_", "")
    return "." in mant and len(mant.split(".")[1]) >= 2 and mant.endswith("0")


def fixed_places(shapes) -> int | None:
    """F, the decimal places of a file printed in fixed point, from the (places, significant
    digits, trailing zero kept) of its nonzero literals, or None when nothing shows a fixed-point
    writing: a kept trailing zero, or two literals of the file's most places (at least 2) with
    different numbers of significant digits ("0.2083333" and "0.0416667": a %g writer gives both
    the same count)."""
    shapes = list(shapes)
    if not shapes:
        return None
    F = max(p for p, _, _ in shapes)
    if any(z for _, _, z in shapes):
        return F
    if F >= 2 and len({sig for p, sig, _ in shapes if p == F}) > 1:
        return F
    return None


def _half_place(places: int):
    """Half a unit in the ``places``-th decimal place, 0.5 * 10^-places, as an exact fmpq."""
    import flint
    return flint.fmpq(5, 10 ** (places + 1)) if places >= -1 else flint.fmpq(5 * 10 ** (-places - 1))


def literal_radius(text: str, digits: int, places: int | None, float_like: bool, json: bool = False):
    """The radius (an exact fmpq) of the ball of what a decimal literal of a tableau file stands for,
    in a file whose longest literal has ``digits`` (D) significant digits and that, where it shows a
    fixed-point writing (``fixed_places``), was printed to ``places`` (F) decimal places (None: no
    such sign). The writer rounded to significant digits (D, trailing zeros dropped) or to places
    (F); so:

    * a literal with LONG_DECIMAL or more digits, or with D digits, or with F places, was rounded at
      its own last digit: half a unit there;
    * every literal is also known at least to half a unit in the D-th significant digit and, in a
      fixed-point file, in the F-th place (a shorter one is a terminating expansion): the larger;
    * a zero ("0.0", "0.0000000") is exact: tableau coefficients are zero by structure (the
      explicit first row of Lobatto IIIA, the last column of IIIB), a true value below half a unit
      in the last place printed as zero is not met in practice, and a zero known only to +- 0.05 in
      a file of one-digit literals ("0.0", "0.5", "1.0") lets order conditions that fail by 1/12
      "hold";
    * plus half an ulp of float64 (2^-53 |x|) for a literal of at most FLOAT64_REPR_DIGITS digits
      when it may be a float64's writing (repr or %.17g: the float nearest the intended value,
      printed): when the file holds a literal of LONG_DECIMAL..FLOAT64_REPR_DIGITS digits
      (``float_like``), or, for a JSON number, when no literal is longer than a float64's writing."""
    import flint
    val, sig, adj = decimal_info(text.lstrip("+-"))
    pl = decimal_places(text.lstrip("+-"))
    if sig == 0:
        return flint.fmpq(0)
    r = decimal_radius(adj, max(digits, sig))           # the D-digit reading
    full = sig >= LONG_DECIMAL or sig >= digits
    if places is not None:                              # the file shows a fixed-point writing
        r = max(r, _half_place(places))
        full = full or pl >= places
    if full:
        r = max(r, decimal_radius(adj, sig))
    if sig <= FLOAT64_REPR_DIGITS and (float_like or (json and digits <= FLOAT64_REPR_DIGITS)):
        # 2^-53 |x| rounded up to a rational with a power-of-two denominator: exact, no arb needed
        r = r + abs(val) / flint.fmpq(2 ** 53)
    return r


class _BallEvaluator:
    """Encloses a tableau entry as the file gave it in an arb ball (at flint's current
    precision). String entries are walked from their AST once more (they were validated by
    ``parse_exact_string`` when the file was loaded; nothing is evaluated as Python), in complex
    ball arithmetic (acb) so that sqrt of a negative intermediate follows sympy's principal branch;
    the entry is real (checked at load), its real part is returned."""

    def __init__(self, digits_given: int | None, places: int | None = None, float_like: bool = False):
        self.D, self.F, self.float_like = digits_given, places, float_like
        self.json = False

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
        # a JSON number: the decimal text to its digits, as a string entry, and half an ulp on top
        # where it may be a float64's writing (``literal_radius``)
        self.json = isinstance(x, JsonNumber)
        try:
            return self.node(ast.parse(src, mode="eval").body, src).real
        finally:
            self.json = False

    def node(self, n, src):
        import ast
        import flint
        acb = flint.acb
        if isinstance(n, ast.Constant):
            if isinstance(n.value, int):
                return acb(n.value)
            text = ast.get_source_segment(src, n) or repr(n.value)
            val = decimal_info(text)[0]          # its radius: literal_radius
            ball = flint.arb(val)
            if self.D is not None:
                rad = literal_radius(text, self.D, self.F, self.float_like, self.json)
                ball = ball + flint.arb(0, flint.arb(rad))
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


# --- the entry language: its limits and its parser ----------------------------------------
# Every bound below keeps parsing a hostile file fast (each entry well under a millisecond to a
# few milliseconds) and memory-bounded; each violation is one TableauError line.
_MAX_ENTRY_LEN = 200          # characters of one string entry
_MAX_EXPONENT = 64            # product of the literal exponents of nested '**'
_MAX_SCI_EXPONENT = 400       # |e| of scientific notation 1.5e-30 (float64 spans 1e-324 .. 1e308)
_MAX_DEPTH = 32               # depth of the expression tree
# sympy's construction of nested sin/cos grows faster than linearly with the nesting (its assumption
# queries recurse): sin(sin(...)) 30 deep took ~0.1 s an entry, minutes for a file of s = 20. Published
# coefficients nest radicals two or three deep (sqrt(245 - 14*sqrt(70))) and use a few of them
# (the shipped gauss2-ten-radicals.json: 10 in one entry)
_MAX_CALL_DEPTH = 4           # sqrt/sin/cos/Rational nested in one another
_MAX_CALLS = 16               # sqrt/sin/cos/Rational calls in one entry
_MAX_BITS = 8192              # numerator / denominator of an intermediate rational
_MAX_TRIG_ARG = 1e6           # |x| in sin(x), cos(x)
MAX_MAGNITUDE = 1e300         # |entry|: every entry converts to a finite float64
MAX_STAGES = 20               # s, unless raised (max_stages=, --max-stages)
_FUNCTIONS = {"sqrt": sympy.sqrt, "Rational": sympy.Rational, "cos": sympy.cos, "sin": sympy.sin}
_CONSTANTS = {"pi": sympy.pi}
# expressions of the Python API (parse_expression): more functions, longer and deeper text
_MAX_EXPR_LEN = 4000
_MAX_EXPR_DEPTH = 64
# sympy builds nested hyperbolic functions at a cost growing 3-5x per level (tanh(sin(...)) 7
# pairs deep: 153 s, tanh 10 deep: 63 s); 6 deep: tanh^6 0.3 s (models nest 2 or 3: sqrt(1 - sin(q)**2))
_MAX_EXPR_CALL_DEPTH = 6
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
    exponents |e| <= 400, intermediate rationals of at most 8192 bits, |x| <= 1e6 inside sin/cos,
    at most 16 calls of sqrt, sin, cos, Rational, nested at most 4 deep. Anything else is a TableauError naming the entry, and so is a denominator (or the base of a
    negative power) that is zero, also when sympy does not reduce it (``sin(1)**2 + cos(1)**2 - 1``):
    it is tested in ball arithmetic at 256, then 12000 bits. ``info``, when given, receives ``digits``: the
    largest number of significant digits of a decimal literal in the entry (0 if none)."""
    src, tree = _parse_source(x, where, _MAX_ENTRY_LEN, TableauError, repr)
    b = _EntryBuilder(x, src, where)
    e = b.build(tree.body, 0, 1)
    if not getattr(e, "is_number", False):
        raise b.bad("not a number")
    if info is not None:
        info["digits"] = max(info.get("digits", 0), b.digits)
        if b.places > -10 ** 6:
            info["places"] = max(info.get("places", b.places), b.places)
        info.setdefault("shapes", set()).update(b.shapes)
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
        self.places = -10 ** 6  # most decimal places of a decimal literal seen (zeros too)
        self.calls = self.call_depth = 0    # function calls so far, and nested around the current node
        self.shapes = set()     # (places, significant digits, trailing zero kept) of nonzero literals

    def zero(self, value, node) -> bool:
        """Whether a (validated) denominator is zero: exactly for a rational, else by its ball at
        _ZERO_TEST_BITS bits (decimals read as exact), which contains 0 for every exact zero."""
        if value == 0:
            return True
        if getattr(value, "is_Rational", False):
            return False
        import flint
        # 256 bits first: a ball that excludes 0 there settles a nonzero denominator (nearly every
        # one) without the 12000-bit evaluation
        for bits in (256, _ZERO_TEST_BITS):
            with flint.ctx.workprec(bits):
                z = _BallEvaluator(None).node(node, self.src)
                if not (z.real.contains(0) and z.imag.contains(0)):
                    return False
        return True

    def divides_by_zero(self, value, node) -> bool:
        """Whether ``value`` (the sympy value of ``node``) is a zero denominator or the zero base of
        a negative power. A symbolic value (an expression in the declared names) is zero only when
        it is the number 0, as sympy builds it ((x - x) is 0); the ball evaluator knows numbers
        only and read every name as pi, so (x - y)**-1 and sin(x)**-1 were 'zero'. A number is
        tested by ``zero`` (in ball arithmetic) when its text is in the entry language, which
        that evaluator knows (pi, sqrt, sin, cos, Rational, integer powers); else (E, exp, log,
        p/q powers of an expression) by sympy's own zero test."""
        if not getattr(value, "is_number", False):
            return value == 0
        if self.symbolic and not _entry_language(node):
            return value == 0 or value.is_zero is True
        return self.zero(value, node)

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
            pl = decimal_places(text)
            self.places = max(self.places, pl)
            if e != 0:
                sig = decimal_info(text)[1]
                self.digits = max(self.digits, sig)
                self.counts.add(sig)
                self.shapes.add((pl, sig, _kept_trailing_zero(text)))
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
        if neg and lit.value != 0 and self.divides_by_zero(base, node.left):
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
                if isinstance(nd.op, ast.Div) and self.divides_by_zero(b, nd.right):
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
        if not self.symbolic:
            self.calls += 1
            if self.calls > _MAX_CALLS:
                raise self.bad(f"more than {_MAX_CALLS} function calls")
        self.call_depth += 1
        limit = _MAX_EXPR_CALL_DEPTH if self.symbolic else _MAX_CALL_DEPTH
        if self.call_depth > limit:
            raise self.bad(f"function calls nested deeper than {limit}")
        try:
            args = [self.build(a, depth + 1, power) for a in node.args]
        finally:
            self.call_depth -= 1
        if fname == "Rational":
            if not all(a.is_Integer for a in args) or (len(args) == 2 and args[1] == 0):
                raise self.bad("Rational needs integer arguments and a nonzero denominator")
        elif len(args) != 1:
            raise self.bad(f"{fname} takes one argument")
        elif ((fname in ("sin", "cos") or self.symbolic) and (not self.symbolic or args[0].is_number)
              and not _small(args[0], _MAX_TRIG_ARG)):
            # only a numeric argument is bounded (every one of an entry, sin/cos of a symbol-free one
            # in an expression); sympy.N of a symbolic one costs 2.3x per level of nesting
            # (sin(sin(...(x))) 12 deep: 51 s) and bounds nothing
            raise self.bad(f"argument of {fname} is not a real number of modulus <= {_MAX_TRIG_ARG:g}")
        return (_SYMBOLIC_FUNCTIONS if self.symbolic else _FUNCTIONS)[fname](*args)


def _entry_language(node) -> bool:
    """Whether the syntax tree ``node`` uses only what ``_BallEvaluator`` evaluates: numbers, pi,
    + - * /, integer powers and the functions of ``_FUNCTIONS``."""
    import ast
    for n in ast.walk(node):
        if isinstance(n, ast.Call):
            if not (isinstance(n.func, ast.Name) and n.func.id in _FUNCTIONS):
                return False
        elif isinstance(n, ast.Name):
            if n.id not in _CONSTANTS and n.id not in _FUNCTIONS:
                return False            # a function's own name is checked at its call
        elif isinstance(n, ast.BinOp) and isinstance(n.op, ast.Pow):
            ex = n.right.operand if isinstance(n.right, ast.UnaryOp) else n.right
            if not (isinstance(ex, ast.Constant) and type(ex.value) is int):
                return False
    return True


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
    a + b + c ... counts as one level), function calls nested at most 6 deep, rational
    coefficients of at most 8192 bits, numeric
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
            # the bound of every entry, checked here on the text written: past it, 1e308 reached the
            # tableau's check, which printed it as its first 40 digits (10^39)
            if abs(e) > sympy.Integer(10) ** 300:
                raise TableauError(f"{where}: {x.strip()} exceeds {MAX_MAGNITUDE:g} in modulus")
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
