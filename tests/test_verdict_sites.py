"""Every any/all, worst-case and ratio rule of the checking code, fed an input on which the rule
and its plausible neighbour differ (one of several items fails; two sides of a pair differ; a
ratio that is not 1 and not symmetric under inversion).

The rules are small pure functions or take constructed records, so the whole file runs in about
a second: a fault planted in one of these rules (``any`` for ``all``, one side of a pair, a ratio
upside down, the best item for the worst) fails here without running a computation."""
import math

import mpmath
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ldaspark.core.errors import InputError
from ldaspark.theory import audit as au
from ldaspark.theory import orders


def _close(x, rel=1e-9, abs=0.0):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny residuals."""
    return pytest.approx(x, rel=rel, abs=abs)


# --- orders: step sizes, method-scope verdicts --------------------------------------------------------
def test_step_sizes_must_decrease_at_every_step():
    errs = [1e-2, 1e-3, 1e-4]
    orders.estimate_order([0.1, 0.05, 0.025], errs, 1e-15)                 # strictly decreasing: accepted
    for hs in ([0.1, 0.05, 0.1], [0.1, 0.2, 0.05], [0.1, 0.1, 0.05], [0.1, 0.05, 0.05]):
        # one bad pair among two (any, not all), equal steps too (>=, not >)
        with pytest.raises(InputError):
            orders.estimate_order(hs, errs, 1e-15)


def _rec(method, scene, variable, observed, claimed=2, scope="variable"):
    return {"method": method, "scene": scene, "variable": variable, "observed_order": observed,
            "claimed_order": claimed, "claim_scope": scope}


def test_a_method_scope_verdict_takes_the_worse_of_q_and_v():
    rec = _rec("m", "s", "q", 2.0, scope="method")
    # q at 2, v at 4: the method's order is min = 2 (max would say HIGHER than claimed)
    recs = [rec, _rec("m", "s", "v", 4.0), _rec("m", "other", "v", 1.0), _rec("n", "s", "v", 1.0)]
    assert orders.verdict(rec, recs) == "holds"
    # the worse one fails: the verdict fails although q alone holds
    recs = [rec, _rec("m", "s", "v", 1.2)]
    assert orders.verdict(rec, recs) == "FAILS"
    # one of the two has no window: no window (not: the other decides)
    recs = [rec, _rec("m", "s", "v", None)]
    assert orders.verdict(rec, recs) == "NO WINDOW"
    # both above the claim by more than tol: higher
    recs = [_rec("m", "s", "q", 3.0, scope="method"), _rec("m", "s", "v", 3.5)]
    assert orders.verdict(recs[0], recs) == "HIGHER than claimed"


@settings(deadline=None)
@given(o=st.floats(0.5, 6.0), c=st.integers(1, 5))
def test_an_order_verdict_is_two_sided(o, c):
    rec = _rec("m", "s", "q", o, claimed=c)
    assert orders.verdict(rec) == ("holds" if abs(o - c) <= 0.3 else "FAILS")


# --- the audit's aggregate rules -------------------------------------------------------------------------
C = au.Check
P, F, S, I = au.PASS, au.FAIL, au.SKIP, au.INFO


def _result(*statuses):
    return au.AuditResult("t", 2, True, 30, True, checks=[C(f"c{i}", x, None, "") for i, x in enumerate(statuses)])


def test_the_exit_code_is_one_when_any_check_fails():
    assert _result(P, P, I, S).exit_code == 0
    assert _result(P, F, P).exit_code == 1
    assert _result(F).exit_code == 1
    assert _result(P, P, F).as_dict()["exit_code"] == 1


def test_entry_tolerances_need_every_condition_to_hold_and_take_the_largest_residual():
    good = [C("22a", P, 1e-20, ""), C("22b", P, 3e-20, ""), C("23a", P, 2e-18, ""), C("23b", P, 1e-18, ""),
            C("23c", P, 0.0, ""), C("23d", P, None, ""), C("theorem1", F, 1.0, "")]
    t22, t23 = au.entry_tolerances(good)
    assert t22 == _close(au.ENTRY_TOL_FACTOR * 3e-20)          # the larger, not the first
    assert t23 == _close(au.ENTRY_TOL_FACTOR * 2e-18)
    for k in range(6):
        bad = list(good)
        bad[k] = C(bad[k].name, F if k < 2 else I, 1e-3, "")
        t22b, t23b = au.entry_tolerances(bad)
        # one condition missed: its group is judged at full strength (0), the other keeps its tolerance
        assert (t22b, t23b) == ((0.0, t23) if k < 2 else (t22, 0.0)), k
    assert au.entry_tolerances([C("23a", P, 1e-9, "")]) == (0.0, _close(au.ENTRY_TOL_FACTOR * 1e-9))


def test_the_symmetry_fact_needs_all_four_of_23_and_22_needs_both(monkeypatch):
    import ldaspark.theory.audit as mod
    from ldaspark.core.families import get_method

    tab = get_method("gauss-2")
    ar, e, _ = au.decide_arith(tab, 30)
    for k in range(6):
        cs = [C("22a", P, 0.0, ""), C("22b", P, 0.0, "")] + [C(f"23{x}", P, 0.0, "") for x in "abcd"]
        cs[k] = C(cs[k].name, F if k < 2 else I, 1.0, "")
        monkeypatch.setattr(mod, "check_22a", lambda ar, e, c=cs[0]: c)
        monkeypatch.setattr(mod, "check_22b", lambda ar, e, c=cs[1]: c)
        monkeypatch.setattr(mod, "check_23", lambda ar, e, c=cs[2:]: list(c))
        _, facts = au.algebraic_checks(tab, ar, e, 30)
        assert (facts["22"], facts["23"]) == ((False, True) if k < 2 else (True, False)), k


# --- the ledger's proof conditions: every entry, both sides ------------------------------------------------
def test_the_proof_conditions_need_every_entry():
    """q0 and q1 of the proof of Theorem 1 hold when every (i, j) entry vanishes: on gauss-2 with one
    entry of A_hat (resp. b_hat) moved, some entries vanish and others do not (all, not any);
    moving b_hat changes q1 only (its own side of the pair)."""
    from ldaspark.claims.ledger import proof_conditions
    from ldaspark.core.families import get_method
    tab = get_method("gauss-2", exact=True)

    def zeros(t):
        K, e = t.field_entries()
        b, bh, A, Ah = e["b"], e["b_hat"], e["A"], e["A_hat"]
        rng = range(t.s)
        return ([b[j] * A[j][i] + b[i] * Ah[i][j] - b[j] * b[i] == K.zero for i in rng for j in rng],
                [b[j] * A[j][i] + b[i] * Ah[i][j] - bh[j] * b[i] == K.zero for i in rng for j in rng])
    assert proof_conditions(tab) == (True, True)
    t_ah = tab.with_entry("A_hat", 0, 1, "1/10")
    z0, z1 = zeros(t_ah)
    assert any(z0) and not all(z0) and any(z1) and not all(z1)        # the input separates all from any
    assert proof_conditions(t_ah) == (False, False)
    t_bh = tab.with_entry("b_hat", 1, None, "1/10")
    z0, z1 = zeros(t_bh)
    assert all(z0) and any(z1) and not all(z1)
    assert proof_conditions(t_bh) == (True, False)


# --- ratios: the right way up ---------------------------------------------------------------------------
@settings(deadline=None)
@given(p=st.floats(0.5, 8.0), c=st.floats(1e-3, 1e3), h0=st.floats(0.01, 1.0), k=st.integers(2, 5))
def test_pairwise_orders_recover_the_power(p, c, h0, k):
    # errors c h^p at h0 / 2^j: every pairwise order is p (either quotient upside down gives -p)
    hs = [h0 / 2 ** j for j in range(k)]
    out = orders.pairwise_orders(hs, [c * h ** p for h in hs])
    assert out == _close([p] * (k - 1), rel=1e-9, abs=1e-9)
    # a zero error has no order; the neighbouring pairs keep theirs
    out = orders.pairwise_orders(hs, [c * h ** p for h in hs[:-1]] + [0.0])
    assert out[-1] is None and all(o == _close(p, rel=1e-9) for o in out[:-1])


def _cost_rows(kind, method, pairs):
    return [{"kind": kind, "method": method, "error": e, "cpu": c} for e, c in pairs]


def test_the_speedup_is_peer_cost_over_spark_cost():
    from ldaspark.reports import peers
    # SPARK reaches 1e-6 at 1 s, the peer at 4 s (both bracket the target, log-interpolated on the envelope)
    rows = (_cost_rows("spark", "s1", [(1e-4, 0.5), (1e-8, 2.0)]) + _cost_rows("spark", "s2", [(1e-4, 3.0), (1e-8, 9.0)])
            + _cost_rows("peer", "p1", [(1e-4, 2.0), (1e-8, 8.0)]) + _cost_rows("peer", "p2", [(1e-4, 7.0), (1e-8, 30.0)]))
    (r,) = peers.speedups(rows, [1e-6])
    assert r["spark"] == "s1" and r["peer"] == "p1"                   # the cheapest of each side
    assert r["speedup"] == _close(r["peer_cpu"] / r["spark_cpu"]) and r["speedup"] > 1
    assert r["speedup"] == _close(4.0, rel=1e-9)
    # the sides swapped: the reciprocal
    sw = [dict(x, kind={"spark": "peer", "peer": "spark"}[x["kind"]]) for x in rows]
    assert peers.speedups(sw, [1e-6])[0]["speedup"] == _close(0.25, rel=1e-9)


@settings(deadline=None)
@given(first=st.floats(1e-8, 1e-3), factor=st.floats(0.05, 20.0))
def test_boundedness_is_last_quarter_over_first(first, factor):
    import numpy as np

    from ldaspark.reports.energy import boundedness
    from ldaspark.reports.systems import _bounded, BOUNDED_RATIO, DRIFT_RATIO
    n = 401
    t = np.linspace(0.0, 1.0, n)
    e = np.full(n, first)
    e[3 * n // 4 + 2:] = first * factor                               # only the last quarter changes
    e[0] = 0.0
    b = boundedness(t, e)
    # the last quarter's slice starts two samples before the change: its max is max(factor, 1) x first
    assert b["last_over_first_quarter"] == _close(max(factor, 1.0), rel=1e-12)
    r = _bounded(t, e, n - 1, 0.0)          # round-off threshold 100 eps sqrt(400) ~ 4e-13 < first
    assert not r["roundoff"]
    assert r["bounded"] == (b["last_over_first_quarter"] <= BOUNDED_RATIO)
    assert r["drift"] == (b["last_over_first_quarter"] >= DRIFT_RATIO)


def test_the_energy_rate_is_log2_of_coarse_over_fine(monkeypatch):
    import types

    import numpy as np

    from ldaspark.theory import audit_checks as ac
    runs = iter([4e-6, 1e-6])                                         # h then h/2: errors fall 4x: rate 2

    def fake_run(tab, sc, N, T, dps):
        m = next(runs)
        return types.SimpleNamespace(energy=np.array([1.0, 1.0 + m, 1.0 - m / 2]))
    monkeypatch.setattr(ac, "_run", fake_run)
    chk, facts = ac.energy_check(None, True)
    # |E - E0| of 1 + 4e-6 carries a rounding of eps / 4e-6 ~ 6e-11 relative
    assert facts["energy_rate"] == _close(2.0, rel=1e-9)
    assert chk.residual == _close(1e-6) and chk.status == au.INFO
    assert [h for h, _ in facts["energy"]] == [0.1, 0.05]


# --- summary verdicts: all of them, not one -----------------------------------------------------------------
def test_the_convergence_summary_holds_only_when_every_record_holds():
    from ldaspark.reports.summary import convergence_values
    recs = [_rec("gauss-2", "skate", "q", 4.0, 4), _rec("gauss-2", "skate", "v", 4.1, 4),
            _rec("gauss-irk-1", "skate", "q", 2.0, 2), _rec("gauss-irk-2", "skate", "q", 4.0, 4)]
    v = convergence_values(recs)
    assert v["convergence.spark"] == "4 of 4" and v["convergence.spark.verdict"] == "hold"
    recs[1] = _rec("gauss-2", "skate", "v", 3.0, 4)                   # one of four fails
    v = convergence_values(recs)
    assert v["convergence.spark"] == "3 of 4" and v["convergence.spark.verdict"] == "do not all hold"


def _claim(claim, method, status, expected, residual, wellposed="well-posed"):
    return {"claim": claim, "method": method, "scene": "s", "status": status, "expected": expected,
            "residual": residual, "wellposed": wellposed}


def test_the_claims_summary_counts_agreement_and_takes_the_worst_residual():
    from ldaspark.reports.summary import claims_values
    recs = [_claim("22a", "m", "pass", "pass", 0.0), _claim("23", "m", "fail", "pass", 1.0),
            _claim("theorem1-q0", "m", "pass", "pass", 1e-30), _claim("theorem1-q1", "m", "pass", "pass", 3e-28),
            _claim("theorem1-q0", "n", "fail", "pass", 1e-3),
            _claim("theorem1-q0", "negctl-a", "fail", "fail", 2e-2), _claim("theorem1-q1", "negctl-b", "fail", "fail", 5e-4),
            _claim("symmetry-x", "m", "pass", "pass", 2e-25), _claim("symmetry-y", "m", "pass", "pass", 7e-26),
            _claim("16", "m", "pass", "pass", 1e-20), _claim("18", "m", "pass", "pass", 4e-19),
            _claim("antisymmetry-exact", "m", "fail", "pass", 1e-10),
            _claim("antisymmetry-exact", "m", "not-applicable", "pass", None)]
    v = claims_values(recs)
    assert v["claims.conditions"] == "1 of 2"
    assert v["claims.theorem1.max"] == "3.0e-28"                     # the worst passing residual
    assert v["claims.theorem1.negctl_min"] == "5.0e-04"              # the least convincing control
    assert v["claims.theorem1.unexpected"] == "1"
    assert v["claims.symmetry.max"] == "2.0e-25"
    assert v["claims.paper"] == "2 of 3"                              # not-applicable not decided
    assert v["claims.paper.max"] == "4.0e-19"


def test_the_peer_floor_needs_both_sides(monkeypatch):
    from ldaspark.reports import summary
    st_ = {"scene": "sc", "speedups": [], "long_speedups": [],
           "long_rows": [{"kind": "spark", "energy_error": 3e-12, "constraint": 1e-15},
                         {"kind": "spark", "energy_error": 1e-12, "constraint": 2e-15},
                         {"kind": "peer", "energy_error": 5e-9, "constraint": 1e-10},
                         {"kind": "peer", "energy_error": 2e-9, "constraint": 3e-10}],
           "vlong_rows": [{"kind": "spark", "energy_error": 1e-12, "constraint": 1e-15}]}
    out = summary.peers_values({"targets": [], "energy_targets": [], "studies": [st_]})
    assert out["peers.sc.long_floor"] == "1.0e-12 / 2.0e-09"          # the smallest of each side
    assert out["peers.sc.long_floor_k"] == "2e-15 / 3e-10"
    assert "peers.sc.vlong_floor" not in out                          # one side only: no floor


# --- fingerprints: every component of a run's identity ---------------------------------------------------
def _binding(monkeypatch, call):
    from ldaspark.dist import workers
    seen = []

    def fake(work, checkpoint, **kw):
        seen.append(checkpoint.fingerprint)
        return {u.name: [] for u in work}
    monkeypatch.setattr(workers, "run_resumable", fake)
    call(workers.Checkpoint("unused.partial.jsonl", "caller-fp"))
    return seen[-1]


def test_the_ledger_binds_every_setting_that_changes_its_records(monkeypatch):
    from ldaspark.claims import ledger
    base = dict(max_s=1, scenes=("particle",), perturbed=False, holonomic=False, controls=False, groups=(),
                quick=False, jobs=1)
    other = dict(max_s=2, scenes=("skate",), perturbed=True, holonomic=True, controls=True,
                 groups=("ldaspark.claims.claims_general:records",), quick=True)
    fp0 = _binding(monkeypatch, lambda ck: ledger.run_ledger(**base, checkpoint=ck))
    assert fp0 == _binding(monkeypatch, lambda ck: ledger.run_ledger(**base, checkpoint=ck))
    for k, v in other.items():
        fp = _binding(monkeypatch, lambda ck: ledger.run_ledger(**dict(base, **{k: v}), checkpoint=ck))
        assert fp != fp0, k


def test_the_catalogue_binds_every_setting_that_changes_a_verdict(monkeypatch):
    from ldaspark.mutants import mutation
    m = [mutation.by_id(mutation.QUICK[0])]
    base = dict(hints_only=False, exclude=(), targets=None, timeout=300)
    fp0 = _binding(monkeypatch, lambda ck: mutation.run_catalogue(m, 1, checkpoint=ck, **base))
    for k, v in dict(hints_only=True, exclude=("tests/test_spark.py",), targets={m[0].id: ["tests/test_x.py"]},
                     timeout=60).items():
        fp = _binding(monkeypatch, lambda ck: mutation.run_catalogue(m, 1, checkpoint=ck, **dict(base, **{k: v})))
        assert fp != fp0, k       # a shorter timeout turns slow kills into timeouts: another verdict


def test_the_package_source_and_each_library_version_enter_the_fingerprint(tmp_path, monkeypatch):
    import importlib.metadata
    import sys

    from ldaspark.dist import workers
    pkg = tmp_path / "pkg"
    (pkg / "dist").mkdir(parents=True)
    (pkg / "core.py").write_text("A = 1\n")
    (pkg / "notes.txt").write_text("not source\n")
    monkeypatch.setattr(workers, "__file__", str(pkg / "dist" / "workers.py"))
    f0 = workers.source_fingerprint("r")
    (pkg / "notes.txt").write_text("changed\n")
    assert workers.source_fingerprint("r") != f0          # every file of the package: its data too (tableaux)
    f0 = workers.source_fingerprint("r")
    (pkg / "core.py").write_text("A = 2\n")
    f1 = workers.source_fingerprint("r")
    assert f1 != f0                                                        # the package's own source
    ident = workers._environment_identity()
    assert ident[0] == sys.version and len(ident) == 2 + len(workers._FINGERPRINT_DISTS)
    real = importlib.metadata.version
    for name in workers._FINGERPRINT_DISTS:
        def version(n, name=name):
            if n == name:
                return "0.0.0-other"
            return real(n)
        monkeypatch.setattr(importlib.metadata, "version", version)
        assert workers.source_fingerprint("r") != f1, name
    monkeypatch.setattr(importlib.metadata, "version", real)
    assert workers.source_fingerprint("r") == f1
    monkeypatch.setattr(sys, "version", sys.version + " other")
    assert workers.source_fingerprint("r") != f1


# --- the paper's claim group: both quantities of a record, and records that describe their run -------------
def test_a_section7_record_fails_when_either_of_its_two_quantities_fails(monkeypatch):
    from ldaspark.claims import claims_paper as cp
    good, bad = 1e-40, 1e-20                                          # around TOL_S7 = 1e-35
    for diff, stage in ((good, good), (bad, good), (good, bad)):
        monkeypatch.setattr(cp, "reduction", lambda kind, tab, constant_K, d=diff, s=stage:
                            {"diff": d if tab.name != "lobatto-iiia-iiib-2" and kind != "euler-ii" or tab.name !=
                             "euler-i" else 1.0, "stage": s})
        monkeypatch.setattr(cp, "one_newton_iteration", lambda tab, ck, guess: {"after_one": 1e-40 if ck or
                                                                                 tab.name == "euler-ii" else 1.0})
        recs = [r for r in cp.section7_records(True) if r["expected"] == "pass" and r["claim"] != "linearly-implicit-7"]
        assert len(recs) == 3
        assert {r["status"] for r in recs} == {"pass" if (diff, stage) == (good, good) else "fail"}, (diff, stage)
        assert all(r["residual"] == _close(max(diff, stage)) for r in recs)


def test_an_energy_balance_record_takes_the_worse_of_pointwise_and_integral(monkeypatch):
    from ldaspark.claims import claims_paper as cp
    from ldaspark.claims.ledger import check_unit_records
    pred = {}

    def discrete(name, tab, hs):
        pred[tab.name] = cp.predicted_mismatch_order(tab)
        return {"order_mismatch": pred[tab.name] + 0.1, "order_delta_E": 1.0}
    monkeypatch.setattr(cp, "discrete_balance", discrete)
    for pw, it in ((1e-30, 1e-30), (1e-10, 1e-30), (1e-30, 1e-10)):
        monkeypatch.setattr(cp, "exact_balance", lambda name, dps, stages, a=pw, b=it:
                            {"pointwise": a, "integral": b, "delta_E": 0.1, "without_L_t": 1.0,
                             "without_psi_term": 1.0})
        recs = cp.energy_records(True)
        check_unit_records("energy-2.2", recs)
        exact = [r for r in recs if r["method"] == "exact-flow"]
        assert len(exact) == 2 and all(r["residual"] == _close(max(pw, it)) for r in exact)
        assert {r["status"] for r in exact} == {"pass" if max(pw, it) < 1e-22 else "fail"}
        d = [r for r in recs if r["point"] == "one-step h-sweep"]
        assert [r["status"] for r in d] == ["pass"] and d[0]["residual"] == _close(0.1)


def test_definition1_records_describe_the_runs_they_come_from(monkeypatch):
    """Each record names its step count and digits; the run must use them, from initial values
    accurate to those digits."""
    from ldaspark.claims import claims_paper as cp
    from ldaspark.claims.ledger import check_unit_records
    from ldaspark.models.scenes import get_scene
    calls = []

    def fake(system, tab, t0, q0, v0, h, n_steps, dps):
        calls.append((n_steps, dps, q0, system))
        return {"15a": 1e-30, "15b": 1e-45, "15a_without_forces": 1.0, "15b_secant": 1.0, "15b_left_end": 1.0,
                "wellposed": "well-posed", "seconds": 0.5}
    monkeypatch.setattr(cp, "definition1_residuals", fake)
    recs = cp.definition1_records(True)
    check_unit_records("definition-1", recs)
    runs = [r for r in recs if "control: left" not in r["method"] and not (r["claim"] == "15b" and r["point"] ==
                                                                           "ivp-10-steps")]
    assert len(runs) == len(calls) == 3
    for rec, (n, dps, q0, system) in zip(runs, calls):
        assert rec["point"].endswith(f"-{n}-steps") and rec["dps"] == dps, rec
        with mpmath.workdps(100):
            ref = get_scene(rec["scene"]).initial(80)[1]
            # the initial point to more digits than the run works with (10 guard digits)
            assert max(abs(mpmath.mpf(a) - b) for a, b in zip(q0, ref)) <= mpmath.mpf(10) ** (-dps - 10), rec


def test_section5_control_records_carry_no_time_of_their_own(monkeypatch):
    """A control is computed with its identity (same call): its time is in the identity's record."""
    from ldaspark.claims.ledger import check_unit_records
    recs = _fake_section5_all(monkeypatch)
    check_unit_records("section-5", recs)
    ctl = [r for r in recs if "control" in r["method"] or "printed" in r["method"]]
    assert ctl and all(r["seconds"] == 0 for r in ctl)


