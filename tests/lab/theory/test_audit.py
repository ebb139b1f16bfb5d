"""``ldaspark audit``: exit codes 0 / 1 / 2, the checks' teeth, the JSON schema, bad input."""
import json
import pathlib

import pytest

from ldaspark.lab.theory import audit as au
from ldaspark.cli import main
from ldaspark.core.errors import TableauError
from ldaspark.analysis.conditions import check_23
from ldaspark.core.tableau_file import load_tableau
from ldaspark.core.families import builtin_method_names, get_method

EX = pathlib.Path(__file__).resolve().parents[3] / "examples" / "tableaux"
# bad-unsolvable.json is a usable file of an unusable tableau: a verdict, exit 1 (issue 47)
BAD = sorted(p.name for p in EX.glob("bad-*.json") if p.name != "bad-unsolvable.json")


@pytest.mark.parametrize("name", BAD)
def test_malformed_file_exits_2_with_one_line(name, capsys):
    rc = main(["audit", str(EX / name), "--quick"])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if not ln.startswith("[audit]")]
    assert rc == 2
    assert len(lines) == 1 and lines[0].startswith("ldaspark: error:") and "Traceback" not in err


def test_unsolvable_tableau_gets_a_verdict_exit_1(capsys):
    """A_tilde = 0, b_tilde = 0: N = [omega A_tilde; b_tilde^T] = 0, (21) leaves the multipliers free."""
    rc = main(["audit", str(EX / "bad-unsolvable.json"), "--quick"])
    out = capsys.readouterr().out
    assert rc == 1 and "(21) is not solvable for this tableau" in out and "never enter" in out


def test_bad_files_name_their_problem(capsys):
    expect = {"bad-nan.json": "not finite", "bad-shape.json": "A must be", "bad-missing-key.json": "b_tilde",
              "bad-nonnumeric.json": "'half'", "bad-singular-omega.json": "omega is singular",
              "bad-syntax.json": "not valid JSON"}
    assert set(expect) == set(BAD)
    for name, frag in expect.items():
        main(["audit", str(EX / name), "--quick"])
        assert frag in capsys.readouterr().err, name


@pytest.mark.parametrize("text", ["(lambda: 1)()", "__import__('os').getcwd()", "10**10**10", "2**100",
                                  "x", "1e999", "sqrt(3) if 1 else 0", "a" * 300])
def test_unsafe_or_non_arithmetic_strings_are_rejected_before_sympy(text, tmp_path):
    d = json.loads((EX / "gauss2.json").read_text())
    d["b"][0] = text
    p = tmp_path / "t.json"
    p.write_text(json.dumps(d))
    with pytest.raises(TableauError):
        au.safe_load_tableau(p)


@pytest.mark.parametrize("text", ["1/2", "0.5", "5e-1", "Rational(1, 2)", "sqrt(4)/4", "2**(-1)", "(1 + 0)/2"])
def test_plain_arithmetic_strings_are_accepted(text, tmp_path):
    d = json.loads((EX / "gauss2.json").read_text())
    d["b"][0] = d["b_hat"][0] = d["b_tilde"][0] = text
    p = tmp_path / "t.json"
    p.write_text(json.dumps(d))
    tab = au.safe_load_tableau(p)
    assert tab.is_exact and str(tab.exact["b"][0]) == "1/2"


def test_file_xor_method_and_dps_range(capsys):
    assert main(["audit"]) == 2
    assert main(["audit", str(EX / "gauss2.json"), "--method", "gauss-2"]) == 2
    assert main(["audit", "--method", "gauss-2", "--dps", "5"]) == 2
    assert main(["audit", "--method", "gauss-x"]) == 2
    err = capsys.readouterr().err
    assert "exactly one of FILE or --method" in err and "--dps" in err and "unknown method" in err


@pytest.mark.parametrize("name", builtin_method_names(4))
def test_builtin_coefficient_checks(name):
    """(22) holds, (23) as the exact core check says, and the predicted order equals the
    claimed order for every built-in (exact for s <= 3, mpmath at 30 digits for s = 4)."""
    tab = get_method(name)
    if tab.s <= 3:
        tab = get_method(name, exact=True)
    ar, e = au.oc.arith_for(tab, 30)
    assert au.check_22a(ar, e).status == au.PASS and au.check_22b(ar, e).status == au.PASS
    sym = all(c.status == au.PASS for c in au.check_23(ar, e))
    if tab.is_exact:
        assert sym == check_23(tab)
    checks, facts = au.order_checks(ar, e)
    assert au.predicted_order(tab, facts) == tab.claimed_order
    assert facts["order:pair"] == tab.claimed_order


