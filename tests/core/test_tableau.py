"""Tableau families against the paper's printed tableaux (7.1-7.6), known Lobatto
coefficients, simplifying assumptions at 50 digits up to s = 10, and the JSON format."""
import json

import mpmath
import pytest
import sympy
from sympy import Rational as R, sqrt

import ldaspark
from ldaspark.core.errors import InputError, LdasparkError, TableauError
from ldaspark.core.tableau import SparkTableau
from ldaspark.core.tableau_file import from_json_dict, load_tableau
from ldaspark.core.families import (euler_i, euler_ii, gauss, get_method, lobatto_coefficients, lobatto_iiia_iiib,
                                   lobatto_iiia_iiib_iiid)


def same(M, rows):
    M2 = sympy.Matrix(rows)
    return M.shape == M2.shape and all(sympy.simplify(a - b) == 0 for a, b in zip(M, M2))


def test_euler_i_7_1():
    t = euler_i()
    assert same(t.exact["c"], [[0]]) and same(t.exact["A"], [[0]])
    assert same(t.exact["A_hat"], [[1]]) and same(t.exact["A_tilde"], [[1]]) and same(t.exact["b"], [[1]])


def test_euler_ii_7_2():
    t = euler_ii()
    assert same(t.exact["c"], [[1]]) and same(t.exact["A"], [[1]])
    assert same(t.exact["A_hat"], [[0]]) and same(t.exact["A_tilde"], [[0]])


def test_gauss_1_midpoint_7_3():
    t = gauss(1, exact=True)
    for k in ("c", "A", "A_hat", "A_tilde"):
        assert same(t.exact[k], [[R(1, 2)]])
    assert same(t.exact["b"], [[1]])


def test_gauss_2_7_4():
    t = gauss(2, exact=True)
    r = sqrt(3) / 6
    A = [[R(1, 4), R(1, 4) - r], [R(1, 4) + r, R(1, 4)]]
    assert same(t.exact["c"], [[R(1, 2) - r], [R(1, 2) + r]])
    for k in ("A", "A_hat", "A_tilde"):
        assert same(t.exact[k], A)
    assert same(t.exact["b"], [[R(1, 2)], [R(1, 2)]])
    assert same(t.exact["omega"], [[R(1, 2), R(1, 2)]])  # (21e): 0 = K1/2 + K2/2


def test_lobatto_iiia_iiib_2_7_5():
    t = lobatto_iiia_iiib(2, exact=True)
    assert same(t.exact["A"], [[0, 0], [R(1, 2), R(1, 2)]])
    assert same(t.exact["A_hat"], [[R(1, 2), 0], [R(1, 2), 0]])
    assert same(t.exact["A_tilde"], t.exact["A_hat"].tolist())


def test_lobatto_iiia_iiib_iiid_2_7_6():
    t = lobatto_iiia_iiib_iiid(2, exact=True)
    assert same(t.exact["A_tilde"], [[R(1, 4), R(-1, 4)], [R(3, 4), R(1, 4)]])
    assert same(t.exact["A_hat"], [[R(1, 2), 0], [R(1, 2), 0]])


def test_lobatto_3_stage_known_coefficients():
    d = lobatto_coefficients(3)
    assert same(d["c"], [[0], [R(1, 2)], [1]])
    assert same(d["b"], [[R(1, 6)], [R(2, 3)], [R(1, 6)]])
    assert same(d["IIIA"], [[0, 0, 0], [R(5, 24), R(1, 3), R(-1, 24)], [R(1, 6), R(2, 3), R(1, 6)]])
    assert same(d["IIIB"], [[R(1, 6), R(-1, 6), 0], [R(1, 6), R(1, 3), 0], [R(1, 6), R(5, 6), 0]])
    assert same(d["IIIC"], [[R(1, 6), R(-1, 3), R(1, 6)], [R(1, 6), R(5, 12), R(-1, 12)], [R(1, 6), R(2, 3), R(1, 6)]])
    assert same(d["IIIC_star"], [[0, 0, 0], [R(1, 4), R(1, 4), 0], [0, 1, 0]])
    assert same(d["IIID"], [[R(1, 12), R(-1, 6), R(1, 12)], [R(5, 24), R(1, 3), R(-1, 24)], [R(1, 12), R(5, 6), R(1, 12)]])
    t = lobatto_iiia_iiib_iiid(3, exact=True)
    assert same(t.exact["A_tilde"], d["IIID"].tolist())


