"""Verdict rules fed inputs on which the right answer and a plausible wrong one differ.

Each test targets one rule that decides a verdict or a reported number and feeds it a
constructed input where the neighbouring (wrong) rule gives another result:

* the checkpoint fingerprint: every piece of a run's identity (each config item, the source
  and test files, their names) changes it, and the callers (the ledger, the mutation runner)
  put every option that changes their records into it;
* the ledger's record of the 4.1 anti-symmetries: exactly one of the three identities fails
  (and exactly one side of a pair in the computation itself);
* the audit's Theorem 1 summary: exactly one of four scenes fails, in every position;
* the stiffness study's growth ratio: its value and direction on a constructed energy record;
* the flow Jacobian's dependent velocities on a system with two constraints whose dependent
  block is neither diagonal nor symmetric, against a 40-digit finite difference along a curve
  that stays on the constraint manifold (solved independently here).

Cost: ~10 s (the flow Jacobian at 40 digits; everything else is monkeypatched)."""
import argparse
import json
import types

import mpmath
import numpy as np
import pytest
import sympy

from ldaspark import executors as workers
from ldaspark.core.families import get_method
from ldaspark.core.system import LagrangianSystem


# --- the checkpoint fingerprint ------------------------------------------------------------------
def test_each_config_item_changes_the_fingerprint():
    base = ("run", True, ("a", "b"), 3)
    f0 = workers.source_fingerprint(*base)
    assert workers.source_fingerprint(*base) == f0                       # deterministic
    for i in range(len(base)):
        other = list(base)
        other[i] = {0: "other-run", 1: False, 2: ("a",), 3: 4}[i]
        assert workers.source_fingerprint(*other) != f0, i
    # order matters too (a swapped pair of options is another run)
    assert workers.source_fingerprint("run", ("a", "b"), True, 3) != f0
    # a dict option: its values count, not only its keys
    assert workers.source_fingerprint({"k": 1}) != workers.source_fingerprint({"k": 2})


def test_the_files_under_dirs_change_the_fingerprint(tmp_path):
    d = tmp_path / "tests"
    d.mkdir()
    (d / "test_a.py").write_text("x = 1\n")
    (d / "notes.txt").write_text("not source\n")
    f0 = workers.source_fingerprint("r", dirs=(d,))
    assert f0 != workers.source_fingerprint("r"), "dirs ignored"
    (d / "notes.txt").write_text("changed\n")                           # not a .py file
    assert workers.source_fingerprint("r", dirs=(d,)) == f0
    (d / "test_a.py").write_text("x = 2\n")                             # content
    f1 = workers.source_fingerprint("r", dirs=(d,))
    assert f1 != f0
    (d / "test_a.py").rename(d / "test_b.py")                           # name, same content
    f2 = workers.source_fingerprint("r", dirs=(d,))
    assert f2 != f1
    sub = d / "sub"
    sub.mkdir()
    (sub / "test_c.py").write_text("")                                  # a new (empty) file below
    assert workers.source_fingerprint("r", dirs=(d,)) != f2
    # a second directory counts as well as the first
    e = tmp_path / "verification"
    e.mkdir()
    (e / "test_v.py").write_text("y = 1\n")
    g0 = workers.source_fingerprint("r", dirs=(d, e))
    (e / "test_v.py").write_text("y = 2\n")
    assert workers.source_fingerprint("r", dirs=(d, e)) != g0


def test_a_checkpoint_of_another_identity_is_not_resumed(tmp_path):
    path = tmp_path / "run.partial.jsonl"
    ck = workers.Checkpoint(path, workers.source_fingerprint("r", 1)).open({})
    ck.add("u", {"v": 1})
    ck.close()
    assert workers.Checkpoint(path, workers.source_fingerprint("r", 1)).load() == {"u": {"v": 1}}
    assert workers.Checkpoint(path, workers.source_fingerprint("r", 2)).load() == {}


class _Stop(Exception):
    pass


