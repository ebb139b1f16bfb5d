"""The README's example must run as written and do what it says."""
import pathlib
import re

import numpy as np

README = pathlib.Path(__file__).resolve().parents[2] / "README.md"


def test_readme_rolling_disk_example_runs(capsys):
    text = README.read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks, "README has no python example"
    ns = {}
    exec(compile(blocks[0], "README.md", "exec"), ns)
    sol = ns["sol"]
    assert np.abs(sol.constraint).max() < 1e-13
    assert np.abs(sol.energy - sol.energy[0]).max() < 1e-10   # free rolling: energy is conserved
    assert sol.q.shape == (101, 4)


def test_readme_commands_match_ci():
    text = README.read_text()
    ci = (README.parent / ".ci" / "run").read_text()
    assert "ldaspark report" in text
    assert "python -m pytest -q" in text and "python -m pytest -q" in ci
    # the same test command, options included (the two workers of -n 2 are part of its timing)
    cmd = next(line.strip() for line in ci.splitlines() if line.strip().startswith("python -m pytest"))
    assert f"&& {cmd}\n" in text, cmd
    assert 'pip install -q -e ".[test]"' in ci and 'pip install -e ".[test]"' in text


# --- README quotes the reports: every number in the findings and speed tables is marked with the
# key it comes from (<!--KEY-->text<!--/-->, see ldaspark.lab.reports.summary) and equals the value
# computed from the committed reports' JSON; verdict words are marked the same way.
from ldaspark.lab.reports.summary import MARK  # noqa: E402
# numbers that are not measurements: equation references "(22a)", "(23a-d)", "(3a-b)", stage
# counts "s = 2", section numbers "8.4"
NOT_MEASURED = re.compile(
    r"\(\d+[a-f]?(?:-[a-f])?\)"          # equation references (22a), (23a-d), (3a-b)
    r"|\bs = \d\b|\b\d+ digits\b"          # stage counts, working precision
    r"|\bh = [\d.]+|\brtol [\d.e-]+"        # step sizes and tolerances of the runs
    r"|\[0, [\d.e+]*\]|\bat \d[\d.e+-]*:"      # the runs' intervals [0, 1e4], target errors "at 1e-9:"
    r"|_\{[^}]*\}|[A-Za-z][\w-]*\d\w*"      # subscripts v_{k+1/2}, names q0, t1, gauss-2
    r"|!?= 0\b")                            # "k != 0"


def _quoted_tables(text):
    """(heading, rows as lists of cells, index of the measured column) of each table of README's
    findings and speed sections. The measured column is the one headed "verdict" or "measured"
    (the third of the "situation | use | measured" table, not always the second)."""
    out = []
    for heading in ("## What the suite found", "## Speed and accuracy"):
        assert heading in text, f"README lost its table '{heading}'"
        block = text.split(heading, 1)[1].split("\n## ", 1)[0]
        for table in re.split(r"\n(?!\|)[^\n]*", "\n" + block):       # runs of consecutive table lines
            lines = [ln for ln in table.split("\n") if ln.startswith("|")]
            if len(lines) < 3:
                continue
            cells = []
            for ln in lines:
                parts = [c.strip() for c in re.split(r"(?<!\\)\|", ln.strip())[1:-1]]
                assert len(parts) >= 2, ln
                cells.append(parts)
            header = [c.lower() for c in cells[0]]
            col = next((i for i, c in enumerate(header) if c.startswith(("measured", "verdict"))), None)
            assert col is not None, f"{heading}: a table without a measured / verdict column: {lines[0]}"
            out.append((heading, cells[2:], col))                  # skip header, delimiter
    return out


def check_readme_quotes(text, values, reports_dir=None, snap=None):
    """Problems: marked values that differ from the reports (by the key's kind: exact, residual
    class, timing against the committed snapshot; ``summary.quote_problem``), unknown keys,
    unmarked numbers in the measured column."""
    from ldaspark.lab.reports.summary import quote_problem
    problems = []
    for heading, cells, col in _quoted_tables(text):
        for row in cells:
            for key, shown in MARK.findall(" | ".join(row)):
                p = quote_problem(key, shown, values, reports_dir, snap)
                if p is not None:
                    problems.append(f"{heading}: {p}")
            rest = NOT_MEASURED.sub("", MARK.sub("", row[col]))      # the verdict / measured column
            if re.search(r"\d", rest):
                problems.append(f"{heading}: unmarked number in {row[col]!r}")
    return problems


def test_readme_numbers_and_verdicts_come_from_the_reports():
    from ldaspark.lab.reports.summary import readme_values
    from ldaspark.lab.reports.summary import quote_problem
    reports = str(README.parent / "reports")
    values = readme_values(reports)
    text = README.read_text()
    assert MARK.search(text), "README's tables carry no <!--KEY-->value<!--/--> marks"
    assert check_readme_quotes(text, values, reports) == []
    # marks in the prose too (the main job's measured time comes from reports/report_timing.json)
    stale = [p for p in (quote_problem(k, v, values, reports) for k, v in MARK.findall(text)) if p]
    assert stale == []
    assert "<!--run.wall-->" in text and "<!--run.cpu-->" in text