def test_gauss_3_known_coefficients():
    t = gauss(3, exact=True)
    r = sqrt(15)
    A = [[R(5, 36), R(2, 9) - r / 15, R(5, 36) - r / 30],
         [R(5, 36) + r / 24, R(2, 9), R(5, 36) - r / 24],
         [R(5, 36) + r / 30, R(2, 9) + r / 15, R(5, 36)]]
    assert same(t.exact["A"], A)
    assert same(t.exact["b"], [[R(5, 18)], [R(4, 9)], [R(5, 18)]])


def _B_C_D_residuals(tab, dps, orders):
    """max residuals of B(pB), C(pC) for A, D(pD) for A_hat (IIIB) at dps digits."""
    pB, pC, pD = orders
    with mpmath.workdps(dps):
        a = tab.arrays(dps)
        s = tab.s
        c, b, A, Ah = a.c, a.b, a.A, a.A_hat
        rB = max(abs(sum(b[i] * c[i] ** (k - 1) for i in range(s)) - mpmath.mpf(1) / k) for k in range(1, pB + 1))
        rC = max(abs(sum(A[i, j] * c[j] ** (k - 1) for j in range(s)) - c[i] ** k / k)
                 for i in range(s) for k in range(1, pC + 1))
        rD = max((abs(sum(b[i] * c[i] ** (k - 1) * Ah[i, j] for i in range(s)) - b[j] * (1 - c[j] ** k) / k)
                  for j in range(s) for k in range(1, pD + 1)), default=0)
        return float(rB), float(rC), float(rD)


@pytest.mark.parametrize("s", range(1, 11))
def test_gauss_B_C_at_50_digits(s):
    rB, rC, _ = _B_C_D_residuals(gauss(s), 50, (2 * s, s, 0))
    assert rB < 1e-48 and rC < 1e-48


@pytest.mark.parametrize("s", range(2, 11))
def test_lobatto_B_C_D_at_50_digits(s):
    rB, rC, rD = _B_C_D_residuals(lobatto_iiia_iiib(s), 50, (2 * s - 2, s, s))
    assert rB < 1e-48 and rC < 1e-48 and rD < 1e-48


def test_B_C_check_has_teeth():
    bad = gauss(3).with_entry("A", 0, 1, 1e-30)
    _, rC, _ = _B_C_D_residuals(bad, 50, (6, 3, 0))
    assert rC > 1e-31


@pytest.mark.parametrize("s", [2, 3, 4, 5])
def test_exact_and_numeric_builders_agree(s):
    for fam in (gauss, lobatto_iiia_iiib_iiid):
        if fam is lobatto_iiia_iiib_iiid and s < 2:
            continue
        ex, nu = fam(s, exact=True).arrays(40), fam(s).arrays(40)
        with mpmath.workdps(40):
            for k in ("c", "A", "A_hat", "A_tilde", "b", "omega"):
                diff = max((abs(x - y) for x, y in zip(getattr(ex, k).reshape(-1), getattr(nu, k).reshape(-1))), default=0)
                assert diff < 1e-38, (fam.__name__, s, k)


def test_float64_arrays_row_sums():
    a = lobatto_iiia_iiib_iiid(10).arrays(None)
    for M in (a.A, a.A_hat, a.A_tilde):
        assert abs(M.sum(axis=1) - a.c).max() < 1e-13