def test_22b_check_names_the_worst_entry():
    tab = load_tableau(EX / "broken-22b.json")
    ar, e = au.oc.arith_for(tab)
    c = au.check_22b(ar, e)
    assert c.status == au.FAIL and "(i, j) = (2, 1)" in c.detail and abs(c.residual - 0.05) < 1e-15
    assert au.check_22a(ar, e).status == au.PASS


def test_float_tableau_tolerance_and_worst_entry():
    """Float entries: (22b) holds to ~1e-17, within the uncertainty float64 entries carry (half an
    ulp each, and cond(V) = 24 ulps of the array's largest entry for the rounding of a float64
    computation: ~1e-15 on the condition); a 1e-8 change does not."""
    tab = load_tableau(EX / "lobatto3-float.json")
    assert not tab.is_exact and tab.precision_kind() == "float"
    ar, e = au.oc.arith_for(tab, 30)
    c = au.check_22b(ar, e)
    assert ar.ball and c.status == au.PASS and 1e-17 < c.tolerance < 1e-14 and c.residual < c.tolerance
    bad = tab.with_entry("A_hat", 1, 2, 1e-8)
    ar2, e2 = au.oc.arith_for(bad, 30)
    c = au.check_22b(ar2, e2)
    # b_2 * 1e-8 = (2/3) 1e-8 at (i, j) = (3, 2)
    assert c.status == au.FAIL and "(i, j) = (3, 2)" in c.detail and abs(c.residual - 2e-8 / 3) < 1e-15


def test_convergence_check_fails_when_prediction_is_wrong():
    """Negative control of the observed-order check: Euler I measured against a claimed 2."""
    tab = get_method("euler-i")
    ok, _ = au.convergence_checks(tab, 1, 30, quick=True)
    bad, _ = au.convergence_checks(tab, 2, 30, quick=True)
    assert [c.status for c in ok if c.name.startswith("convergence")] == [au.PASS, au.PASS]
    assert [c.status for c in bad if c.name.startswith("convergence")] == [au.FAIL, au.FAIL]


def test_broken_22b_exits_1_with_theorem1_failing():
    tab = load_tableau(EX / "broken-22b.json")
    res = au.audit(tab, quick=True, theorem_scenes=("skate", "particle"))
    assert res.exit_code == 1
    th = [c for c in res.checks if c.name.startswith("theorem1")]
    assert th and all(c.status == au.FAIL for c in th)
    assert all(c.residual > 1e-4 for c in th)
    assert "violates" in res.verdict and "Theorem 1 does not apply" in res.verdict


def test_cli_builtin_exit_0_and_json_schema(tmp_path, capsys):
    out = tmp_path / "a.json"
    md = tmp_path / "a.md"
    rc = main(["audit", "--method", "gauss-2", "--quick", "--json", str(out), "--out", str(md)])
    assert rc == 0
    d = json.loads(out.read_text())
    assert d["exit_code"] == 0 and d["tableau"] == "gauss-2"
    names = {c["name"] for c in d["checks"]}
    for need in ("22a", "22b", "23a", "order:pair(A,A_hat)", "omega-rank", "convergence:skate",
                 "convergence:particle", "constraint", "energy", "theorem1:particle", "theorem1:skate",
                 "theorem1:robot", "theorem1:mp-particles", "symmetry:skate", "stability:A"):
        assert need in names, need
    for c in d["checks"]:
        # the contract's four keys, extended by the arithmetic that decided and its tolerance
        assert set(c) == {"name", "status", "residual", "detail", "arithmetic", "tolerance"}
        assert c["status"] in ("pass", "fail", "info", "skip")
    by = {c["name"]: c for c in d["checks"]}
    assert by["22b"]["arithmetic"].startswith("exact in QQ<sqrt(3)>") and by["22b"]["tolerance"] == 0.0
    assert by["energy"]["arithmetic"] is None
    assert all(c["status"] != "fail" for c in d["checks"])
    text = md.read_text()
    assert "## Verdict" in text and "Theorem 1 applies" in text


def test_float_file_audits_exit_0():
    tab = load_tableau(EX / "lobatto3-float.json")
    res = au.audit(tab, quick=True, theorem_scenes=("skate",))
    assert res.exit_code == 0, [c for c in res.checks if c.status == au.FAIL]
    assert res.facts["predicted_order"] == 4


@pytest.mark.exhaustive
@pytest.mark.parametrize("name", builtin_method_names(4))
def test_every_builtin_full_quick_audit_exit_0(name):
    assert main(["audit", "--method", name, "--quick"]) == 0


@pytest.mark.exhaustive
def test_three_stage_quick_audit_under_a_minute():
    import time
    t = time.time()
    assert main(["audit", "--method", "lobatto-iiia-iiib-iiid-3", "--quick"]) == 0
    assert time.time() - t < 60