def test_readme_quote_check_catches_a_stale_number():
    # negative controls: a number that differs from the report, and an unmarked one
    text = ("## What the suite found\n\n| claim | verdict |\n|---|---|\n"
            "| orders | <!--convergence.spark-->119 of 120<!--/--> hold |\n\n"
            "## Speed and accuracy\n\n| what | measured |\n|---|---|\n| steps/s | median 178x |\n")
    problems = check_readme_quotes(text, {"convergence.spark": "120 of 120"})
    assert len(problems) == 2 and "119 of 120" in problems[0] and "unmarked" in problems[1]
    ok = text.replace("119 of 120", "120 of 120").replace("median 178x", "median <!--wp.sps.median-->178x<!--/-->")
    snap = {"values": {"wp.sps.median": "178x"}}
    assert check_readme_quotes(ok, {"convergence.spark": "120 of 120", "wp.sps.median": "178x"}, snap=snap) == []
    # a timing differs on another machine: checked against the committed snapshot, not the new run
    assert check_readme_quotes(ok, {"convergence.spark": "120 of 120", "wp.sps.median": "95x"}, snap=snap) == []
    # ... but a timing README quotes that the snapshot does not record, or records otherwise, fails
    assert len(check_readme_quotes(ok, {"convergence.spark": "120 of 120"}, snap={"values": {}})) == 1
    assert len(check_readme_quotes(ok, {"convergence.spark": "120 of 120"},
                                   snap={"values": {"wp.sps.median": "180x"}})) == 1


def test_readme_quote_check_reads_the_measured_column_of_every_table():
    """The unmarked-number check read the second column of every row; in the "situation | use |
    measured" table that is the method's name, so an unmarked measured number there passed (a
    check that could not fail). Each table's measured column is found from its header now; a
    run's interval and target ("t in [0, 100]", "at 1e-9:") are settings, not measurements."""
    text = ("## What the suite found\n\n| claim | verdict | where |\n|---|---|---|\n"
            "| orders | <!--convergence.spark-->120 of 120<!--/--> hold | tests/x.py |\n\n"
            "## Speed and accuracy\n\n| what | measured |\n|---|---|\n| steps/s | <!--wp.sps.median-->178x<!--/--> |\n\n"
            "prose between the tables\n\n| situation | use | measured |\n|---|---|---|\n"
            "| short runs | SPARK gauss-8 | speed-up on the skate, t in [0, 100]: 3.1x (at 1e-9: "
            "<!--wp.sps.median-->178x<!--/-->) |\n")
    vals, snap = {"convergence.spark": "120 of 120", "wp.sps.median": "178x"}, {"values": {"wp.sps.median": "178x"}}
    problems = check_readme_quotes(text, vals, snap=snap)
    assert len(problems) == 1 and "unmarked number" in problems[0] and "3.1x" in problems[0], problems
    assert check_readme_quotes(text.replace("3.1x", "<!--wp.sps.median-->178x<!--/-->"), vals, snap=snap) == []
    assert [col for _, _, col in _quoted_tables(text)] == [1, 1, 2]


def test_readme_interface_example_runs(tmp_path, monkeypatch, capsys):
    """The dense output / event / plot / file example runs as written (in a scratch directory:
    it writes energy.png and skate.npz) and finds the crossing it names."""
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
    assert len(blocks) >= 2, "README has no interface example"
    monkeypatch.chdir(tmp_path)
    ns = {}
    exec(compile(blocks[1], "README.md", "exec"), ns)
    assert ns["hit"].status == 1
    assert abs(ns["hit"].t_events[0][0] - np.arcsin(np.sqrt(0.6))) < 1e-5
    assert (tmp_path / "energy.png").stat().st_size > 0 and (tmp_path / "skate.npz").exists()


# --- the README's main job and then its tests on another machine: timings and
# float64 round-off differ, verdicts and counts do not. Simulated on a copy of the reports.
def _another_machine(tmp_path):
    """A copy of the committed reports as a run on another machine would leave them: every CPU
    time of the work-precision study scaled by a different factor (a machine with other relative
    speeds), the largest general-claims residual moved by round-off (6.3e-17 -> 9.9e-17 was seen),
    and report_timing.json rewritten by the main job's writer (which keeps README's snapshot)."""
    import json
    import shutil
    src = README.parent / "reports"
    out = tmp_path / "reports"
    shutil.copytree(src, out, ignore=shutil.ignore_patterns("figures"))
    wp = json.loads((out / "work_precision.json").read_text())
    for i, st in enumerate(wp["studies"]):
        for j, r in enumerate(st["rows"]):
            r["cpu"] *= 1.0 + 0.5 * ((i + j) % 3)
        st.pop("ratios", None)
    from ldaspark.lab.reports.work_precision import ratios
    for st in wp["studies"]:
        st["ratios"] = {"error": ratios(st, key="error"), "energy_error": ratios(st, key="energy_error")}
    wp["steps_per_second_summary"]["median"] *= 0.6
    (out / "work_precision.json").write_text(json.dumps(wp))
    recs = json.loads((out / "claims.json").read_text())
    return out, recs