def test_json_roundtrip_exact(tmp_path):
    t = gauss(2, exact=True)
    p = tmp_path / "g2.json"
    t.save(p)
    d = json.loads(p.read_text())
    assert d["A"][0][1] in ("1/4 - sqrt(3)/6", "-sqrt(3)/6 + 1/4")
    t2 = load_tableau(p)
    assert t2.is_exact
    assert same(t2.exact["A"], t.exact["A"].tolist())



@pytest.mark.parametrize("make, dps", [(lambda: gauss(1), 40), (lambda: lobatto_iiia_iiib(2), 40),
                                       (lambda: lobatto_iiia_iiib_iiid(3), 25)])
def test_json_roundtrip_computed_keeps_digits(tmp_path, make, dps):
    """A computed tableau saved at dps digits is read back as known to dps digits: entries that are
    short in binary (0.5, 1) were written "0.5", "1.0", and the reloaded gauss-1 was "known to 2
    digits" (the audit's convergence check undecided, (22b) to +-0.16)."""
    t = make()
    p = tmp_path / "t.json"
    t.save(p, dps=dps)
    u = load_tableau(p)
    assert u.precision_kind() == "decimal" and u.decimal_digits == dps
    with mpmath.workdps(dps + 20):
        ref = t.mp_entries(dps + 20)
        for k, v in u.ball_entries(dps + 20).items():
            for x, y in zip(_flat(v), _flat(ref[k])):
                # a ball of half a unit in the dps-th digit that holds the computed value
                assert float(x.rad()) <= 0.501 * 10.0 ** (1 - dps) * max(abs(float(y)), 1e-300) or y == 0
                assert x.contains(flint_arb(y)), (k, x, y)


@pytest.mark.parametrize("dps", ["40", 1.5, True, 0, -3, 10 ** 6])
def test_to_json_dict_refuses_bad_dps(dps):
    """dps="40" was a TypeError, 1.5 an IndexError-like TypeError, 0 and -3 wrote nonsense."""
    with pytest.raises(LdasparkError, match="dps must be an integer"):
        gauss(2).to_json_dict(dps)


def _flat(v):
    return [z for x in v for z in _flat(x)] if isinstance(v, list) else [v]


def flint_arb(y):
    import flint
    with flint.ctx.workprec(int(mpmath.mp.dps * 3.33) + 16):
        return flint.arb(mpmath.nstr(y, mpmath.mp.dps))

def test_json_float_entries_not_exact():
    t = from_json_dict({"c": [0.5], "A": [[0.5]], "A_hat": [[0.5]], "A_tilde": [[0.5]], "b": [1.0],
                        "b_hat": [1], "b_tilde": ["1"]})
    assert not t.is_exact and t.source_digits == 15


@pytest.mark.parametrize("bad, msg", [
    ({"c": [0.5], "A": [[0.5, 1]], "A_hat": [[0.5]], "A_tilde": [[0.5]], "b": [1], "b_hat": [1], "b_tilde": [1]}, "A must be"),
    ({"c": [0.5], "A": [["x"]], "A_hat": [[0.5]], "A_tilde": [[0.5]], "b": [1], "b_hat": [1], "b_tilde": [1]}, "not a number"),
    ({"c": [0.5], "A": [[float("nan")]], "A_hat": [[0.5]], "A_tilde": [[0.5]], "b": [1], "b_hat": [1], "b_tilde": [1]}, "not finite"),
    ({"c": [0.5], "A": [[0.5]]}, "missing"),
    ({"c": [0, 1], "A": [[0, 0], [0.5, 0.5]], "A_hat": [[0.5, 0], [0.5, 0]], "A_tilde": [[0.5, 0], [0.5, 0]],
      "b": [0.5, 0.5], "b_hat": [0.5, 0.5], "b_tilde": [0.5, 0.5], "omega": [[0, 0]]}, "omega is singular"),
])
def test_json_malformed(bad, msg):
    with pytest.raises(TableauError, match=msg):
        from_json_dict(bad)


