"""Rules of ``ldaspark.lab.reports.stability`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import pytest
from ldaspark.lab.reports import stability as st
from stability_fakes import _dps_rows, _floor_rows, _stiff_rows, _tiny_rows


# ================================================================================================
# stability (the report)
# ================================================================================================
def _step(method, floor_err64=1e-16, fail=None):
    h = [1e-6, 1e-3, 1e-2, 1e-1]
    return {"method": method, "order": 4, "h": h,
            "err": {"float64": [floor_err64, 1e-14, 1e-11, 1e-6], "30": [1e-29, 1e-16, 1e-11, 1e-6],
                    "50": [1e-36, 1e-16, 1e-11, 1e-6]},
            "floor_h": 1e-4 if method == "gauss-2" else 1e-3, "slope50": 5.0,
            "newton": [(4096.0, None), (64.0, fail), (None, 0.25)]}


def _results(mass_bad=True, soft_silent=True):
    """Synthetic job results for every job of the default report (keys of ``jobs``)."""
    R = {}
    for key, fn, args, cost in st.jobs(False):
        kind = key[0]
        if kind == "step":
            R[key] = _step(args[0], floor_err64=3e-15 if args[0] == "gauss-2" else 1e-16,
                           fail=128.0 if args[0] == "gauss-3" else None)
        elif kind == "stage":
            R[key] = [{"method": "gauss-1", "s": 1, "float64": {"B": 0.0, "C": 1e-17, "D": 2e-17, "22b": 0.0},
                       "mp50": {"B": 0.0, "C": 1e-51, "D": 0.0, "22b": 0.0}},
                      {"method": "gauss-2", "s": 2, "float64": {"B": 3e-17, "C": 5e-17, "D": 2e-17, "22b": 4e-17},
                       "mp50": {"B": 2e-51, "C": 1e-52, "D": 0.0, "22b": 0.0}}]
        elif kind == "order":
            m = args[0]
            R[key] = ({"method": m, "claimed": 4, "err": [1e-6, 6.25e-8], "order": [4.0]},
                      {"method": m, "claimed": 4, "err": [1e-6, 6.3e-8], "order": [3.99]})
        elif kind == "long":
            m = args[0]
            R[key] = {"method": m, "path": "spark", "windows": [10 ** 3, 10 ** 4, 10 ** 5, 10 ** 6],
                      "max_k": {"kahan": {"gauss-2": 1e-16, "lobatto-iiia-iiib-2": 4e-16}.get(m, 2e-16),
                                "plain": 1e-15},
                      "dE_window": {"kahan": [1e-10] * 4, "plain": [2e-10] * 4},
                      "plain_minus_kahan": [1e-16, 1e-15, 1e-14, 3e-14], "gap_exponent": 0.51,
                      "drift_halves": {"kahan": 1e-15, "plain": 1e-14}, "seconds_kahan": 1.0, "seconds_plain": 0.5,
                      "series": {"steps": [0, 1000], "dE_kahan": [0.0, 1e-10], "dE_plain": [0.0, 2e-10],
                                 "k_kahan": [0.0, 1e-16]}}
        elif kind == "roundoff":
            R[key] = {"N": [1e3, 1e4, 1e5, 1e6], "rms": {"plain": [1e-16, 1e-15, 1e-14, 1e-13],
                                                        "compensated": [1e-17, 1e-16, 1e-15, 1e-14]},
                      "exponent": {"plain": 0.98, "compensated": 0.97}, "extra": "dropped from the json"}
        elif kind == "mass":
            R[key] = [{"mu": 1e8, "rcond": 1e-9, "outcome": "ok", "rel_err": 1e-15, "iterations": 2.0},
                      {"mu": 1e16, "rcond": 1e-17, "outcome": "ok", "rel_err": 2e-15, "iterations": 2.0},
                      {"mu": 1e20, "rcond": 1e-21, "outcome": "SingularSaddleError" if mass_bad else "ok",
                       "message": "rcond too small"},
                      {"mu": 1e24, "rcond": 1e-25, "outcome": "SingularSaddleError" if mass_bad else "ok",
                       "message": "rcond too small"}]
        elif kind == "rank":
            R[key] = [{"eps": 1e-2, "rcond": 1e-4, "outcome": "ok", "err": 1e-13, "max_psi": 1e2, "iterations": 2},
                      {"eps": 1e-4, "rcond": 1e-8, "outcome": "ok", "err": 1e-9, "max_psi": 1e4, "iterations": 3},
                      {"eps": 1e-8, "rcond": 1e-16, "outcome": "SingularSaddleError", "message": "singular"}]
        elif kind == "soft":
            R[key] = [{"delta": 1e-1, "rcond": 0.1, "outcome": "ok", "min_v1": 0.9, "max_v1": 0.95,
                       "crossing_step": None, "dE": 1e-9},
                      {"delta": 1e-3, "rcond": 1e-3, "outcome": "ok", "min_v1": 0.99, "max_v1": 1.01,
                       "crossing_step": 7 if soft_silent else None, "dE": 1e-8},
                      {"delta": 1e-5, "rcond": 1e-5, "outcome": "SingularSaddleError", "message": "crossed",
                       "crossing_step": 3}]
        elif kind == "reversal":
            m, scene, full = args
            sym = m in st.SYMMETRIC
            base = {"gauss-1": 1e-15, "gauss-3": 4e-15, "euler-i": 0.3, "euler-ii": 0.02}.get(m, 2e-15)
            R[key] = ({"method": m, "scene": scene, "return_error": base * (2 if scene == "robot" else 1),
                       "excursion": 1.5, "N": 100},
                      {"method": m, "scene": scene, "return_error": (1e-29 if sym else 0.01) * (3 if m == "gauss-2"
                                                                                            else 1), "N": 20})
        elif kind == "stiff":
            scene, m = args
            R[key] = [r for r in _stiff_rows() if r["scene"] == scene and r["method"] == m]
        elif kind == "tiny":
            R[key] = [r for r in _tiny_rows() if r["scene"] == args[0]]
        elif kind == "floor":
            R[key] = dict(_floor_rows()[0], method=args[0])
        elif kind == "dps":
            R[key] = _dps_rows()
    return R


def test_findings_numbers_pick_the_right_extremes():
    d = st.collect(_results())
    # the job order, whatever order the results come in
    d2 = st.collect(dict(reversed(list(_results().items()))))
    assert [r["method"] for r in d2["step"]] == list(st.DEFAULT_SWEEP) and d2["reversal"] == d["reversal"]
    f = st.findings_numbers(d)
    assert f["floor_method"] == "gauss-2" and f["floor_h"] == 1e-4 and f["floor_float64"] == 3e-15
    assert f["floor_30"] == 1e-29 and f["floor_50"] == 1e-36
    assert f["stage_max_float64"] == 5e-17 and f["stage_max_mp50"] == 2e-51
    assert f["long_max_k"] == 4e-16
    assert f["long_gap_exponents"] == {m: 0.51 for m in st.LONG_METHODS}
    assert f["roundoff_exponent"] == {"plain": 0.98, "compensated": 0.97}
    assert f["mu_ok"] == 1e16 and f["mu_bad"] == 1e20
    assert f["eps_ok"] == 1e-4 and f["eps_err"] == 1e-9
    assert f["soft_silent"] == [1e-3]
    assert f["reversal_symmetric_float64"] == 8e-15          # gauss-3 on the robot
    assert f["reversal_symmetric_30"] == pytest.approx(3e-29, rel=1e-12, abs=0)     # gauss-2
    assert f["reversal_nonsymmetric_min"] == 0.02
    # no gauss-2 in the sweep: the first row; no ok rank run: None
    d["step"] = [r for r in d["step"] if r["method"] != "gauss-2"]
    d["rank"] = [r for r in d["rank"] if r["outcome"] != "ok"]
    f = st.findings_numbers(d)
    assert f["floor_method"] == d["step"][0]["method"] and f["eps_ok"] is None and f["eps_err"] is None


def test_findings_text_both_branches():
    L = "\n".join(st.section_findings(st.collect(_results())))
    assert "up to mu = 1.0e+16; from mu = 1.0e+20 on, `check_saddle` rejects" in L
    assert "the user is NOT warned: for delta in 1e-03 the run" in L
    assert "Newton limit (first failing h, doubling from 0.25 to 4096): euler-i -/-/0.25;" in L
    assert "gauss-3 -/128/0.25" in L
    assert "N^0.51/0.51/0.51 (gauss-2/lobatto-iiia-iiib-2/gauss-1" in L
    assert "works down to eps = 1.0e-04 with error 1.0e-09" in L
    assert "methods miss by >= 2.0e-02." in L
    L = "\n".join(st.section_findings(st.collect(_results(mass_bad=False, soft_silent=False))))
    assert "up to mu = 1.0e+24 (the largest tried)" in L and "rejects the problem" not in L
    assert "NOT warned" not in L and "outcomes per delta: 1e-01: ok, 1e-03: ok, 1e-05: SingularSaddleError." in L


def test_sections_render_the_data():
    d = st.collect(_results())
    s1 = "\n".join(st.section_step_size(d))
    assert "| gauss-2 | 4 | 1.0e-04 | 3.0e-15 | 1.0e-29 | 1.0e-36 | 5.00 | 4096 / 64 / none (fails at 0.25) |" in s1
    assert "First failures: euler-i on robot at h = 0.25," in s1 and "gauss-3 on particle at h = 128" in s1
    assert "| 1.0e-06 | 1.0e-16 / 1.0e-29 / 1.0e-36 |" in s1
    s2 = "\n".join(st.section_stages(d))
    assert "| gauss-2 | 2 | 3.0e-17 | 5.0e-17 | 2.0e-17 | 4.0e-17 | 2.0e-51 | 1.0e-52 | 0.0e+00 | 0.0e+00 |" in s2
    assert "| gauss-4 | 4 | 1.00e-06, 6.25e-08 | 4.00 | 1.00e-06, 6.30e-08 | 3.99 |" in s2
    s3 = "\n".join(st.section_long_runs(d))
    assert "max dE n<=1e6" in s3 and "| gauss-2 | 1.0e-16 | 1.0e-15 | 1.00e-10 |" in s3 and "| 0.51 |" in s3
    assert "| plain | 1.0e-15 | 1.0e-14 | 1.0e-13 | 0.98 | 2.2e-13 |" in s3
    s4 = "\n".join(st.section_ill_conditioned(d))
    assert "| 1e+20 | 1.0e-21 | SingularSaddleError: `rcond too small` | - | - |" in s4
    assert "| 1e-04 | 1.0e-08 | ok | 1.0e-09 | 1.0e+04 | 3 |" in s4
    assert "| 1e-03 | 1.0e-03 | ok | 0.99 | 1.01 | 7 | 1.0e-08 |" in s4
    s5 = "\n".join(st.section_time_reversal(d))
    assert "| euler-i | no | particle | 0.05 | 100 (30 digits: 20) | 3.0e-01 | 1.0e-02 | 1.50 |" in s5
    assert "| gauss-1 | yes | robot |" in s5
    s6 = "\n".join(st.section_bad_input(d))
    assert s6.count("\n| ") == 1 + len(st.BAD_INPUT) and "SingularSaddleError" in s6
    assert "tests/lab/reports/test_extremes.py" in "\n".join(st.section_header(d)) and "--full" not in st.section_header(d)[2]
    assert "report stability --full" in st.section_header(dict(d, full=True))[2]
    assert st._e(None) == "-" and st._e(2.5) == "2.5e+00" and st._e(3) == "3"


def test_jobs_cover_the_report_and_run_here(monkeypatch, tmp_path):
    J = st.jobs(False)
    keys = [j[0] for j in J]
    assert len(keys) == len(set(keys))
    assert [k[1] for k in keys if k[0] == "step"] == list(st.DEFAULT_SWEEP)
    assert len([k for k in keys if k[0] == "reversal"]) == 2 * (len(st.SYMMETRIC) + len(st.NONSYMMETRIC))
    assert len([k for k in keys if k[0] == "stiff"]) == len(st.STIFF_SCENES) * len(st.STIFF_METHODS)
    costs = {j[0]: j[3] for j in J}
    assert costs[("long", "gauss-2")] > costs[("long", "lobatto-iiia-iiib-2")]
    JF = st.jobs(True)
    assert [k[1] for k, *_ in JF if k[0] == "step"] == list(st.SWEEP_METHODS)
    assert all(a[-1] is True for k, fn, a, c in JF if k[0] in ("reversal", "tiny"))
    assert st.order_methods(False) == st.order_methods(True)[:5] and "gauss-10" in st.order_methods(True)
    R = _results()
    by_call = {(fn, args): key for key, fn, args, cost in J}
    for fn in {j[1] for j in J}:
        monkeypatch.setattr(st, fn, (lambda f: (lambda *a: R[by_call[(f, a)]]))(fn))
    figs = []
    for name in ("_fig_step_sweep", "_fig_stage", "_fig_long", "_fig_stiff", "_fig_floor"):
        monkeypatch.setattr(st, name, (lambda n: (lambda *a: figs.append((n, a[-1]))))(name))
    d = st.build_report(False, str(tmp_path))
    assert [n for n, _ in figs] == ["_fig_step_sweep", "_fig_stage", "_fig_long", "_fig_stiff", "_fig_floor"]
    assert all(p.startswith(str(tmp_path / "figures")) for _, p in figs)
    md = (tmp_path / "stability.md").read_text()
    assert md.startswith("# Numerical stability") and "## Findings" in md and "## 8. Tiny steps" in md
    assert "Generated by `ldaspark report stability`" in md
    import json
    js = json.loads((tmp_path / "stability.json").read_text())
    assert "series" not in js["long"][0] and js["long"][0]["gap_exponent"] == 0.51
    assert set(js["roundoff"]) == {"N", "rms", "exponent"}
    assert js["findings"]["mu_bad"] == 1e20 and js["regimes"] and len(js["stiff_summary"]) == 6
    assert d["full"] is False and len(d["stiff"]) == len(_stiff_rows())
    # the CLI entry points
    import argparse
    p = argparse.ArgumentParser()
    st.add_arguments(p)
    args = p.parse_args(["--outdir", str(tmp_path / "o")])
    assert args.full is False and st.run(args) == 0 and (tmp_path / "o" / "stability.md").exists()
    st.run_default(str(tmp_path / "p"))
    assert (tmp_path / "p" / "stability.json").exists()


def test_job_functions_pass_the_right_arguments(monkeypatch):
    calls = []
    rec = lambda name, ret=None: (lambda *a, **k: calls.append((name, a, k)) or ret)  # noqa: E731
    monkeypatch.setattr(st, "order_at_precision", lambda m, dps: (m, dps))
    assert st.order_pair("gauss-2") == (("gauss-2", 50), ("gauss-2", None))
    monkeypatch.setattr(st, "time_reversal", rec("rev", 1))
    st.reversal_pair("gauss-1", "robot")
    st.reversal_pair("gauss-1", "robot", True)
    assert [c[1:] for c in calls] == [(("gauss-1", "robot", 0.05, 100), {}), (("gauss-1", "robot", 0.05, 20), {"dps": 30}),
                                      (("gauss-1", "robot", 0.05, 100), {}), (("gauss-1", "robot", 0.05, 100), {"dps": 30})]
    calls.clear()
    for name in ("long_run", "roundoff_growth", "tiny_step_grid", "error_floor"):
        monkeypatch.setattr(st, name, rec(name, 1))
    st.long_job("gauss-2"); st.roundoff_job(); st.tiny_job("skate"); st.tiny_job("robot", True); st.floor_job("gauss-1")
    assert calls == [("long_run", ("gauss-2", "particle", 0.05, st.N_LONG, 1000), {}),
                     ("roundoff_growth", (), {"n_steps": st.N_LONG, "every": 1000, "n_ics": 8}),
                     ("tiny_step_grid", (st.N_TINY,), {"scenes": ("skate",)}),
                     ("tiny_step_grid", (st.N_TINY_FULL,), {"scenes": ("robot",)}),
                     ("error_floor", ("gauss-1",), {})]
    # step_row: the floor from float64 against 50 digits, the slope of the 50-digit errors on [1e-3, 1e-1]
    row = _step("gauss-2")
    row["err"]["float64"] = [1e-15, 1e-14, 2 * 10 ** -13.5, 1e-11]
    row["err"]["50"] = [1e-36, 1e-16, 10 ** -13.5, 1e-11]     # slope 2.5 on [1e-3, 1e-1]; float64 > 4x up to 1e-3
    row["err"]["30"] = [1e-29, 1e-14, 10 ** -13.5, 1e-11]     # would give the floor 1e-6 and another slope
    monkeypatch.setattr(st, "step_size_sweep", lambda ms: [dict(row, method=ms[0])])
    monkeypatch.setattr(st, "newton_limit", lambda m, scene: (8.0, {"robot": 16.0}.get(scene), "msg"))
    r = st.step_row("gauss-2")
    assert r["floor_h"] == 1e-3 and r["slope50"] == pytest.approx(2.5, abs=1e-9)
    assert r["newton"] == [(8.0, None), (8.0, None), (8.0, 16.0)]


def test_run_jobs_here_calls_every_job_once(monkeypatch):
    seen = []
    for key, fn, args, cost in st.jobs(False):
        monkeypatch.setattr(st, fn, (lambda f: (lambda *a: seen.append((f, a)) or (f, a)))(fn))
    out = st.run_jobs_here(False)
    assert list(out) == [j[0] for j in st.jobs(False)]
    assert out[("step", "gauss-1")] == ("step_row", ("gauss-1",)) and len(seen) == len(out)


def test_write_without_a_clock_has_no_timing_line(monkeypatch, tmp_path):
    for name in ("_fig_step_sweep", "_fig_stage", "_fig_long", "_fig_stiff", "_fig_floor"):
        monkeypatch.setattr(st, name, lambda *a: None)
    from ldaspark.lab.reports.timing import Clock
    st.write(_results(), str(tmp_path / "a"))
    st.write(_results(), str(tmp_path / "b"), clock=Clock(), command="ldaspark report stability --x")
    a, b = (tmp_path / "a" / "stability.md").read_text(), (tmp_path / "b" / "stability.md").read_text()
    assert "ldaspark report stability --x" not in a and "ldaspark report stability --x" in b
    assert b.startswith(a.rstrip("\n"))


def test_job_costs_are_positive_and_sizes_match_the_report_text():
    """Every job has a positive cost estimate (the scheduler starts the longest first; a zero
    would put a 2 s job behind every other one), and the long runs are the 1e6 steps the report's
    section 3 heading and the findings quote."""
    for full in (False, True):
        assert all(c > 0 for *_, c in st.jobs(full))
    assert st.N_LONG == 10 ** 6 and st.N_TINY == 10 ** 4 and st.N_TINY_FULL == 10 ** 5
    d = st.collect(_results())
    assert "N = 1e+06 steps" in "\n".join(st.section_long_runs(d))