def _ledger_identity(monkeypatch, tmp_path, quick, groups=None):
    from ldaspark.lab.reports import claims
    seen = {}

    def fake_run_ledger(*a, checkpoint=None, **k):
        seen["fp"], seen["path"], seen["kw"] = checkpoint.fingerprint, checkpoint.path, k
        raise _Stop
    monkeypatch.setattr(claims, "run_ledger", fake_run_ledger)
    if groups is not None:
        monkeypatch.setattr(claims._ledger, "CLAIM_GROUPS", groups)
    with pytest.raises(_Stop):
        claims.run_verify(outdir=str(tmp_path), quick=quick)
    return seen


def test_the_ledgers_run_identity_has_every_option_that_changes_its_records(monkeypatch, tmp_path):
    full = _ledger_identity(monkeypatch, tmp_path, False)
    quick = _ledger_identity(monkeypatch, tmp_path, True)
    # quick changes the scenes, the tableaux and the claim groups' pieces: another identity
    assert quick["kw"] != full["kw"]
    assert quick["fp"] != full["fp"]
    # the claim groups run: another list, another identity
    # negative control: the same options give the same identity (a resumed run is possible)
    assert _ledger_identity(monkeypatch, tmp_path, False)["fp"] == full["fp"]
    other = _ledger_identity(monkeypatch, tmp_path, False, groups=("ldaspark.lab.claims.claims_general:records",))
    assert other["fp"] != full["fp"]


def _mutants_identity(monkeypatch, tmp_path, **over):
    from ldaspark.lab.mutants import command as mutation
    seen = {}

    def fake_run_catalogue(mutants, jobs=2, hints_only=False, checkpoint=None, **k):
        seen["fp"], seen["hints_only"], seen["exclude"] = checkpoint.fingerprint, hints_only, k.get("exclude")
        raise _Stop
    monkeypatch.setattr(mutation, "run_catalogue", fake_run_catalogue)
    monkeypatch.setattr(mutation, "run_control", lambda *a, **k: {})
    # the identity only: the catalogue's own snippet check is another test's business
    monkeypatch.setattr(mutation, "snippet_problems", lambda *a, **k: [])
    args = dict(quick=False, outdir=str(tmp_path), jobs=1, only=None, exclude="", scheduler=None, fresh=False,
                generated=None)
    args.update(over)
    with pytest.raises(_Stop):
        mutation.run(argparse.Namespace(**args))
    return seen


def test_the_mutation_runs_identity_has_every_option_that_changes_its_records(monkeypatch, tmp_path):
    base = _mutants_identity(monkeypatch, tmp_path)
    quick = _mutants_identity(monkeypatch, tmp_path, quick=True)
    assert quick["hints_only"] and not base["hints_only"]          # quick changes what runs...
    assert quick["fp"] != base["fp"]                               # ...so it changes the identity
    excl = _mutants_identity(monkeypatch, tmp_path, exclude="tests/core/test_spark.py")
    assert excl["exclude"] == ("tests/core/test_spark.py",)
    assert excl["fp"] != base["fp"]
    # options that do not change a record keep it (a resumed run with more jobs is possible)
    assert _mutants_identity(monkeypatch, tmp_path, jobs=2)["fp"] == base["fp"]


# --- the ledger's anti-symmetry record -------------------------------------------------------------
def _fake_section5(monkeypatch, anti):
    """section5_records on constructed results: every identity holds (1e-30) and every control
    fails (1e-3), except the anti-symmetry results ``anti(scene)``."""
    from ldaspark.lab.claims import claims_paper as cp
    ident = {k: 1e-30 for k in ("16", "18", "17", "19", "20b-corrected")}
    ident.update({"16-without-force": 1e-3, "18-without-force": 1e-3, "20b-printed": 1e-3, "f_d_minus": 1.0,
                  "k0": 0.0})
    monkeypatch.setattr(cp, "exact_identities", lambda scn, **k: dict(ident))
    monkeypatch.setattr(cp, "antisymmetry", lambda scn, **k: anti(scn))
    monkeypatch.setattr(cp, "holonomic_exact",
                        lambda scn, **k: {"tangential": 1e-30 if scn == "pendulum" else 1e-3, "full": 1.0})
    return cp.section5_records(quick=True)


def _anti_status(recs):
    return [(r["scene"], r["status"]) for r in recs if r["claim"] == "antisymmetry-exact" and "control" not in r["method"]]