def test_unknown_method_name():
    with pytest.raises(TableauError):
        get_method("gauss-x")
    with pytest.raises(TableauError):
        get_method("lobatto-iiia-iiib-1")


@pytest.mark.parametrize("name", ["gauss-02", "lobatto-iiia-iiib-03", "lobatto-iiia-iiib-iiid-002"])
def test_a_stage_count_with_leading_zeros_is_refused_like_the_comparators(name):
    # one spelling per method: "gauss-02" ran as gauss-2 under another name while the
    # comparator "gauss-irk-02" was refused
    with pytest.raises(TableauError, match="leading zeros"):
        get_method(name)
    with pytest.raises(InputError, match="unknown method"):
        ldaspark.integrate("particle", name, n_steps=1, h=0.1)
    with pytest.raises(InputError, match="unknown method"):
        ldaspark.integrate("particle", "gauss-irk-02", n_steps=1, h=0.1)


@pytest.mark.parametrize("name", ["mid\nldaspark: error: fake", "a\x1b[31mred", "tab\tname", {"a": [1, 2]}, 5, ["x"]])
def test_a_tableau_files_name_is_printable_text(name, tmp_path):
    """The name of a tableau file is printed by ``ldaspark integrate`` and heads the audit report:
    a newline or an escape sequence in it forged lines on the terminal and in the markdown, and a
    number, list or dict was turned into its repr. Each is one TableauError; printable names load."""
    d = {"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]], "b": [1], "b_hat": [1],
         "b_tilde": [1], "name": name}
    path = tmp_path / "t.json"
    path.write_text(json.dumps(d))
    with pytest.raises(TableauError, match="name"):
        load_tableau(str(path))
    with pytest.raises(TableauError, match="name"):
        SparkTableau(name, 1, exact=from_json_dict(dict(d, name="ok")).exact)
    assert from_json_dict(dict(d, name="midpoint (Gauss, s = 1) \u03c9")).name == "midpoint (Gauss, s = 1) \u03c9"


@pytest.mark.parametrize("text", ["(lambda: 1)()", "__import__('os').getcwd()", "10**10**10", "x", "1e999",
                                  "[1]", "1/0", "Rational(1, 0)", "a" * 300])
def test_string_entries_are_never_evaluated_as_python(text):
    d = {"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]], "b": [text], "b_hat": [1],
         "b_tilde": [1]}
    with pytest.raises(TableauError, match=r"b\[0\]"):
        from_json_dict(d)


@pytest.mark.parametrize("text, value", [("1/4 - sqrt(3)/6", sympy.Rational(1, 4) - sqrt(3) / 6), ("0.1", R(1, 10)),
                                         ("-2.5e-1", R(-1, 4)), ("Rational(1, 3)", R(1, 3)), ("2**-3", R(1, 8)),
                                         ("pi/4", sympy.pi / 4)])
def test_exact_string_entries(text, value):
    from ldaspark.core.numbers import parse_exact_string
    assert sympy.simplify(parse_exact_string(text) - value) == 0


def test_exact_beyond_radicals_is_a_clear_error():
    with pytest.raises(TableauError, match="any precision"):
        gauss(6, exact=True)
    assert gauss(6).arrays(30).A.shape == (6, 6)