def _fake_section5_all(monkeypatch):
    from ldaspark.claims import claims_paper as cp
    ident = {k: 1e-30 for k in ("16", "18", "17", "19", "20b-corrected")}
    ident.update({"16-without-force": 1e-3, "18-without-force": 1e-3, "20b-printed": 1e-3, "f_d_minus": 1.0,
                  "k0": 0.0})
    clock = iter(range(0, 10 ** 6, 7))
    monkeypatch.setattr(cp.time, "time", lambda: float(next(clock)))      # every timed call "takes" 7 s
    monkeypatch.setattr(cp, "exact_identities", lambda scn, **k: dict(ident))
    monkeypatch.setattr(cp, "antisymmetry", lambda scn, **k: {"L": 1e-30, "f_plus": 1e-30, "f_minus": 1e-30,
                                                                "wrong-pairing": 1.0})
    monkeypatch.setattr(cp, "holonomic_exact",
                        lambda scn, **k: {"tangential": 1e-30 if scn == "pendulum" else 1e-3, "full": 1.0})
    return cp.section5_records(quick=True)


# --- exact conditions, pairs of covectors, skipped caches: one item of many -------------------------------
def test_the_exact_conditions_need_every_index():
    from ldaspark.core.families import get_method
    from ldaspark.theory import conditions as cd
    g2, g3 = get_method("gauss-2", exact=True), get_method("gauss-3", exact=True)
    assert cd.check_22a(g2) and cd.check_22b(g2) and cd.check_23(g3)
    assert not cd.check_22a(g2.with_entry("b_hat", 1, None, "1/10"))      # b_hat_1 = b_1 still holds
    assert not cd.check_22b(g2.with_entry("A_hat", 0, 1, "1/10"))
    # c_2 + c_2 = 1 still holds, c_1 + c_3 does not
    assert not cd.check_23(g3.with_entry("c", 0, None, "1/10"))


