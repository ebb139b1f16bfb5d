"""The README's example must run as written and do what it says."""
import pathlib
import re

import numpy as np

README = pathlib.Path(__file__).resolve().parents[1] / "README.md"


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
    assert 'pip install -q -e ".[test]"' in ci and 'pip install -e ".[test]"' in text


# --- README quotes the reports: every number in the findings and speed tables is marked with the
# key it comes from (<!--KEY-->text<!--/-->, see ldaspark.reports.summary) and equals the value
# computed from the committed reports' JSON; verdict words are marked the same way.
from ldaspark.reports.summary import MARK  # noqa: E402
# numbers that are not measurements: equation references "(22a)", "(23a-d)", "(3a-b)", stage
# counts "s = 2", section numbers "8.4"
NOT_MEASURED = re.compile(
    r"\(\d+[a-f]?(?:-[a-f])?\)"          # equation references (22a), (23a-d), (3a-b)
    r"|\bs = \d\b|\b\d+ digits\b"          # stage counts, working precision
    r"|\bh = [\d.]+|\brtol [\d.e-]+"        # step sizes and tolerances of the runs
    r"|_\{[^}]*\}|[A-Za-z][\w-]*\d\w*"      # subscripts v_{k+1/2}, names q0, t1, gauss-2
    r"|!?= 0\b")                            # "k != 0"


def _quoted_tables(text):
    """(heading, rows as lists of cells) of README's findings and speed tables."""
    out = []
    for heading in ("## What the suite found", "## Speed and accuracy"):
        assert heading in text, f"README lost its table '{heading}'"
        block = text.split(heading, 1)[1].split("\n## ", 1)[0]
        rows = [ln for ln in block.split("\n") if ln.startswith("|")][2:]     # skip header, delimiter
        cells = []
        for ln in rows:
            parts = [c.strip() for c in re.split(r"(?<!\\)\|", ln.strip())[1:-1]]
            assert len(parts) >= 2, ln
            cells.append(parts)
        out.append((heading, cells))
    return out


def check_readme_quotes(text, values):
    """Problems: marked values that differ from the reports, unknown keys, unmarked numbers."""
    problems = []
    for heading, cells in _quoted_tables(text):
        for row in cells:
            for key, shown in MARK.findall(" | ".join(row)):
                if key not in values:
                    problems.append(f"{heading}: unknown key {key}")
                elif shown != values[key]:
                    problems.append(f"{heading}: {key} shows {shown!r}, the reports give {values[key]!r}")
            rest = NOT_MEASURED.sub("", MARK.sub("", row[1]))       # the verdict / measured column
            if re.search(r"\d", rest):
                problems.append(f"{heading}: unmarked number in {row[1]!r}")
    return problems


def test_readme_numbers_and_verdicts_come_from_the_reports():
    from ldaspark.reports.summary import readme_values
    values = readme_values(str(README.parent / "reports"))
    text = README.read_text()
    assert MARK.search(text), "README's tables carry no <!--KEY-->value<!--/--> marks"
    assert check_readme_quotes(text, values) == []
    # marks in the prose too (the main job's measured time comes from reports/report_timing.json)
    stale = [(k, v, values.get(k)) for k, v in MARK.findall(text) if values.get(k) != v]
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
    assert check_readme_quotes(ok, {"convergence.spark": "120 of 120", "wp.sps.median": "178x"}) == []


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