# --- derived tableaux are independent of their source (no shared state) -------------------------
@pytest.mark.parametrize("exact", [True, False])
def test_with_entry_copies_are_independent_of_the_source(exact):
    """Two negative controls derived from one tableau: each carries only its own change, and the
    source (also its cached arrays) keeps its entries."""
    import numpy as np
    src = get_method("gauss-2", exact=exact)
    a0 = np.array(src.arrays(None).A_hat, float)
    b0 = np.array(src.arrays(None).b_hat, float)
    d1 = src.with_entry("A_hat", 0, 1, "1/10")
    d2 = src.with_entry("b_hat", 0, None, "1/10")
    assert np.array_equal(np.array(src.arrays(None).A_hat, float), a0)
    assert np.array_equal(np.array(get_method("gauss-2", exact=exact).arrays(None).A_hat, float), a0)
    assert np.array_equal(np.array(src.arrays(None).b_hat, float), b0)
    diff1 = np.array(d1.arrays(None).A_hat, float) - a0
    assert abs(diff1[0, 1] - 0.1) < 1e-15 and np.count_nonzero(np.abs(diff1) > 1e-15) == 1
    assert np.array_equal(np.array(d1.arrays(None).b_hat, float), b0)
    assert np.array_equal(np.array(d2.arrays(None).A_hat, float), a0)        # not d1's change
    assert abs(np.array(d2.arrays(None).b_hat, float)[0] - b0[0] - 0.1) < 1e-15
    if exact:                                                                  # and the exact entries
        assert src.exact["A_hat"] == get_method("gauss-2", exact=True).exact["A_hat"]


# --- a builder given directly: its entries are checked as exact ones are ------------------------
def _half_builder(s, **change):
    def builder(dps):
        h = mpmath.mpf(1) / 2
        ent = {k: [[h] * s for _ in range(s)] if k.startswith("A") else [h] * s
               for k in ("c", "A", "A_hat", "A_tilde", "b", "b_hat", "b_tilde")}
        ent["omega"] = [[h] * s for _ in range(s - 1)]
        ent.update(change)
        return ent
    return builder


@pytest.mark.parametrize("change, msg", [
    ({"c": [0.5]}, "list of 2 numbers"),                         # was a numpy reshape ValueError
    ({"A": [[0.5, 0.5, 0.5]] * 3}, "2 x 2 list"),
    ({"omega": [[0.5, 0.5]] * 2}, "1 x 2 list"),
    ({"b": [float("nan"), 0.5]}, "not a finite real"),           # was a NaN trajectory
    ({"A_hat": [["x", 0.5], [0.5, 0.5]]}, "not a finite real"),
    ({"b_tilde": [True, 0.5]}, "not a finite real"),
])
def test_builder_entries_checked(change, msg):
    bad = SparkTableau("direct", 2, builder=_half_builder(2, **change))
    with pytest.raises(TableauError, match=msg):
        bad.arrays()
    with pytest.raises(TableauError, match=msg):
        bad.arrays(30)
    with pytest.raises(TableauError, match=msg):
        ldaspark.integrate("skate", bad, t_span=(0, 0.1), h=0.1, engine="generic")
    # valid neighbour: the same builder unchanged, and vectors given as s x 1 lists
    assert SparkTableau("ok", 2, builder=_half_builder(2)).arrays().A.shape == (2, 2)
    col = SparkTableau("col", 2, builder=_half_builder(2, c=[[0.25], [0.75]])).arrays()
    assert list(col.c) == [0.25, 0.75]


def test_builder_not_a_dict():
    with pytest.raises(TableauError, match="must return a dict"):
        SparkTableau("direct", 1, builder=lambda dps: 5).arrays()


@pytest.mark.parametrize("exact", [True, False])
def test_with_entry_tableau_pickles(exact):
    """A negative control of a computed tableau goes to an ensemble's worker processes: its builder
    was a closure ("Can't pickle local object 'SparkTableau.with_entry.<locals>.builder'")."""
    import pickle
    t = gauss(2, exact=exact).with_entry("A_hat", 0, 1, "1/1000").with_entry("b", 1, None, "1/10")
    u = pickle.loads(pickle.dumps(t))
    with mpmath.workdps(40):
        for k in ("A_hat", "b", "A"):
            x, y = getattr(t.arrays(40), k).reshape(-1), getattr(u.arrays(40), k).reshape(-1)
            assert all(a == b for a, b in zip(x, y)), k
    assert abs(float(u.arrays().A_hat[0, 1] - gauss(2).arrays().A_hat[0, 1]) - 1e-3) < 1e-15