def test_the_holonomic_tangential_residual_is_the_worse_endpoint(monkeypatch):
    import types

    import numpy as np

    from ldaspark.theory import section5
    # n = 2, m = 1, K = (1, 0): the tangential part of a covector is its second entry
    system = types.SimpleNamespace(n=2, saddle_matrix=lambda bk, t, q, v: np.array(
        [[1, 0, 1], [0, 1, 0], [1, 0, 0]], dtype=object))
    mp = mpmath.mpf
    for fm, fp, want in (((5, 0), (7, 2), 2), ((5, 3), (7, 0), 3)):
        r = types.SimpleNamespace(v0=None, v1=None, k0=np.array([mp(0)], dtype=object),
                                  f_d_minus=np.array([mp(x) for x in fm], dtype=object),
                                  f_d_plus=np.array([mp(x) for x in fp], dtype=object))
        monkeypatch.setattr(section5, "endpoints", lambda *a, **k: (0, None, 1, None))
        monkeypatch.setattr(section5, "flow_for", lambda *a, r=r, **k: types.SimpleNamespace(
            system=system, bvp=lambda *b: r))
        out = section5.holonomic_exact.__wrapped__("pendulum") if hasattr(section5.holonomic_exact, "__wrapped__") \
            else section5.holonomic_exact("pendulum")
        assert float(out["tangential"]) == _close(want) and float(out["full"]) == _close(7)


