"""Methods written as their users write them, decided at the precision the writing carries
(``numbers.literal_radius``): fixed-point tables ("0.0416667" beside "1.0000000"), a float64's repr
or "%.17g" as strings, 30-digit JSON numbers beside float64 ones. Each writing of a method that
satisfies (22) passes (22) and its consistency; the same writing with one coefficient moved in its
6th digit fails (22b) (the negative control), and the violation is measured against the violated
entry's own uncertainty."""
import json

import pytest

from ldaspark.core import numbers as nb
from ldaspark.core.tableau_file import from_json_dict, load_tableau
from ldaspark.lab.theory import audit as au
from ldaspark.lab.theory import audit_checks as ac

from audit_writings import builtin, write, written

METHODS = ("lobatto-iiia-iiib-3", "lobatto-iiia-iiib-4", "gauss-3", "gauss-4")
KINDS = ("f7", "f8", "f10", "repr", "g17", "mixed30")


def _algebraic(tab):
    ar, e = au.decide_arith(tab, 30)[:2]
    checks, facts = au.algebraic_checks(tab, ar, e, 30)
    return {c.name: c for c in checks}, facts


def _load(tmp_path, name, kind, move=None):
    c, A, b, Ah, At = builtin(name)
    d = written(c, A, b, kind, Ah, At, name=name)
    if move is not None:                 # one coefficient of A_hat moved by 1e-6 relative (6th digit)
        x = d["A_hat"][0][1]
        y = float(x) * (1 + 1e-6) + 1e-7
        d["A_hat"][0][1] = type(x)(f"{y:.{len(str(x))}g}") if isinstance(x, str) else y
    return load_tableau(write(tmp_path / f"{name}-{kind}.json", d))


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", METHODS)
def test_every_writing_satisfies_22_and_is_consistent(name, kind, tmp_path):
    by, facts = _algebraic(_load(tmp_path, name, kind))
    assert by["22a"].status == au.PASS and by["22b"].status == au.PASS, by["22b"].detail
    assert by["consistent"].status == au.PASS
    assert facts["order:A"] >= 4


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", ("lobatto-iiia-iiib-3", "gauss-3"))
def test_a_coefficient_moved_in_its_6th_digit_fails_22b(name, kind, tmp_path):
    by, _ = _algebraic(_load(tmp_path, name, kind, move=True))
    c = by["22b"]
    assert c.status == au.FAIL
    # the uncertainty named in the message is the violated entry's, below its residual
    assert c.tolerance < c.residual


def test_fixed_point_literals_are_known_to_their_places():
    """In a file printed to 7 places (D = 8 from "1.0000000"), "0.0416667" (6 digits) is known to
    5e-8, not to the 8th significant digit (5e-10, the old reading that failed Lobatto IIIA-B 3);
    "0.5" to 5e-8 as well ("0.0000000" is exact); a repr-printed "0.16666666666666666" to half a unit in
    its last digit plus half an ulp (its digits are the float's, not 1/6's)."""
    r = lambda *a, **k: float(nb.literal_radius(*a, **k))
    assert r("0.0416667", 8, 7, False) == pytest.approx(5e-8)
    assert r("0.5", 8, 7, False) == pytest.approx(5e-8)
    assert r("0.0000000", 8, 7, False) == 0          # a zero is structural, exact
    # a file of 16-17 significant digits: "0.5" is a terminating expansion, 5e-17
    assert r("0.5", 17, 18, False) == pytest.approx(5e-18)
    # the float64 writing: 1/6 - 0.16666666666666666 = 6.7e-18 > 5e-18, within 5e-18 + 1.85e-17
    one_sixth = r("0.16666666666666666", 17, 18, True)
    assert one_sixth > 1 / 6 - 0.16666666666666666 + 1e-18 and one_sixth < 3e-17
    assert r("0.16666666666666666", 30, 30, False) == pytest.approx(5e-18)   # control: no ulp
    assert nb.decimal_places("2.5e-1") == 2 and nb.decimal_places("1.5e3") == -2
    # the fixed-point reading applies where the file shows one: a kept trailing zero, or literals
    # of the most places with different digit counts; not to "0.0", "0.5", "1.0" (nstr of
    # Lobatto IIIA-IIIB 2 at any digits: "0.5" stays 1/2 to its D = 2 digits, +- 0.005)
    assert nb.fixed_places({(7, 8, True), (7, 6, False)}) == 7
    assert nb.fixed_places({(7, 7, False), (7, 6, False)}) == 7
    assert nb.fixed_places({(1, 2, False), (1, 1, False)}) is None
    assert nb.fixed_places({(17, 17, False), (16, 16, False)}) is None
    assert r("0.5", 2, None, False) == pytest.approx(5e-3)