@pytest.mark.parametrize("bad", ["L", "f_plus", "f_minus"])
def test_the_antisymmetry_record_fails_when_one_identity_fails(monkeypatch, bad):
    good = {"L": 1e-30, "f_plus": 1e-30, "f_minus": 1e-30, "wrong-pairing": 1.0}
    recs = _fake_section5(monkeypatch, lambda scn: dict(good, **({bad: 1e-10} if scn == "rheonomic-skate" else {})))
    assert _anti_status(recs) == [("particle", "pass"), ("rheonomic-skate", "fail")]
    rec = [r for r in recs if r["claim"] == "antisymmetry-exact" and r["scene"] == "rheonomic-skate"][0]
    assert rec["residual"] == pytest.approx(1e-10)
    # negative control: all three hold -> pass on both scenes
    recs = _fake_section5(monkeypatch, lambda scn: dict(good))
    assert _anti_status(recs) == [("particle", "pass"), ("rheonomic-skate", "pass")]


def test_the_antisymmetry_control_record_is_the_wrong_pairing(monkeypatch):
    good = {"L": 1e-30, "f_plus": 1e-30, "f_minus": 1e-30, "wrong-pairing": 1e-30}
    recs = _fake_section5(monkeypatch, lambda scn: dict(good))
    ctl = [r["status"] for r in recs if r["claim"] == "antisymmetry-exact" and "control" in r["method"]]
    assert ctl == ["pass", "pass"]          # a control that is satisfied: "pass" against expected "fail"


def _fake_bvp(Ld, fm, fp):
    return types.SimpleNamespace(L_d=mpmath.mpf(Ld), f_d_minus=np.array([mpmath.mpf(x) for x in fm], dtype=object),
                                 f_d_plus=np.array([mpmath.mpf(x) for x in fp], dtype=object),
                                 v0=np.array([mpmath.mpf(0)], dtype=object), v1=np.array([mpmath.mpf(0)], dtype=object))


def _antisymmetry_on(monkeypatch, fw, rv):
    """section5.antisymmetry on a fake exact flow whose forward and reverse solves are given."""
    from ldaspark.lab.theory import section5
    monkeypatch.setattr(section5, "endpoints", lambda *a, **k: ("t0", "q0", "t1", "q1"))
    flow = types.SimpleNamespace(bvp=lambda t0, q0, t1, q1: fw if t0 == "t0" else rv)
    monkeypatch.setattr(section5, "flow_for", lambda *a, **k: flow)
    return section5.antisymmetry.__wrapped__("particle")


def test_the_antisymmetry_computation_pairs_each_side_with_the_other():
    """f^{E+}(rev) = -f^{E-}(fwd) and f^{E-}(rev) = -f^{E+}(fwd): a reverse solve that satisfies the
    first pair only fails the second (and vice versa); L^E(rev) = -L^E(fwd) on its own."""
    mp = pytest.MonkeyPatch()
    try:
        fw = _fake_bvp(2, ["1", "3"], ["5", "7"])
        r = _antisymmetry_on(mp, fw, _fake_bvp(-2, ["-5", "-7"], ["-1", "-3"]))     # all hold
        assert r["L"] == 0 and r["f_plus"] == 0 and r["f_minus"] == 0
        assert r["wrong-pairing"] == pytest.approx(4 / 7)          # |f+(rev) + f+(fwd)| = |(-1+5, -3+7)| / 7
        r = _antisymmetry_on(mp, fw, _fake_bvp(-2, ["-5", "-6"], ["-1", "-3"]))     # f^- (rev) off by 1
        assert r["f_plus"] == 0 and r["f_minus"] == pytest.approx(1 / 7) and r["L"] == 0
        r = _antisymmetry_on(mp, fw, _fake_bvp(-2, ["-5", "-7"], ["-1", "-2"]))     # f^+ (rev) off by 1
        assert r["f_minus"] == 0 and r["f_plus"] == pytest.approx(1 / 7)
        r = _antisymmetry_on(mp, fw, _fake_bvp(-1, ["-5", "-7"], ["-1", "-3"]))     # L_d(rev) off
        assert r["L"] == pytest.approx(0.5) and r["f_plus"] == 0 and r["f_minus"] == 0
    finally:
        mp.undo()


# --- the audit's Theorem 1 verdict ------------------------------------------------------------------
SCENES4 = ("particle", "skate", "robot", "mp-particles")