def test_a_cache_directory_anywhere_below_is_left_out_of_the_fingerprint(tmp_path):
    from ldaspark.dist import workers
    d = tmp_path / "tests"
    (d / "sub" / "__pycache__").mkdir(parents=True)
    (d / "test_a.py").write_text("x = 1\n")
    f0 = workers.source_fingerprint("r", dirs=(d,))
    (d / "sub" / "__pycache__" / "stale.py").write_text("y = 2\n")       # one part of three is a cache
    assert workers.source_fingerprint("r", dirs=(d,)) == f0
    (d / "sub" / "test_b.py").write_text("")
    assert workers.source_fingerprint("r", dirs=(d,)) != f0


def test_peer_ratios_are_quoted_when_any_target_has_one():
    from ldaspark.reports.summary import work_precision_values
    st_ = {"scene": "sc", "ratios": {"error": [{"target": 1e-6, "scipy/spark-fast": 2.0},
                                               {"target": 1e-8, "scipy/spark-fast": None, "peer/spark-fast": 3.0}]}}
    out = work_precision_values({"studies": [st_], "dps": []})
    assert out["wp.sc.peer_ratios"] == "- / 3x"


def test_a_general_symmetry_record_fails_when_either_identity_fails(monkeypatch):
    import types

    from ldaspark.claims import claims_general as cg
    scn = types.SimpleNamespace(system=None, name="scene")
    tab = types.SimpleNamespace(name="tab")
    assert 1e-40 < cg.TOL_SYMMETRY < 1e-10                             # the inputs straddle the tolerance
    for ld, phi in ((1e-40, 1e-40), (1e-10, 1e-40), (1e-40, 1e-10)):
        monkeypatch.setattr(cg, "check_symmetry", lambda *a, ld=ld, phi=phi, **k: {
            "symmetry-Ld": ld, "symmetry-Phi": phi, "wellposed": "well-posed", "seconds": 0.1})
        rec = cg._symmetry_record(scn, tab, "pass", 0, [0], [0])
        assert rec["residual"] == _close(max(ld, phi))
        assert rec["status"] == ("pass" if max(ld, phi) <= cg.TOL_SYMMETRY else "fail")