def test_shorter_literals_in_a_long_file_are_still_terminating_expansions():
    """The fixed-point reading does not loosen a %g file: Gauss-2 at 40 digits keeps "0.5" to 40
    digits (its (22a) tolerance below 1e-39)."""
    c, A, b, Ah, At = builtin("gauss-2")
    tab = from_json_dict(written(c, A, b, "40", Ah, At))
    by, _ = _algebraic(tab)
    assert by["22a"].tolerance < 1e-39


def test_entries_near_the_magnitude_limit_do_not_overflow(tmp_path):
    """b = 1e155 squares beyond float64 in (22b): the checks say so in numbers, no OverflowError."""
    p = tmp_path / "big.json"
    p.write_text(json.dumps({"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]],
                             "b": ["1e155"], "b_hat": ["1e155"], "b_tilde": ["1"]}))
    by, _ = _algebraic(load_tableau(p))
    assert by["22a"].status == au.PASS and by["consistent"].status == au.FAIL
    assert ac.digits_of(float("inf")) == 0 and ac.digits_of(1e-5) == 5


def test_nested_calls_are_bounded():
    """sin(sin(...)) took sympy ~0.1 s an entry at 30 levels: nesting beyond 4 and more than 16
    calls in one entry are refused in one line; the published writings stay within (control)."""
    from ldaspark.core.errors import TableauError
    nb.parse_exact_string("1/" + "sin(" * 4 + "7" + ")" * 4)
    with pytest.raises(TableauError, match="nested deeper than 4"):
        nb.parse_exact_string("1/" + "sin(" * 5 + "7" + ")" * 5)
    nb.parse_exact_string("+".join(f"sqrt({k})" for k in range(2, 18)))
    with pytest.raises(TableauError, match="more than 16 function calls"):
        nb.parse_exact_string("+".join(f"sqrt({k})" for k in range(2, 19)))
    # a zero denominator is still found when the cheap 256-bit test cannot decide it
    with pytest.raises(TableauError, match="division by zero"):
        nb.parse_exact_string("1/(sin(1)**2 + cos(1)**2 - 1)")


def test_convergence_hidden_by_the_entries_is_undecided_not_failed(monkeypatch):
    """When every error is within what the entries' uncertainty changes, down to one step of
    t_end, the order is undecided (info), not a failure of the method; with exact entries and every
    error exactly zero (a comparison that compared nothing) no slope is still a failure (control)."""
    from ldaspark.core.families import get_method
    tab = get_method("gauss-2")
    monkeypatch.setattr(ac, "_entry_floor_measured", lambda *a: (1.0, 1.0))
    ch, f = ac.convergence_checks(tab, 4, 30, True)
    conv = [c for c in ch if c.name.startswith("convergence:")]
    # undecided for the entries' reason (more digits in the file), not the working precision's
    assert all(c.status == ac.INFO and "undecided" in c.detail and "entries' uncertainty" in c.detail
               and "more digits in the file" in c.detail for c in conv), [c.detail for c in conv]
    assert f["convergence:skate"]["N"][0] == 1
    monkeypatch.setattr(ac, "_entry_floor_measured", lambda *a: (0.0, 0.0))
    monkeypatch.setattr(ac, "observed_order", lambda tab, sc, Ns, t, w, fl: {
        "scene": sc, "N": Ns, "t_end": t, "errors": [0.0] * len(Ns), "slopes": [], "observed": float("nan"),
        "reference": "-", "max_constraint": 0.0})
    ch, _ = ac.convergence_checks(tab, 4, 30, True)
    assert all(c.status == ac.FAIL for c in ch if c.name.startswith("convergence:"))