@pytest.mark.parametrize("name, got", [("x" * 501, "a string of 501 characters"), ("", "a string of 0 characters"),
                                       (5, "int")])
def test_tableau_name_message_names_the_rule(name, got):
    """A long name was refused with "must be a non-empty string, got str" (it is a string)."""
    with pytest.raises(TableauError, match=f"at most 500 characters, got {got}"):
        SparkTableau(name, 1, exact=gauss(1, exact=True).exact)
    assert SparkTableau("x" * 500, 1, exact=gauss(1, exact=True).exact).s == 1


@pytest.mark.parametrize("bad", [sympy.Rational(1, 2) + sympy.I / 10, sympy.oo, sympy.nan, sympy.zoo,
                                 sympy.Symbol("x"), sympy.Integer(10) ** 400])
def test_exact_entries_given_directly_are_finite_reals(bad):
    """SparkTableau(exact=...) gets the file reader's value checks: 1/2 + I/10 ran as 1/2 (re() taken
    silently), nan and zoo gave NaN coefficients (integrate status -1), oo and a Symbol a ValueError."""
    ex = dict(gauss(1, exact=True).exact)
    ex["A"] = sympy.Matrix([[bad]])
    with pytest.raises(TableauError, match=r"exact\['A'\]\[0\]\[0\] .* is not a finite real number"):
        SparkTableau("direct", 1, exact=ex)
    # valid neighbours: a real number written with I, and the unchanged tableau
    ex["A"] = sympy.Matrix([[(1 + sympy.I) * (1 - sympy.I) / 4]])
    assert SparkTableau("direct", 1, exact=ex).arrays().A[0, 0] == 0.5


@pytest.mark.parametrize("zero", ["0.0", "-0.0", "0e0"])
def test_a_file_whose_only_json_numbers_are_zeros_is_described_and_audited(tmp_path, zero):
    # Lobatto IIIA-IIIB 2 in exact strings, its zeros written as JSON numbers: these have no
    # significant digits (decimal_digits None), and precision_text raised a TypeError (_ordinal(None))
    # in every audit of such a file: `ldaspark audit` printed a traceback, exit 1
    from ldaspark.lab.theory import audit as au
    q = tmp_path / "lobatto2.json"
    q.write_text('{"c": [' + zero + ', "1"], "A": [[' + zero + ', ' + zero + '], ["1/2", "1/2"]], '
                 '"A_hat": [["1/2", ' + zero + '], ["1/2", ' + zero + ']], "A_tilde": [["1/2", 0], ["1/2", 0]], '
                 '"b": ["1/2", "1/2"], "b_hat": ["1/2", "1/2"], "b_tilde": ["1/2", "1/2"]}')
    t = load_tableau(q)
    text = t.precision_text()
    assert "zero" in text and "None" not in text
    ar, e, reason = au.decide_arith(t, 30)
    assert "None" not in ar.scope and "None" not in ar.label   # "to the None digits given as JSON numbers"
    C, facts = au.algebraic_checks(t, ar, e, 30)
    st = {c.name: c.status for c in C}
    assert st["22a"] == st["22b"] == "pass" and facts["order:pair"] == 2


@pytest.mark.parametrize("name, got", [({"a": 1}, "dict"), (5, "int"), ("", "a string of 0 characters"),
                                       (["x"], "list")])
def test_a_file_name_that_is_not_a_nonempty_string_is_refused(name, got):
    # the file's "name" was str()-ed ({"a": 1} audited as "{'a': 1}") or, when falsy ("", []),
    # replaced by "custom" in silence; it now gets the rule of SparkTableau's name
    d = {"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]], "b": ["1"], "b_hat": ["1"],
         "b_tilde": ["1"], "name": name}
    with pytest.raises(TableauError, match=f"tableau name must be a non-empty printable string.*got {got}"):
        from_json_dict(d)
    assert from_json_dict(dict(d, name=None)).name == "custom" == from_json_dict({k: v for k, v in d.items() if k != "name"}).name
    assert from_json_dict(dict(d, name="midpoint")).name == "midpoint"