def test_ledger_jobs_floor_at_one_and_follow_the_environment(monkeypatch):
    from ldaspark.claims.ledger import ledger_jobs
    assert ledger_jobs(3) == 3 and ledger_jobs(0) == 1
    monkeypatch.setenv("LDASPARK_JOBS", "0")
    assert ledger_jobs() == 1
    monkeypatch.setenv("LDASPARK_JOBS", "5")
    assert ledger_jobs() == 5


def test_a_condition_within_the_uncertainty_reports_its_largest_residual():
    import types

    from ldaspark.theory.audit_checks import _worst
    ball = types.SimpleNamespace(exact=False, radius=lambda v: 1e-28, is_zero=lambda v: abs(v) <= 1e-28,
                                 to_float=float)
    assert _worst(ball, [(1e-30, "a"), (-3e-30, "b"), (2e-30, "c")]) == (3e-30, None, True, 1e-28)
    # one item beyond the uncertainty: that one, and the largest of those beyond
    w, lab, ok, _ = _worst(ball, [(1e-30, "a"), (5e-20, "b"), (-7e-20, "c"), (6e-20, "d")])
    assert (w, lab, ok) == (7e-20, "c", False)


def test_omega_rank_is_decided_by_the_smallest_singular_value_relative_to_the_largest():
    import types

    from ldaspark.core.errors import TableauError
    from ldaspark.theory import audit_checks as ac

    def tab(om, src=None):
        return types.SimpleNamespace(s=3, source_digits=src, mp_entries=lambda dps: {"omega": om})
    c = ac.check_omega(tab([[2, 0, 0], [0, 0.5, 0]]), None, None, 30)
    assert c.status == ac.PASS and c.residual == _close(0.5)
    assert c.tolerance == _close(10.0 ** -27 * 3 * 2)                  # relative to the largest (2 > 1)
    c = ac.check_omega(tab([[2, 0, 0], [0, 0.5, 0]], src=20), None, None, 30)
    assert c.tolerance == _close(10.0 ** -17 * 3 * 2)                  # the fewer digits given decide
    with pytest.raises(TableauError):
        ac.check_omega(tab([[2, 0, 0], [0, 1e-30, 0]]), None, None, 30)  # one small singular value of two


