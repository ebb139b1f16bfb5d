"""Rules of ``ldaspark.lab.reports.summary`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import json
from ldaspark.lab.reports import peers, summary, systems


def _claim(claim, status="pass", expected="pass", residual=None, method="m", **kw):
    return dict({"claim": claim, "status": status, "expected": expected, "residual": residual, "method": method,
                 "scene": "s", "wellposed": "ok"}, **kw)


def _fig4(exps):
    return {"methods": list(range(len(exps))), "fit": {i: {"exponent": x} for i, x in enumerate(exps)}, "seconds": 2.25}


# =============================================================================================
# summary
# =============================================================================================
def test_readme_values_skip_absent_reports_and_the_probe_ratio(tmp_path):
    assert summary._load(str(tmp_path), "claims.json") is None
    (tmp_path / "report_timing.json").write_text(json.dumps({"wall": 99.6, "cpu": 300.0, "cpu_count": 2,
                                                             "probe": {"cpu": 0.25}}))
    v = summary.readme_values(str(tmp_path))
    assert v == {"run.wall": "100 s", "run.cpu": "300 s", "run.cores": "2", "run.probe_ratio": "1200"}
    assert "run.probe_ratio" not in summary.run_values({"wall": 1, "cpu": 1, "cpu_count": 1, "probe": None})


def test_claims_values_max_of_the_passing_min_of_the_negative_controls():
    recs = [_claim("theorem1-a", residual=1e-16), _claim("theorem1-a", residual=4e-15),
            _claim("theorem1-b", status="fail", residual=1e-3),             # unexpected, not in the max
            _claim("theorem1-a", method="negctl-x", status="fail", expected="fail", residual=2e-2),
            _claim("theorem1-a", method="negctl-y", status="fail", expected="fail", residual=5e-4),
            _claim("symmetry-x", residual=3e-16), _claim("symmetry-y", residual=2e-15),
            _claim("symmetry-z", status="fail", residual=1.0),
            _claim("22a", status="pass", expected="pass"), _claim("23", status="fail", expected="pass"),
            _claim("implicit-function", wellposed="singular", method="euler"),
            _claim("implicit-function", wellposed="singular", method="negctl-e")]
    v = summary.claims_values(recs)
    assert v["claims.theorem1.max"] == "4.0e-15" and v["claims.theorem1.negctl_min"] == "5.0e-04"
    assert v["claims.theorem1.unexpected"] == "1" and v["claims.symmetry.max"] == "2.0e-15"
    assert v["claims.conditions"] == "1 of 2" and v["claims.singular"] == "euler on s"
    # nothing passing, no negative control, no symmetry record: the keys are absent
    v = summary.claims_values([_claim("theorem1-a", status="fail", residual=1.0), _claim("23")])
    assert not {"claims.theorem1.max", "claims.theorem1.negctl_min", "claims.symmetry.max"} & set(v)
    assert v["claims.theorem1.unexpected"] == "1" and v["claims.singular"] == "none"
    # a claim group: not-applicable records are not decided; order claims have no residual max
    v = summary.claims_values([_claim("energy-balance-2.2", residual=1.0),
                               _claim("nonideal-3.3", residual=2e-3), _claim("nonideal-3.3", residual=3e-3),
                               _claim("nonideal-3.3", status="not-applicable", residual=9.0)])
    assert v["claims.energy-balance"] == "1 of 1" and "claims.energy-balance.max" not in v
    assert v["claims.nonideal"] == "2 of 2"


def test_energy_fig4_verdict_needs_every_exponent_near_one():
    base = {"figures": [{"methods": {"a": {"last_over_first_quarter": 1.25, "bounded": True},
                                     "b": {"last_over_first_quarter": 0.5, "bounded": False}}}]}
    v = summary.energy_values(base)
    assert v == {"energy.figs13.ratio": "0.50-1.25", "energy.figs13.bounded": "1 of 2"}
    for exps, near, verdict in (([1.25, 0.75, 1.0], "3 of 3", "reproduced"), ([1.25, 1.5, 1.0], "2 of 3",
                                                                               "partly reproduced"),
                                ([1.5, 0.5, 2.0], "0 of 3", "not reproduced")):
        v = summary.energy_values(dict(base, figure4_nonholonomic=_fig4(exps)))
        assert v["energy.fig4.nh.near1"] == near and v["energy.fig4.nh.verdict"] == verdict
        assert "energy.fig4.printed.verdict" not in v and v["energy.fig4.nh.seconds"] == "2.2 s"


def test_work_precision_peer_ratios_only_where_measured():
    d = {"studies": [{"scene": "s", "ratios": {"error": [{"target": 1e-3, "scipy/spark-fast": 12.4},
                                                         {"target": 1e-6, "scipy/spark-fast": None}]}}],
         "dps": []}
    v = summary.work_precision_values(d)
    assert v["wp.s.ratios"] == "12x / -" and "wp.s.peer_ratios" not in v
    d["studies"][0]["ratios"]["error"][1]["peer/spark-fast"] = 0.456
    assert summary.work_precision_values(d)["wp.s.peer_ratios"] == "- / 0.46x"
    assert summary._r(None, at_most=4.94) == "<= 4.9x" and summary._r(None, at_least=12.3) == ">= 12x"


def test_peer_ratios_of_a_run_without_the_strongest_peers_are_not_quoted():
    """A main job run without the bench extra compares SPARK with scipy's and Fortran's loops only
    (a fresh clone's run gave particle 5.5x / 8.1x / 10x where CyRK's nbsolve2_ivp gives 0.057x /
    0.078x / 0.16x); README's row names CyRK, so those ratios are refused, not quoted."""
    row = {"target": 1e-3, "scipy/spark-fast": 12.4, "peer/spark-fast": 5.5}
    d = {"studies": [{"scene": "s", "ratios": {"error": [row]}}], "dps": [],
         "peers_skipped": ['cyrk-nbsolve2-DOP853, cyrk-nbsolve2-Vern8 skipped: CyRK is not installed '
                           '(pip install -e ".[bench]")']}
    v = summary.work_precision_values(d)["wp.s.peer_ratios"]
    assert "5.5x" not in v and v.startswith("not measured") and "cyrk-nbsolve2-Vern8" in v
    assert summary.work_precision_values(dict(d, peers_skipped=[]))["wp.s.peer_ratios"] == "5.5x"   # control