def _fake_t1(**over):
    r = {"theorem1-q0": 1e-40, "theorem1-q1": 1e-40, "fd_error": 1e-35, "without_forces_q0": 1.0,
         "wellposed": "well-posed", "rank_deficiency": 0, "dps": 30, "dps_fd": 50}
    r.update(over)
    return r


def _raising(msg):
    def boom(*a, **k):
        from ldaspark.analysis.discrete import DiscreteSolveError
        raise DiscreteSolveError(msg)
    return boom


def _statuses(hyp23):
    checks, _ = au.theorem1_checks(get_method("gauss-1"), True, hyp23, 30, True, ("skate", "particle"))
    return {c.name: c.status for c in checks}


def test_undecided_theorem1_scenes_cannot_pass_silently(monkeypatch):
    """Negative control of the skip rule: when every BVP solve fails, the summary check fails."""
    from ldaspark.analysis import discrete, symmetry
    monkeypatch.setattr(discrete, "theorem1_residuals", _raising("BVP Newton did not converge"))
    by = _statuses(hyp23=False)
    assert by["theorem1:skate"] == au.SKIP and by["theorem1"] == au.FAIL


def test_theorem1_residual_above_tolerance_fails_and_coarse_fd_is_not_a_pass(monkeypatch):
    from ldaspark.analysis import discrete, symmetry
    monkeypatch.setattr(discrete, "theorem1_residuals", lambda *a, **k: _fake_t1(**{"theorem1-q1": 1e-3}))
    checks, _ = au.theorem1_checks(get_method("gauss-1"), True, False, 30, True, ("skate", "particle"))
    assert {c.status for c in checks if c.name.startswith("theorem1")} == {au.FAIL}
    monkeypatch.setattr(discrete, "theorem1_residuals", lambda *a, **k: _fake_t1(fd_error=1e-3))
    checks, _ = au.theorem1_checks(get_method("gauss-1"), True, False, 30, True, ("skate",))
    assert [c.status for c in checks if c.name.startswith("theorem1")] == [au.SKIP, au.FAIL]


def test_symmetry_fd_parts_judged_only_for_nonsingular_bvp(monkeypatch):
    from ldaspark.analysis import discrete, symmetry
    monkeypatch.setattr(discrete, "theorem1_residuals", lambda *a, **k: _fake_t1())
    sym = {"symmetry-Ld": 0.0, "symmetry-fd-plus": 1e-3, "symmetry-fd-minus": 1e-3, "symmetry-Phi": 1e-30}
    for cls, want in (("well-posed", au.FAIL), ("gauge-deficient", au.FAIL), ("singular", au.PASS)):
        monkeypatch.setattr(symmetry, "check_symmetry", lambda *a, cls=cls, **k: dict(sym, wellposed=cls))
        checks, _ = au.theorem1_checks(get_method("gauss-1"), True, True, 30, True, ("skate",))
        assert next(c for c in checks if c.name == "symmetry:skate").status == want, cls
    monkeypatch.setattr(symmetry, "check_symmetry",
                        lambda *a, **k: dict(sym, wellposed="singular", **{"symmetry-Phi": 1e-3}))
    checks, _ = au.theorem1_checks(get_method("gauss-1"), True, True, 30, True, ("skate",))
    assert next(c for c in checks if c.name == "symmetry:skate").status == au.FAIL


def test_a_tilde_lowers_the_order_and_the_prediction_sees_it():
    """Gauss-2 with a lower-triangular A_tilde satisfies (22) (A_tilde is not in it) but the
    three-coloured trees predict order 2, not the pair's 4; the skate and particle agree."""
    tab = au.safe_load_tableau(EX / "gauss2-lowtri-atilde.json")
    ar, e = au.oc.arith_for(tab)
    assert au.check_22b(ar, e).status == au.PASS
    checks, facts = au.order_checks(ar, e)
    assert facts["order:pair"] == 4 and au.predicted_order(tab, facts) == 2
    ok, f2 = au.convergence_checks(tab, 2, 30, quick=True)
    assert all(c.status == au.PASS for c in ok)
    wrong, _ = au.convergence_checks(tab, 4, 30, quick=True)
    assert [c.status for c in wrong if c.name.startswith("convergence")] == [au.FAIL, au.FAIL]


def test_json_output_is_strict_json_even_with_nan_and_mpf():
    import mpmath
    res = au.AuditResult("t", 1, True, 30, True)
    res.checks.append(au.Check("x", au.INFO, float("inf"), "d"))
    res.facts = {"a": float("nan"), "b": [mpmath.mpf(2), (1, float("-inf"))], "c": {"d": object}}
    d = res.as_dict()
    json.dumps(d, allow_nan=False)
    assert d["facts"]["a"] == "nan" and d["facts"]["b"] == [2.0, [1, "-inf"]] and d["checks"][0]["residual"] is None