def _fake_t1(**over):
    r = {"theorem1-q0": 1e-40, "theorem1-q1": 1e-40, "fd_error": 1e-35, "without_forces_q0": 1.0,
         "wellposed": "well-posed", "rank_deficiency": 0, "dps": 30, "dps_fd": 50}
    r.update(over)
    return r


def _theorem1(monkeypatch, per_scene):
    from ldaspark.lab.theory import audit as au
    from ldaspark.analysis import discrete
    monkeypatch.setattr(discrete, "theorem1_residuals", lambda system, *a, **k: per_scene(system.name))
    checks, _ = au.theorem1_checks(get_method("gauss-1"), True, False, 30, True, SCENES4)
    return {c.name: c for c in checks}


@pytest.mark.parametrize("bad", SCENES4)
@pytest.mark.parametrize("side", ["theorem1-q0", "theorem1-q1"])
def test_theorem1_fails_when_exactly_one_scene_fails(monkeypatch, bad, side):
    from ldaspark.lab.theory import audit as au
    by = _theorem1(monkeypatch, lambda scn: _fake_t1(**({side: 1e-3} if scn == bad else {})))
    assert [by[f"theorem1:{s}"].status for s in SCENES4] == [au.FAIL if s == bad else au.PASS for s in SCENES4]
    assert by["theorem1"].status == au.FAIL
    assert by["theorem1"].residual == pytest.approx(1e-3)              # the worst scene, not the first
    assert "1 failing" in by["theorem1"].detail and "4 of 4" in by["theorem1"].detail


def test_theorem1_passes_only_when_every_decided_scene_passes(monkeypatch):
    from ldaspark.lab.theory import audit as au
    by = _theorem1(monkeypatch, lambda scn: _fake_t1())
    assert by["theorem1"].status == au.PASS and "0 failing" in by["theorem1"].detail
    # one undecided scene (tolerance without teeth) and three passing: still decided, passes
    by = _theorem1(monkeypatch, lambda scn: _fake_t1(**({"fd_error": 1e-3} if scn == "robot" else {})))
    assert by["theorem1:robot"].status == au.SKIP and by["theorem1"].status == au.PASS
    assert "3 of 4" in by["theorem1"].detail
    # one undecided and one failing: fails
    by = _theorem1(monkeypatch, lambda scn: _fake_t1(**({"fd_error": 1e-3} if scn == "robot" else
                                                      {"theorem1-q1": 1e-3} if scn == "skate" else {})))
    assert by["theorem1"].status == au.FAIL
    # decided on exactly two (the minimum): passes; on one: fails
    by = _theorem1(monkeypatch, lambda scn: _fake_t1(**({"fd_error": 1e-3} if scn in ("robot", "skate") else {})))
    assert by["theorem1"].status == au.PASS
    by = _theorem1(monkeypatch, lambda scn: _fake_t1(**({"fd_error": 1e-3} if scn != "particle" else {})))
    assert by["theorem1"].status == au.FAIL and "at least 2" in by["theorem1"].detail


def test_theorem1_summary_rule_directly():
    from ldaspark.lab.theory import audit as au
    C = au.Check

    def summary(*st):
        return au._theorem1_summary([C(f"theorem1:s{i}", x, 1e-9 * (i + 1), "") for i, x in enumerate(st)]
                                    + [C("22a", au.FAIL, 1.0, "")])       # other checks do not count
    P, F, S = au.PASS, au.FAIL, au.SKIP
    assert summary(P, P, P, P).status == P
    for i in range(4):
        st = [P] * 4
        st[i] = F
        assert summary(*st).status == F, i
    assert summary(P, S, S, S).status == F          # decided on 1 < 2
    assert summary(P, P, S, S).status == P
    assert summary(P).status == P                  # one scene given: one suffices
    assert summary(S).status == F
    assert summary(P, P, P, P).residual == pytest.approx(4e-9)


# --- the stiffness study's growth ratio --------------------------------------------------------------
def _stiff_row(monkeypatch, energy):
    from ldaspark.compiled import fast
    from ldaspark.lab.reports import stability_stiff as st
    sol = types.SimpleNamespace(energy=np.asarray(energy, float), constraint=np.zeros(len(energy)),
                                stats={"mean_iterations": 2.0, "max_iterations": 3})
    monkeypatch.setattr(fast, "fast_integrate", lambda *a, **k: sol)
    return st.stiff_run("stiff-particle", "gauss-2", 0.5, n=len(energy) - 1)