def test_residuals_agree_within_a_factor_ten_only():
    sm = summary.same_magnitude
    assert sm("1e0", "1e1") and sm("1e1", "1e0") and not sm("1e0", "1.01e1") and not sm("1.01e1", "1e0")
    assert sm("1e-16", "1e-16") and sm("-2e-3", "3e-3") and not sm("1e-16", "1e-12")
    assert sm("0", "0.0") and not sm("0", "1e-300") and not sm("1e-300", "0")
    assert sm("inf", "inf") and not sm("inf", "1e300") and not sm("nan", "nan")
    assert sm("n/a", "n/a") and not sm("n/a", "1e-3")


def test_quote_problem_by_kind(tmp_path):
    vals = {"claims.x.max": "1.0e-15", "convergence.spark": "3 of 3"}
    assert summary.quote_problem("nope.key", "1", vals).startswith("unknown key")
    assert summary.quote_problem("claims.x.max", "9.0e-15", vals) is None
    assert "another order" in summary.quote_problem("claims.x.max", "1.1e-14", vals)
    assert summary.quote_problem("convergence.spark", "3 of 3", vals) is None
    assert summary.quote_problem("convergence.spark", "2 of 3", vals) is not None
    # timing: against the snapshot, and against the reports while they are the snapshot's
    (tmp_path / "report_timing.json").write_text(json.dumps({"wall": 10, "cpu": 20, "cpu_count": 1, "date": "d"}))
    snap = {"values": {"run.wall": "10 s"}, "run": {"date": "d", "wall": 10, "cpu": 20}}
    assert summary.quote_problem("run.wall", "10 s", {"run.wall": "10 s"}, str(tmp_path), snap) is None
    assert "the reports" in summary.quote_problem("run.wall", "10 s", {"run.wall": "11 s"}, str(tmp_path), snap)
    snap["run"]["cpu"] = 21                                              # another run: the snapshot rules
    assert summary.quote_problem("run.wall", "10 s", {"run.wall": "11 s"}, str(tmp_path), snap) is None
    assert "no snapshot" in summary.quote_problem("run.wall", "10 s", {}, str(tmp_path))