def _flat(v):
    return [y for x in v for y in _flat(x)] if isinstance(v, (list, tuple)) else [v]


@pytest.mark.parametrize("name", ["gauss-2", "gauss-3", "lobatto-iiia-iiib-3"])
def test_mpmath_coefficients_carry_the_working_precision(name):
    """The coefficients the mpmath engine runs with (``arrays(dps)``, ``SparkMethod.tab``) are the
    tableau's entries to dps digits: against the same entries at dps + 20 digits, off by at most
    one unit in the last place, 10^(1 - dps) max(1, |entry|), at dps below and above the 20
    digits the float64 conversion starts from. (Coefficients fixed at 20 digits are off by
    ~1e-22 at dps = 30, which no run comparison saw: test_dps_400_runs_and_agree_with_dps_440
    compares two runs with the same wrong coefficients, and the theorem checks passed.)"""
    from ldaspark.core.spark import SparkMethod
    from ldaspark.models.scenes import get_scene
    tab = get_method(name)
    system = get_scene("particle").system
    for dps in (16, 30, 60):
        with mpmath.workdps(dps + 20):
            ref = tab.mp_entries(dps + 20)
            bound = mpmath.mpf(10) ** (1 - dps)
            for got in (tab.arrays(dps), SparkMethod(system, tab, dps=dps).tab):
                assert got.dps == dps
                for key, want in ref.items():
                    g, w = list(getattr(got, key).reshape(-1)), _flat(want)
                    assert len(g) == len(w), (name, key)
                    err = max((abs(mpmath.mpf(x) - y) / max(1, abs(y)) for x, y in zip(g, w)), default=0)
                    assert err <= bound, (name, dps, key, mpmath.nstr(err, 3))


@pytest.mark.parametrize("text, shown", [("1e301", "1e301"), ("1e308", "1e308"), ("-1.5e305", "-1.5e305"),
                                         ("1e400", "1e400"), ("1e999999", "1e999999")])
def test_a_json_number_beyond_1e300_is_refused_as_written(text, shown, tmp_path):
    """A JSON number above the entries' bound 1e300 skipped the reader's magnitude check: 1e308
    reached the tableau's own check, whose message printed the first 40 digits of its integer,
    "exact['c'][0] = 1000000000000000000000000000000000000000" (10^39, not the 1e308 written),
    and 1e999999 (inf as a float64) read "entry inf is not finite". Each names the entry and the
    text written; 1e300 itself loads (the bound is inclusive), and a string entry "1e301" gets the
    same one-line refusal (controls)."""
    ok = '{"c": [%s], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]], "b": ["1"], "b_hat": ["1"], ' \
         '"b_tilde": ["1"]}'
    p = tmp_path / "t.json"
    p.write_text(ok % text)
    with pytest.raises(TableauError) as exc:
        load_tableau(str(p))
    msg = str(exc.value)
    assert msg.startswith("c[0]: ") and shown in msg and "\n" not in msg, msg
    assert "0" * 30 not in msg and "inf" not in msg.replace("1e999999", ""), msg
    p.write_text(ok % "1e300")
    assert load_tableau(str(p)).s == 1
    p.write_text(ok % '"1e301"')
    with pytest.raises(TableauError, match=r"^c\[0\]: '1e301' exceeds 1e\+300 in modulus$"):
        load_tableau(str(p))
    # the tableau's own check (an exact entry given to the API) marks a shortened number as such
    ex = dict(from_json_dict(json.loads(ok % '"1/2"')).exact, c=sympy.Matrix([[sympy.Integer(10) ** 308]]))
    with pytest.raises(TableauError, match=r"= 1000000000000000000000000000000000000\.\.\. is not a finite"):
        SparkTableau("big", 1, exact=ex)