def _rewrite_timing(out):
    from ldaspark.lab.reports import driver

    class _Clock:
        wall, cpu = 301.0, 569.0
    driver.write_run_timing(str(out), {"convergence": {"cpu": 1.0, "wall": 1.0, "jobs": 1}}, _Clock(), 2, probe=0.1)


def _write_claims(out, recs):
    import json
    (out / "claims.json").write_text(json.dumps(recs))


def _general_max_record(recs):
    from ldaspark.lab.reports.summary import CLAIM_GROUP_KEYS, ORDER_CLAIMS
    rs = [r for r in recs if CLAIM_GROUP_KEYS["claims.general"](r["claim"]) and r["status"] != "not-applicable"
          and r["expected"] == "pass" and r["status"] == "pass" and r["residual"] is not None
          and r["claim"] not in ORDER_CLAIMS]
    return max(rs, key=lambda r: r["residual"])


def _problems(out):
    from ldaspark.lab.reports.summary import quote_problem, readme_values
    values = readme_values(str(out))
    text = README.read_text()
    return [p for p in (quote_problem(k, v, values, str(out)) for k, v in MARK.findall(text)) if p]


def test_readme_holds_after_the_main_job_on_another_machine(tmp_path):
    import json
    from ldaspark.lab.reports.summary import readme_values
    out, recs = _another_machine(tmp_path)
    _general_max_record(recs)["residual"] *= 9.9 / 6.3
    _write_claims(out, recs)
    _rewrite_timing(out)
    values = readme_values(str(out))
    # the simulated run really differs where a machine can differ ...
    text = README.read_text()
    shown = dict(MARK.findall(text))
    assert values["wp.particle.ratios"] != shown["wp.particle.ratios"]
    assert values["claims.general.max"] != shown["claims.general.max"]
    assert values["run.wall"] != shown["run.wall"] and "run.probe_ratio" in values
    assert "readme" in json.loads((out / "report_timing.json").read_text())     # the writer kept the snapshot
    # ... and README still agrees with it
    assert _problems(out) == []


def test_readme_check_fails_on_a_wrong_verdict_or_residual_class(tmp_path):
    # negative controls on the same simulated machine: a count that changes (one general record
    # fails), a residual of another order of magnitude, a README timing that the snapshot lacks
    out, recs = _another_machine(tmp_path)
    _rewrite_timing(out)
    bad = [dict(r) for r in recs]
    _general_max_record(bad)["status"] = "fail"
    _write_claims(out, bad)
    assert any("claims.general shows" in p for p in _problems(out))
    bad = [dict(r) for r in recs]
    _general_max_record(bad)["residual"] *= 1e3
    _write_claims(out, bad)
    assert [p for p in _problems(out) if "claims.general.max" in p and "order of magnitude" in p]
    _write_claims(out, recs)
    assert _problems(out) == []
    import json
    d = json.loads((out / "report_timing.json").read_text())
    d["readme"]["values"]["wp.particle.ratios"] = "90x / 80x / 70x"
    (out / "report_timing.json").write_text(json.dumps(d))
    assert [p for p in _problems(out) if "wp.particle.ratios" in p and "snapshot" in p]


def test_readme_timings_are_strict_while_the_reports_are_the_snapshots(tmp_path):
    # in the committed state (the report files of the snapshot) a stale timing fails even if the
    # snapshot was left stale with it: README, snapshot and reports must agree
    import json
    import shutil
    out = tmp_path / "reports"
    shutil.copytree(README.parent / "reports", out, ignore=shutil.ignore_patterns("figures"))
    # the copy's own snapshot, so that this holds also after the main job rewrote reports/ here
    from ldaspark.lab.reports.summary import write_snapshot
    write_snapshot(str(out))
    d = json.loads((out / "report_timing.json").read_text())
    key = "wp.sps.median"
    d["readme"]["values"][key] = "999x"
    (out / "report_timing.json").write_text(json.dumps(d))
    from ldaspark.lab.reports.summary import quote_problem, readme_values
    values = readme_values(str(out))
    assert quote_problem(key, "999x", values, str(out)) is not None      # the reports give another value
    assert quote_problem(key, values[key], values, str(out)) is not None  # the snapshot gives another value