def test_fill_and_snapshot_through_main(tmp_path, capsys):
    rep = tmp_path / "reports"
    rep.mkdir()
    assert summary.write_snapshot(str(rep)) is None and not (rep / "report_timing.json").exists()
    (rep / "report_timing.json").write_text(json.dumps({"wall": 12.0, "cpu": 34.0, "cpu_count": 2, "date": "x"}))
    readme = tmp_path / "README.md"
    readme.write_text("wall <!--run.wall-->1 s<!--/-->, kept <!--other.key-->as is<!--/-->\n")
    assert summary.main(["--reports", str(rep), "--fill", str(readme)]) == 0
    assert readme.read_text() == "wall <!--run.wall-->12 s<!--/-->, kept <!--other.key-->as is<!--/-->\n"
    assert "updated" in capsys.readouterr().out
    snap = json.loads((rep / "report_timing.json").read_text())["readme"]
    assert snap["values"] == {"run.wall": "12 s", "run.cpu": "34 s"} and snap["run"]["cpu"] == 34.0
    assert summary.main(["--reports", str(rep), "--fill", str(readme)]) == 0
    assert "already current" in capsys.readouterr().out
    assert summary.main(["--reports", str(rep)]) == 0
    assert "<!--run.cores-->2<!--/-->" in capsys.readouterr().out.splitlines()


def test_main_bad_inputs_are_one_line_and_exit_2(tmp_path, capsys):
    """``--fill /dev/zero`` read without bound (memory filled); a missing --fill file, a directory,
    a report of another layout gave tracebacks (exit 1); a --reports directory that does not exist
    listed nothing and exited 0. One line on stderr and exit 2 now, before anything is written."""
    import os
    rep = tmp_path / "reports"
    rep.mkdir()
    (rep / "report_timing.json").write_text(json.dumps({"wall": 12.0, "cpu": 34.0, "cpu_count": 2, "date": "x"}))
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    bad_claims = tmp_path / "bad"
    bad_claims.mkdir()
    (bad_claims / "claims.json").write_text('{"x": 1}')
    (bad_claims / "energy.json").write_text('{not json')
    binary = tmp_path / "bin.md"
    binary.write_bytes(b"\xff\xfe\x00junk")
    for argv, match in ((["--fill", "/dev/zero"], "not a regular file"), (["--fill", str(fifo)], "not a regular file"),
                        (["--fill", str(tmp_path / "none.md")], "no such"), (["--fill", str(tmp_path)], "regular"),
                        (["--fill", str(binary)], "UTF-8"), (["--reports", str(tmp_path / "none")], "not a directory"),
                        (["--reports", str(bad_claims)], "claims.json"),
                        (["--reports", str(rep / "report_timing.json")], "not a directory")):
        args = (["--reports", str(rep)] if "--reports" not in argv else []) + argv
        assert summary.main(args) == 2, argv
        out, err = capsys.readouterr()
        assert out == "" and len(err.strip().splitlines()) == 1 and match in err and "Traceback" not in err, err
    (bad_claims / "claims.json").unlink()
    assert summary.main(["--reports", str(bad_claims)]) == 2 and "energy.json" in capsys.readouterr().err
    assert json.loads((rep / "report_timing.json").read_text()).get("readme") is None   # nothing written
    # control: a good run lists the keys; names from the files are printed with their controls escaped
    (rep / "claims.json").write_text(json.dumps([_claim("implicit-function", wellposed="singular",
                                                        method="e\x1b[31m", scene="s\nx")]))
    assert summary.main(["--reports", str(rep)]) == 0
    out = capsys.readouterr().out
    assert "<!--run.wall-->12 s<!--/-->" in out and "\x1b" not in out and "e\\x1b[31m on s\\nx" in out


def _rec(method, scene, variable, observed, claimed=2, scope="variable"):
    return {"method": method, "scene": scene, "variable": variable, "observed_order": observed,
            "claimed_order": claimed, "claim_scope": scope}


def _claim_2(claim, method, status, expected, residual, wellposed="well-posed"):
    return {"claim": claim, "method": method, "scene": "s", "status": status, "expected": expected,
            "residual": residual, "wellposed": wellposed}


# --- summary verdicts: all of them, not one -----------------------------------------------------------------
def test_the_convergence_summary_holds_only_when_every_record_holds():
    from ldaspark.lab.reports.summary import convergence_values
    recs = [_rec("gauss-2", "skate", "q", 4.0, 4), _rec("gauss-2", "skate", "v", 4.1, 4),
            _rec("gauss-irk-1", "skate", "q", 2.0, 2), _rec("gauss-irk-2", "skate", "q", 4.0, 4)]
    v = convergence_values(recs)
    assert v["convergence.spark"] == "4 of 4" and v["convergence.spark.verdict"] == "hold"
    recs[1] = _rec("gauss-2", "skate", "v", 3.0, 4)                   # one of four fails
    v = convergence_values(recs)
    assert v["convergence.spark"] == "3 of 4" and v["convergence.spark.verdict"] == "do not all hold"