def test_the_growth_ratio_is_second_half_over_first_half(monkeypatch):
    from ldaspark.lab.reports.stability_stiff import DE_GROWTH, classify
    # E0 = 2: relative errors 0, 1e-6, 2e-6, 1e-6, | 5e-6, 1e-5, 4e-6, 3e-6  (half = 4)
    rel = [0, 1e-6, 2e-6, 1e-6, 5e-6, 1e-5, 4e-6, 3e-6]
    row = _stiff_row(monkeypatch, [2 * (1 + x) for x in rel])
    assert row["outcome"] == "ok"
    assert row["dE_growth"] == pytest.approx(5.0, rel=1e-9)            # 1e-5 / 2e-6, not 2e-6 / 1e-5
    assert row["max_rel_dE"] == pytest.approx(1e-5, rel=1e-9)
    assert DE_GROWTH < 5.0 and classify(row) == "growing"
    # the same errors in reverse order: decaying, ratio 1/5, bounded
    row = _stiff_row(monkeypatch, [2 * (1 + x) for x in [0, 3e-6, 4e-6, 1e-5, 5e-6, 1e-6, 2e-6, 1e-6]])
    assert row["dE_growth"] == pytest.approx(0.5, rel=1e-9)            # 5e-6 / 1e-5
    assert classify(row) == "bounded"
    # energy errors below the round-off threshold are not judged, whatever their ratio
    row = _stiff_row(monkeypatch, [2 * (1 + x) for x in [0, 1e-12, 1e-12, 1e-12, 1e-10, 1e-10, 1e-10, 1e-10]])
    assert row["dE_growth"] == pytest.approx(100.0, rel=1e-3) and classify(row) == "bounded"


def test_the_growth_classification_thresholds():
    from ldaspark.lab.reports.stability_stiff import DE_GROWTH, classify
    ok = {"outcome": "ok", "max_rel_dE": 1e-3}
    assert classify(dict(ok, dE_growth=DE_GROWTH * 1.01)) == "growing"
    assert classify(dict(ok, dE_growth=DE_GROWTH)) == "bounded"         # strictly above
    assert classify(dict(ok, dE_growth=None)) == "bounded"
    assert classify(dict(ok, dE_growth=10.0, max_rel_dE=1e-9)) == "bounded"
    assert classify({"outcome": "NewtonError"}) == "failed"


# --- the flow Jacobian's dependent velocities ---------------------------------------------------------
def two_constraints():
    """n = 4, m = 2, k = (v3 + q2 v4 - cos(q1) v1, v4 + (1 + q3) v3 - q1 v2): the dependent block
    K_dep = [[1, q2], [1 + q3, 1]] is neither diagonal nor symmetric and k_q != 0."""
    q, v = sympy.symbols("q1:5"), sympy.symbols("v1:5")
    L = sum(x ** 2 for x in v) / 2 - (q[0] ** 2 + 2 * q[1] ** 2 + q[2] ** 2 / 2 + q[3] ** 2 / 3) / 2
    k = [v[2] + q[1] * v[3] - sympy.cos(q[0]) * v[0], v[3] + (1 + q[2]) * v[2] - q[0] * v[1]]
    return LagrangianSystem(L, k, q, v, name="two-constraints"), q, v, k


def _consistent_v(kfun, q, vfree, dps):
    """v3, v4 with k(q, v) = 0 (k linear in v3, v4: one exact 2x2 solve at dps digits)."""
    with mpmath.workdps(dps):
        a = kfun(q, [vfree[0], vfree[1], 0, 0])
        c3 = [kfun(q, [vfree[0], vfree[1], 1, 0])[i] - a[i] for i in range(2)]
        c4 = [kfun(q, [vfree[0], vfree[1], 0, 1])[i] - a[i] for i in range(2)]
        M = mpmath.matrix([[c3[0], c4[0]], [c3[1], c4[1]]])
        x = mpmath.lu_solve(M, mpmath.matrix([-a[0], -a[1]]))
        return [vfree[0], vfree[1], x[0], x[1]]