def test_short_json_numbers_beside_30_digit_ones_are_terminating_expansions(tmp_path):
    """A file of 30-digit JSON numbers writes 1/2, 1 and 0 as 0.5, 1.0, 0.0 (mpmath.nstr drops
    trailing zeros): terminating expansions, known to the file's 30 digits as the same texts in
    strings are, not float64 values off by cond(V) ulps (2.2e-15 for Lobatto IIIB's zeros). Read
    as float64, a_hat_13 = 1e-20 in Lobatto IIIA-IIIB 3 (exactly 0) passed (22), (23) and order
    4. (22b) at (1, 3) misses by b_1 1e-20 = 1.7e-21; its ball sums products of 30-digit entries
    (|b|, |a| <= 1, half-units <= 5e-31 each), so the tolerance stays below 1e-29, eight orders
    under the residual."""
    from audit_writings import JsonText
    name = "lobatto-iiia-iiib-3"
    c, A, b, Ah, At = builtin(name)
    # the correct case: the 30-digit JSON writing passes (22) and (23) with order 4 (control)
    by, facts = _algebraic(load_tableau(write(tmp_path / "ok.json", written(c, A, b, "json30", Ah, At))))
    assert facts["22"] and facts["23"] and facts["predicted_order"] == 4, by["22b"].detail
    # 0.5 (c_2) is known to the 30 digits, as the string "0.5" is: (23a) c_1 + c_3 = 1, c_2 + c_2 = 1
    assert by["23a"].tolerance < 1e-29
    for kind, fault in (("json30", JsonText("1e-20")), ("30", "1e-20")):   # strings: the control
        d = written(c, A, b, kind, Ah, At)
        assert float(d["A_hat"][0][2]) == 0.0
        d["A_hat"][0][2] = fault
        by, facts = _algebraic(load_tableau(write(tmp_path / f"fault-{kind}.json", d)))
        c22 = by["22b"]
        assert c22.status == au.FAIL and c22.tolerance < 1e-29 < 1.6e-21 < c22.residual, (kind, c22.detail)
        assert facts["predicted_order"] == 1 and not facts["23"], kind
        assert "float64" not in c22.detail, c22.detail
    # a 17-digit float64 JSON number beside 30-digit ones is still a float64's writing (mixed30):
    # cond(V) = 24 ulps of max |A_hat| = 5/6, 24 2^-53 5/6 = 2.22e-15, and half an ulp of 1/6,
    # 1.9e-17, on 1/6 (control: the fix leaves float64 writings alone)
    tab = load_tableau(write(tmp_path / "mixed.json", written(c, A, b, "mixed30", Ah, At)))
    assert 2.2e-15 < float(tab.ball_entries(60)["A_hat"][0][0].rad()) < 2.3e-15


@pytest.mark.parametrize("kind", ("float64", "10", "16", "30"))
def test_an_exact_omega_beside_rounded_b_and_c_spans_the_default_rows(kind, tmp_path):
    """omega-span stacks omega on the rows b_j c_j^(i-1) made from the file's b and c and counts
    singular values above the uncertainty; it took twice omega's uncertainty for both, so an
    omega written exactly (uncertainty 0) beside b, c known to 10 digits or float64 "did not span"
    the rows it is made of (Gauss-3: stacked sigma_3 ~ 1e-11 against a tolerance of ~1e-58). The
    default rows now carry the uncertainty of b and c. Control: an omega with rows b and c (c is
    not in span{b, b c}: sigma_3 = O(0.01)) still does not span, at every writing."""
    c, A, b, Ah, At = builtin("gauss-3")
    d = written(c, A, b, kind, Ah, At)
    d["omega"] = [[str(b[j] * c[j] ** i) for j in range(3)] for i in range(2)]
    tab = load_tableau(write(tmp_path / "span.json", d))
    chk = ac.check_omega_default(tab, 30)
    assert chk.status == au.PASS, chk.detail
    d["omega"][1] = [str(x) for x in c]
    chk = ac.check_omega_default(load_tableau(write(tmp_path / "nospan.json", d)), 30)
    assert chk.status == au.INFO and chk.residual > 1e3 * chk.tolerance, (chk.residual, chk.tolerance)