def test_the_claims_summary_counts_agreement_and_takes_the_worst_residual():
    from ldaspark.lab.reports.summary import claims_values
    recs = [_claim_2("22a", "m", "pass", "pass", 0.0), _claim_2("23", "m", "fail", "pass", 1.0),
            _claim_2("theorem1-q0", "m", "pass", "pass", 1e-30), _claim_2("theorem1-q1", "m", "pass", "pass", 3e-28),
            _claim_2("theorem1-q0", "n", "fail", "pass", 1e-3),
            _claim_2("theorem1-q0", "negctl-a", "fail", "fail", 2e-2), _claim_2("theorem1-q1", "negctl-b", "fail", "fail", 5e-4),
            _claim_2("symmetry-x", "m", "pass", "pass", 2e-25), _claim_2("symmetry-y", "m", "pass", "pass", 7e-26),
            _claim_2("16", "m", "pass", "pass", 1e-20), _claim_2("18", "m", "pass", "pass", 4e-19),
            _claim_2("antisymmetry-exact", "m", "fail", "pass", 1e-10),
            _claim_2("antisymmetry-exact", "m", "not-applicable", "pass", None)]
    v = claims_values(recs)
    assert v["claims.conditions"] == "1 of 2"
    assert v["claims.theorem1.max"] == "3.0e-28"                     # the worst passing residual
    assert v["claims.theorem1.negctl_min"] == "5.0e-04"              # the least convincing control
    assert v["claims.theorem1.unexpected"] == "1"
    assert v["claims.symmetry.max"] == "2.0e-25"
    assert v["claims.paper"] == "2 of 3"                              # not-applicable not decided
    assert v["claims.paper.max"] == "4.0e-19"


def test_the_peer_floor_needs_both_sides(monkeypatch):
    from ldaspark.lab.reports import summary
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


def test_peer_ratios_are_quoted_when_any_target_has_one():
    from ldaspark.lab.reports.summary import work_precision_values
    st_ = {"scene": "sc", "ratios": {"error": [{"target": 1e-6, "scipy/spark-fast": 2.0},
                                               {"target": 1e-8, "scipy/spark-fast": None, "peer/spark-fast": 3.0}]}}
    out = work_precision_values({"studies": [st_], "dps": []})
    assert out["wp.sc.peer_ratios"] == "- / 3x"


def test_quasi_step_values_quote_each_side_the_right_way_up():
    """``summary.quasi_step_values`` quotes the study's cpu(peer) / cpu(SPARK) (``peers.speedups``)
    as it is: a SPARK run 4x cheaper than the peer reads 4.00x, the Newton side (8x dearer than
    the quasi run) 0.50x under its own key; a bound reads '>= ' or '<= ', a missing one '-'; the
    per-step range runs from the smallest to the largest speed-up."""
    from ldaspark.lab.reports.summary import quasi_step_values

    def side(spark_cpu, peer_cpu=0.004, **kw):
        r = {"target": 1e-9, "spark_cpu": spark_cpu, "peer_cpu": peer_cpu, "speedup": peer_cpu / spark_cpu,
             "speedup_at_least": None, "speedup_at_most": None}
        r.update(kw)
        return [r]
    study = {"scene": "skate", "t_end": 100.0, "key": "error", "quasi": side(0.001), "newton": side(0.008)}
    d = {"per_step": [{"speedup": 3.32}, {"speedup": 1.07}], "studies": [study],
         "load_average_1min_at_start": 2.04, "load_average_1min_at_end": 1.96}
    out = quasi_step_values(d)
    assert (out["qs.skate.error.1e-09"], out["qs.skate.error.1e-09.newton"]) == ("4.00x", "0.50x")
    assert out["qs.per_step.range"] == "1.07-3.3x" and out["qs.load"] == "2.0-2.0"
    study["quasi"] = side(0.001, speedup=None, speedup_at_least=1.5)
    study["newton"] = side(0.008, speedup=None, speedup_at_most=0.25)
    out = quasi_step_values(d)
    assert (out["qs.skate.error.1e-09"], out["qs.skate.error.1e-09.newton"]) == (">= 1.50x", "<= 0.25x")
    study["newton"] = side(0.008, speedup=None)
    assert quasi_step_values(d)["qs.skate.error.1e-09.newton"] == "-"
    # a study run with --tol-kappa: its Newton(tol = K * target) rows under '.tol', absent without
    assert "qs.skate.error.1e-09.tol" not in quasi_step_values(d)
    study["quasi_tol"] = side(0.002)
    assert quasi_step_values(d)["qs.skate.error.1e-09.tol"] == "2.00x"