def test_dependent_velocities_against_a_40_digit_difference_on_the_manifold():
    import ldaspark
    sysm, qs, vs, k = two_constraints()
    kl = sympy.lambdify((qs, vs), k, modules="mpmath")

    def kfun(q, v):
        return [mpmath.mpf(x) for x in kl(q, v)]
    dps = 40
    with mpmath.workdps(dps):
        q0 = [mpmath.mpf(x) for x in ("0.3", "-0.2", "0.4", "0.1")]
        v0 = _consistent_v(kfun, q0, [mpmath.mpf("0.5"), mpmath.mpf("-0.7")], dps)
        fj = ldaspark.flow_jacobian(sysm, "gauss-2", q0, v0, "0.1", dps=dps, coords=["q1", "q2"],
                                    rates=["v1", "v2"])
        B = fj.tangent
        # the tangent basis satisfies the linearised constraint k_q dq + k_v dv = 0 (to 40 digits)
        Kq = sympy.Matrix(k).jacobian(qs)
        Kv = sympy.Matrix(k).jacobian(vs)
        sub = dict(zip(qs + vs, q0 + v0))
        Kq_ = np.array([[mpmath.mpf(sympy.N(Kq[i, j].subs(sub), 50)) for j in range(4)] for i in range(2)], dtype=object)
        Kv_ = np.array([[mpmath.mpf(sympy.N(Kv[i, j].subs(sub), 50)) for j in range(4)] for i in range(2)], dtype=object)
        lin = Kq_.dot(B[:4, :]) + Kv_.dot(B[4:, :])
        assert max(abs(x) for x in lin.reshape(-1)) < mpmath.mpf(10) ** -35
        # each column of J against a central difference of the step along a curve on the
        # manifold: q_i (or v_j) moves by +-d, the dependent v3, v4 solved from k = 0 exactly
        from ldaspark.core.spark import SparkMethod
        sm = SparkMethod(sysm, get_method("gauss-2"), dps=dps, newton="full")
        d = mpmath.mpf(10) ** -13
        S = fj.select
        worst = 0
        for col, (kind, idx) in enumerate([("q", 0), ("q", 1), ("v", 0), ("v", 1)]):
            outs = []
            for sgn in (1, -1):
                q = list(q0)
                vf = [v0[0], v0[1]]
                if kind == "q":
                    q[idx] += sgn * d
                else:
                    vf[idx] += sgn * d
                v = _consistent_v(kfun, q, vf, dps)
                r = sm.step(mpmath.mpf(0), np.array(q, dtype=object), np.array(v, dtype=object), mpmath.mpf("0.1"))
                outs.append(np.concatenate([r.q1, r.v1]))
            fd = (outs[0] - outs[1]) / (2 * d)
            for row, s_ in enumerate(S):
                worst = max(worst, abs(fj.J[row, col] - fd[s_]))
        # truncation d^2 ~ 1e-26, round-off 1e-40 / d = 1e-27; a float64 solve or a dropped
        # coupling of the dependent block is off by >= 1e-17
        assert worst < mpmath.mpf(10) ** -22, worst
        # negative control: the naive basis (dependent velocities left fixed) is far off
        naive = fj.full[S, :][:, [0, 1, 4, 5]]
        assert max(abs(naive[r_, c_] - fj.J[r_, c_]) for r_ in range(4) for c_ in range(4)) > 1e-3


def test_the_default_dependent_velocities_are_outside_the_rates():
    import ldaspark
    sysm, *_ = two_constraints()
    fj = ldaspark.flow_jacobian(sysm, "gauss-1", [0.3, -0.2, 0.4, 0.1], [0.5, -0.7, 0.0, 0.0], 0.1,
                                coords=["q1"], rates=["v1", "v2"])
    B = np.asarray(fj.tangent, float)
    # the rates' own entries are unit vectors; the dependent rows v3, v4 carry the correction
    assert B[4, 1] == 1 and B[5, 2] == 1 and B[4, 2] == 0 and B[5, 1] == 0
    assert np.any(B[6:, :] != 0)
    assert fj.select == [0, 4, 5]
    assert json.dumps(fj.select)