def test_solvability_within_the_digits_given_is_undecided_not_failed(tmp_path):
    """solvable compared N = [omega A_tilde; b_tilde^T]'s smallest singular value with the entries'
    uncertainty and failed whenever it was within it: Gauss-4 printed to 3 digits got "(21) is not
    solvable for this tableau: N has rank 3 < s = 4 (smallest singular value 2.29e-03, within
    3.0e-03)", exit 1, for a method whose N is regular. Above the SVD's own error (~1e-55 at the
    60-digit working precision) the written N is regular and only the method the digits stand for
    is in doubt: 'skip', not decided at these digits. Controls: Gauss-4 to 5 digits passes; an N
    singular as written (A_tilde = 0, b_tilde = 0: smallest singular value 0) still fails."""
    c, A, b, Ah, At = builtin("gauss-4")
    chk = ac.check_solvable(load_tableau(write(tmp_path / "g4-3.json", written(c, A, b, "3", Ah, At))))
    assert chk.status == au.SKIP and 1e-50 < chk.residual <= chk.tolerance, (chk.residual, chk.tolerance)
    assert "not decided" in chk.detail and "as written" in chk.detail, chk.detail
    assert ac.check_solvable(load_tableau(write(tmp_path / "g4-5.json", written(c, A, b, "5", Ah, At)))).status == au.PASS
    d = written(c, A, b, "3", Ah, At)
    d["A_tilde"] = [["0"] * 4 for _ in range(4)]
    d["b_tilde"] = ["0"] * 4
    chk = ac.check_solvable(load_tableau(write(tmp_path / "g4-zero.json", d)))
    assert chk.status == au.FAIL and chk.residual == 0.0 and "never enter" in chk.detail



def _fsal(tab_name):
    """``tab_name``'s coefficients with a last stage repeating the last node, weight 0 (FSAL-like):
    row s+1 of A and A_hat = row s, column s+1 zero, b_(s+1) = 0; (22) still holds."""
    c, A, b, Ah, At = builtin(tab_name)
    grow = lambda M: [r + [0] for r in M] + [M[-1] + [0]]
    return c + [c[-1]], grow(A), b + [0], grow(Ah), grow(At)


def test_a_node_computed_twice_in_float64_is_one_node_for_the_rounding_estimate(tmp_path):
    """float64 entries are known to cond(V) ulps, V the Vandermonde matrix of the distinct nodes;
    a node that a float64 computation returns twice with different last bits (Tsit5's FSAL nodes
    1.0 and 0.9999999999999998) counted as two nodes 2.2e-16 apart: cond(V) = 5.3e17 ulps, every
    entry known to ~1e2, and Tsit5's float64 writing was refused, "omega is singular ... within
    3.9e+11", while its 17- and 40-digit writings load. Nodes within 2^-40 (relative) are one node:
    distinct nodes that close would need cond(V) > 1e12, beyond what float64 entries carry.
    Lobatto IIIA-IIIB 3 with an FSAL stage (c = 0, 1/2, 1, 1) in float64, c_4 = 0.9999999999999998:
    cond(V) of (0, 1/2, 1) = 24 ulps as with c_4 = 1.0, it loads and (22) holds. Control: nodes
    1e-6 apart stay two nodes (cond(V) > 1e5)."""
    c, A, b, Ah, At = _fsal("lobatto-iiia-iiib-3")
    d = written(c, A, b, "float64", Ah, At)
    ref = load_tableau(write(tmp_path / "ref.json", d)).float_computation_ulps()
    d["c"][3] = 0.9999999999999998
    tab = load_tableau(write(tmp_path / "twice.json", d))
    assert tab.float_computation_ulps() == pytest.approx(ref) and ref == pytest.approx(24.0)
    by, facts = _algebraic(tab)
    assert facts["22"], by["22b"].detail
    # two genuinely distinct nodes 1e-6 apart: cond(V) far above 24 (control of the merging)
    d["c"][3] = 1 - 1e-6
    assert load_tableau(write(tmp_path / "close.json", d)).float_computation_ulps() > 1e5