def test_new_tableau_radau_iia_with_symplectic_conjugate():
    """A tableau that is not built in: Radau IIA (order 5) with A_hat = A_tilde from (22b).
    (22) holds exactly, (23a) does not (c3 = 1 has no mirror), the forced-ODE order is 5."""
    tab = au.safe_load_tableau(EX / "radau-iia-3-conjugate.json")
    ar, e = au.oc.arith_for(tab)
    assert ar.exact
    assert au.check_22a(ar, e).status == au.PASS and au.check_22b(ar, e).status == au.PASS
    assert au.check_23(ar, e)[0].status == au.INFO
    _, facts = au.order_checks(ar, e)
    assert facts["order:pair"] == 5 and au.predicted_order(tab, facts) == 5
    assert facts["R_inf:A"] == "0" and facts["R_inf:A_hat"] == "inf"


def test_inconsistent_tableau_fails_although_22_and_theorem1_hold():
    """(22) can hold for a method that does not converge (b = 2): the consistency check fails."""
    tab = au.safe_load_tableau(EX / "inconsistent-b2.json")
    ar, e = au.oc.arith_for(tab)
    assert au.check_22b(ar, e).status == au.PASS
    res = au.audit(tab, quick=True, theorem_scenes=("skate",))
    assert res.get("consistent").status == au.FAIL and res.exit_code == 1
    assert res.get("theorem1:skate").status == au.PASS      # the geometry is still there


def test_symmetry_summary_fails_when_nothing_is_decided(monkeypatch):
    from ldaspark.analysis import discrete, symmetry
    monkeypatch.setattr(discrete, "theorem1_residuals", lambda *a, **k: _fake_t1())
    monkeypatch.setattr(symmetry, "check_symmetry", _raising("reverse BVP failed"))
    by = _statuses(hyp23=True)
    assert by["symmetry:skate"] == au.SKIP and by["symmetry"] == au.FAIL


def _gauss3_with_omega(omega, kind="exact"):
    import sys
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from audit_writings import builtin, written
    from ldaspark.core.tableau_file import from_json_dict
    c, A, b, Ah, At = builtin("gauss-3")
    d = written(c, A, b, kind, Ah, At)
    if omega is not None:
        d["omega"] = omega
    return from_json_dict(d)


def test_symmetry_needs_omegas_rows_to_be_closed_under_reversal():
    """(23a-d) make the method symmetric for the omega of [26, 27] (rows b_j c_j^(i-1): reversed,
    b_j (1 - c_j)^(i-1), they span the same rows); for an omega whose reversed rows
    omega_(i,s+1-j) leave its row space, the adjoint's (21e) is another equation and the method is
    not symmetric. Gauss-3 with omega = rows of the identity passed (23) ("the method is
    symmetric") while the symmetry identities fail on the particle by 1.7e-7 (tolerance 1e-15).
    The check '23-omega' decides the rank of [omega; omega reversed] like omega's (identity: sigma_3
    = 1). Controls: omega = [1 1 1; 1 0 -1] (reversal-invariant, not the default) passes and the
    particle's identities hold to 1e-30; the default omega passes exactly and printed to 10 digits."""
    by = lambda tab: {c.name: c for c in au.algebraic_checks(tab, *au.decide_arith(tab, 30)[:2], 30)[0]}
    facts = lambda tab: au.algebraic_checks(tab, *au.decide_arith(tab, 30)[:2], 30)[1]
    bad = _gauss3_with_omega([["1", "0", "0"], ["0", "1", "0"]])
    chk = by(bad)["23-omega"]
    assert chk.status == au.INFO and chk.residual > 0.5 > 1e-10 > chk.tolerance, (chk.residual, chk.tolerance)
    assert all(by(bad)[k].status == au.PASS for k in ("23a", "23b", "23c", "23d")) and not facts(bad)["23"]
    good = _gauss3_with_omega([["1", "1", "1"], ["1", "0", "-1"]])
    assert by(good)["23-omega"].status == au.PASS and facts(good)["23"]
    for kind in ("exact", "10"):
        tab = _gauss3_with_omega(None, kind)
        assert by(tab)["23-omega"].status == au.PASS and facts(tab)["23"], kind
    # the measurement the condition predicts: the identities fail without it, hold with it
    sym = lambda tab: next(c for c in au.theorem1_checks(tab, True, True, 30, True, ("particle",))[0]
                           if c.name == "symmetry:particle")
    assert sym(bad).status == au.FAIL and sym(bad).residual > 1e-8
    assert sym(good).status == au.PASS and sym(good).residual < 1e-25