def test_a_section7_reduction_difference_is_the_worst_of_q_v_and_psi():
    from ldaspark.core.families import get_method
    from ldaspark.theory.section7 import reduction
    r = reduction("euler-ii", get_method("euler-i", exact=True), constant_K=False)     # the control: differs
    parts = [r["q1"], r["v1"], r["Psi1"]]
    assert len(set(parts)) > 1 and r["diff"] == max(parts)


def test_the_least_squares_slope_uses_the_window_only():
    # the window is the first two points (the third is below the floor): slope log2(10)
    est = orders.estimate_order([0.1, 0.05, 0.025], [1e-2, 1e-3, 1e-20], 1e-12)
    assert est.window == (0, 1) and est.observed_order == _close(math.log2(10))


def test_the_audit_error_is_the_worst_component_of_q_and_v():
    import types

    import numpy as np

    from ldaspark.theory.audit_checks import _err
    sol = types.SimpleNamespace(q=[np.array([1.0, 2.5])], v=[np.array([0.0, 5.0])])
    assert _err(sol, [1.0, 2.0], [0.0, 0.0]) == 5.0                    # v's second component
    assert _err(sol, [1.0, -4.0], [0.0, 5.0]) == 6.5                   # q's second component


def test_equal_errors_end_the_asymptotic_window():
    assert orders.asymptotic_window([0.1, 0.05, 0.025], [1e-2, 1e-3, 1e-3], 1e-12) == (0, 1)


def test_mp_arithmetic_asked_for_is_used_even_for_exact_entries():
    from ldaspark.core.families import get_method
    ar, _, _ = au.decide_arith(get_method("gauss-2", exact=True), 30, "mp")
    assert not ar.exact
    ar, _, _ = au.decide_arith(get_method("gauss-2", exact=True), 30, "auto")
    assert ar.exact


def test_growth_below_the_round_off_threshold_is_bounded_at_the_threshold():
    from ldaspark.reports.stability_stiff import classify
    row = {"outcome": "ok", "dE_growth": 10.0}
    assert classify(dict(row, max_rel_dE=1e-8)) == "bounded"           # strictly above 1e-8 is judged
    assert classify(dict(row, max_rel_dE=1.01e-8)) == "growing"


def test_a_dict_option_fingerprints_the_same_in_any_key_order():
    from ldaspark.dist import workers
    assert workers.source_fingerprint({"a": 1, "b": 2}) == workers.source_fingerprint({"b": 2, "a": 1})