def test_a_symbolic_link_loop_is_named_as_such(tmp_path):
    """A tableau path that is a link loop (a -> b -> a) was reported "not found", which sends the
    user looking for a missing file; a link that does not resolve is now named as one (a loop or a
    missing target). Controls: a plain missing path is "not found", a link to a good file loads."""
    import os
    (tmp_path / "a.json").symlink_to(tmp_path / "b.json")
    (tmp_path / "b.json").symlink_to(tmp_path / "a.json")
    (tmp_path / "dangling.json").symlink_to(tmp_path / "nowhere.json")
    for name in ("a.json", "dangling.json"):
        with pytest.raises(TableauError, match="symbolic link that does not resolve"):
            load_tableau(str(tmp_path / name))
    with pytest.raises(TableauError, match="not found$"):
        load_tableau(str(tmp_path / "missing.json"))
    good = tmp_path / "good.json"
    good.write_text(json.dumps({"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]],
                                "b": ["1"], "b_hat": ["1"], "b_tilde": ["1"]}))
    os.symlink(good, tmp_path / "link.json")
    assert load_tableau(str(tmp_path / "link.json")).s == 1


def test_a_key_given_twice_is_refused_and_a_utf8_bom_is_read(tmp_path):
    """json.loads keeps the last of two "A_hat" keys in silence: the audit judged a tableau the
    file gives two ways (a first A_hat satisfying (22b), a second violating it, passed or failed
    by which came last). A key given twice is one TableauError naming it. A UTF-8 byte-order mark (Windows editors write one) was refused with
    Python's advice "decode using utf-8-sig"; it is read. Controls: the file without the second
    key and without the BOM loads to the same tableau; non-UTF-8 bytes are still refused."""
    text = ('{"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]], "b": ["1"], '
            '"b_hat": ["1"], "b_tilde": ["1"]%s}')
    p = tmp_path / "t.json"
    p.write_text(text % ', "A_hat": [["1/3"]]')
    with pytest.raises(TableauError, match=r"key 'A_hat' is given twice$"):
        load_tableau(str(p))
    p.write_text(text % "")
    ref = load_tableau(str(p))
    p.write_bytes(b"\xef\xbb\xbf" + (text % "").encode())
    assert load_tableau(str(p)).exact == ref.exact
    p.write_bytes(b"\xff\xfe" + (text % "").encode())
    with pytest.raises(TableauError, match="cannot read tableau file"):
        load_tableau(str(p))


@pytest.mark.parametrize("typo, key", [("Omega", "omega"), ("omgea", "omega"), ("A-hat", "A_hat"), ("Name", "name"),
                                       ("a_tilde", "A_tilde")])
def test_a_misspelt_tableau_key_is_refused_not_ignored(typo, key, tmp_path):
    """Keys other than the tableau's were ignored in silence, so a misspelt optional key changed
    the method audited: Gauss-3 with its omega under "Omega" (rows of the identity: measured order 4,
    not symmetric) was audited with the default omega, exit 0, "symmetric", order 6. A key that
    is a near miss of a tableau key (the same letters up to case and _ - space, or difflib ratio
    >= 0.8) is refused naming the key meant; a required key misspelt was "missing key(s)" without
    the hint. Controls: the correct key loads; metadata keys ("comment", "source", "order",
    "reference") are still accepted."""
    d = {"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]], "b": ["1"], "b_hat": ["1"],
         "b_tilde": ["1"]}
    bad = dict(d, **{typo: d.get(key, [] if key == "omega" else "midpoint")})
    if key in d and typo != key:
        bad.pop(key)
    p = tmp_path / "t.json"
    p.write_text(json.dumps(bad))
    with pytest.raises(TableauError, match=rf"key '{typo}' .*did you mean '{key}'"):
        load_tableau(str(p))
    p.write_text(json.dumps(dict(d, comment="Gauss 1", source="Jay 2009", order=2, reference="[27]")))
    assert load_tableau(str(p)).s == 1
