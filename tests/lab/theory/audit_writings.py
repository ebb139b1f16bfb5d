"""One method written the ways its users write it (tests of ``ldaspark audit``): exact strings,
float64 JSON numbers, 17- and 40-digit decimal strings; as an RK embedding (A = A_hat = A_tilde) or
paired with its adjoint (A_hat from (22b): a_hat_ji = b_i (b_j - a_ij) / b_j)."""
import json
from decimal import Decimal

import mpmath
import sympy

from ldaspark.core.families import get_method

WRITINGS = ("exact", "float64", "17", "40")
# besides: "15json" (JSON numbers of 15 digits), any other integer string (decimal strings of that many
# digits), "fN" (strings printed to N decimal places, fixed point: "0.0416667" for f7), "repr" (a float64's
# repr as a string), "g17" ("%.17g" of the float64 as a string), "mixed30" (30-digit JSON numbers, with
# A_hat and A_tilde as float64 JSON numbers), "json30" (every entry a 30-digit JSON number)


def builtin(name):
    """(c, A, b, A_hat, A_tilde) of a built-in as sympy numbers (exact)."""
    t = get_method(name, exact=True)
    E = t.exact
    s = t.s
    vec = lambda k: [E[k][i, 0] for i in range(s)]
    mat = lambda k: [[E[k][i, j] for j in range(s)] for i in range(s)]
    return vec("c"), mat("A"), vec("b"), mat("A_hat"), mat("A_tilde")


def nodepy_method(m):
    """(c, A, b) of a nodepy method as sympy numbers (nodepy's floats stay floats)."""
    conv = lambda x: x if isinstance(x, float) else sympy.nsimplify(x) if isinstance(x, (int, float)) else sympy.sympify(x)
    A = [[conv(x) for x in r] for r in m.A]
    b = [conv(x) for x in m.b]
    c = [conv(x) for x in m.c]
    return c, A, b


def adjoint(A, b):
    """A_hat of (22b) with b_hat = b: a_hat_ji = b_i (b_j - a_ij) / b_j (exact when A, b are)."""
    s = len(b)
    return [[sympy.simplify(b[i] * (b[j] - A[i][j]) / b[j]) for i in range(s)] for j in range(s)]


def written(c, A, b, kind, A_hat=None, A_tilde=None, name="m"):
    """The JSON dict of the method written as ``kind`` (one of WRITINGS)."""
    A_hat = A if A_hat is None else A_hat
    A_tilde = A_hat if A_tilde is None else A_tilde

    def one(x, kind=kind):
        if kind == "exact":
            return str(sympy.nsimplify(x) if isinstance(x, float) else x)
        with mpmath.workdps(60):
            v = mpmath.mpf(sympy.N(x, 60)) if not isinstance(x, float) else mpmath.mpf(x)
            if kind == "float64":
                return float(v)
            if kind.startswith("f") and kind[1:].isdigit():
                # fixed point, N places, trailing zeros kept ("1.0000000"), as a table prints them
                return format(Decimal(mpmath.nstr(v, 50, strip_zeros=False)), f".{int(kind[1:])}f")
            if kind == "repr":
                return repr(float(v))
            if kind == "g17":
                return "%.17g" % float(v)
            if kind in ("mixed30", "json30"):
                return JsonText(mpmath.nstr(v, 30, min_fixed=-5, max_fixed=5))
            if kind == "15json":            # a published 15-digit coefficient, as a JSON number
                return float(mpmath.nstr(v, 15))
            return mpmath.nstr(v, int(kind), min_fixed=-5, max_fixed=5)
    vec = lambda v, k=kind: [one(x, k) for x in v]
    mat = lambda M, k=kind: [[one(x, k) for x in r] for r in M]
    hat = "float64" if kind == "mixed30" else kind
    return {"name": f"{name} ({kind})", "c": vec(c), "A": mat(A), "A_hat": mat(A_hat, hat),
            "A_tilde": mat(A_tilde, hat), "b": vec(b), "b_hat": vec(b), "b_tilde": vec(b)}


class JsonText(str):
    """A JSON number longer than a float64 holds, written as its text by ``write``."""


def _dumps(x) -> str:
    if isinstance(x, JsonText):
        return str(x)
    if isinstance(x, dict):
        return "{" + ", ".join(f"{json.dumps(k)}: {_dumps(v)}" for k, v in x.items()) + "}"
    if isinstance(x, list):
        return "[" + ", ".join(_dumps(v) for v in x) + "]"
    return json.dumps(x)


def write(path, d):
    """A tableau file as a user writes it (float64 values as JSON numbers)."""
    with open(path, "w") as f:
        f.write(_dumps(d))
    return path