def test_quasi_step_values_quote_the_specialised_kernel_against_the_generic_one():
    """The specialised kernel's range covers the rows where it ran only (a general-form row has
    none: its ratio 1.0 would pull the range down); the generic kernel's own range against Newton
    and its study keys ('.generic') are quoted apart from the specialised ones."""
    from ldaspark.lab.reports.summary import quasi_step_values
    rows = [{"speedup": 2.0, "specialised": True, "specialised_speedup": 1.5, "generic_speedup": 1.33},
            {"speedup": 4.0, "specialised": True, "specialised_speedup": 1.34, "generic_speedup": 3.0},
            {"speedup": 1.0, "specialised": False, "specialised_speedup": 1.0, "generic_speedup": 1.0}]
    gen = [{"target": 1e-9, "speedup": 0.5, "speedup_at_least": None, "speedup_at_most": None}]
    spec = [{"target": 1e-9, "speedup": 0.7, "speedup_at_least": None, "speedup_at_most": None}]
    d = {"per_step": rows, "studies": [{"scene": "skate", "key": "error", "quasi": spec, "quasi_generic": gen,
                                        "newton": gen}]}
    out = quasi_step_values(d)
    assert out["qs.specialised.range"] == "1.34-1.5x"
    assert out["qs.per_step.generic.range"] == "1-3x" and out["qs.per_step.range"] == "1-4x"
    assert (out["qs.skate.error.1e-09"], out["qs.skate.error.1e-09.generic"]) == ("0.70x", "0.50x")


def test_test_run_values_quote_the_latest_record_of_each_kind():
    """README's test-run numbers (``reports/test_runs.json``, from ``benchmarks/test_runs.py``): the
    latest "ci" and "newcomer" records, an earlier one ignored (control: the first CI record's
    counts are not what is quoted)."""
    base = {"date": "2026-12-07 18:00", "load_start": 0.42, "load_end": 1.0, "cpu_count": 2,
            "test_seconds": 249.4, "skipped": 733, "failed": 0, "errors": 0}
    d = {"runs": [{**base, "kind": "ci", "commit": "a" * 40, "rc": 1, "passed": 10, "wall_seconds": 300.0},
                  {**base, "kind": "newcomer", "commit": "b" * 40, "rc_first": 0, "rc_second": 0, "passed": 4545,
                   "first_seconds": 213.2, "second_seconds": 185.0, "main_job_wall": 179.4, "main_job_cpu": 326.0},
                  {**base, "kind": "ci", "commit": "c" * 40, "rc": 0, "passed": 4553, "wall_seconds": 372.0,
                   "mutants": 17, "mutants_killed": 17}]}
    v = summary.test_run_values(d)
    assert v["tests.ci.passed"] == "4553" and v["tests.ci.commit"] == "cccccccc" and v["tests.ci.rc"] == "0"
    assert v["tests.ci.wall"] == "6.2 min" and v["tests.ci.mutants"] == "17 of 17" and v["tests.ci.load"] == "0.4"
    assert v["tests.newcomer.rc"] == "0 and 0" and v["tests.newcomer.first"] == "213 s"
    assert v["tests.newcomer.main_job"] == "179 s wall, 326 s CPU" and v["tests.newcomer.passed"] == "4545"
    assert summary.quote_kind("tests.ci.passed") == "exact"
    # a failed CI run has no mutation record (.ci/run stops at the tests): README's mark says so,
    # not an unknown key (3 README tests failed on such a record in stop 65)
    failed = summary.test_run_values({"runs": d["runs"][:2]})
    assert failed["tests.ci.rc"] == "1" and failed["tests.ci.mutants"].startswith("none run")


def test_test_runs_parses_pytests_last_summary_line():
    """``benchmarks/test_runs.pytest_summary``: the counts and seconds of the last summary line
    (an earlier run's line in the same output is not taken); {} without one."""
    import importlib.util
    import pathlib
    path = pathlib.Path(__file__).resolve().parents[3] / "benchmarks" / "test_runs.py"
    spec = importlib.util.spec_from_file_location("test_runs_bench", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = ("3 passed in 1.00s\n....\n4553 passed, 733 skipped, 5 warnings in 249.12s (0:04:09)\n"
           "17 of 17 mutants killed -> /tmp/x/mutation.md\n")
    assert mod.pytest_summary(out) == {"passed": 4553, "skipped": 733, "failed": 0, "errors": 0,
                                       "test_seconds": 249.12}
    assert mod.pytest_summary("2 failed, 7 passed, 1 error in 3.5s") == {"passed": 7, "skipped": 0, "failed": 2,
                                                                      "errors": 1, "test_seconds": 3.5}
    assert mod.pytest_summary("no summary here") == {}
    assert mod.MUTANTS_LINE.findall(out)[-1] == ("17", "17")
