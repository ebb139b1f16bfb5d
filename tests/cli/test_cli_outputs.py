"""Two outputs of one command never name the same file: the second write replaced the first, and
the run ended with exit 0 and one of the two files missing (found by probe t17)."""
import io
import os
import types

import pytest

from ldaspark.cli import main
from run_helpers import main_rc_err


class _Reached(Exception):
    """The command got past its checks and started its computation (a stand-in here)."""


def _rc_err(capsys, argv):
    return main_rc_err(capsys, argv)


def _refused_as_same_file(rc, err):
    assert rc == 2 and err.count("\n") == 1 and "name the same file" in err and "Traceback" not in err, (rc, err)


def test_audit_out_and_json_on_one_file_is_refused(capsys, tmp_path):
    """``audit --out F --json F`` wrote the report, then replaced it with the JSON (exit 0); through
    a symbolic link too. Control: two paths get both files, and /dev/null takes both writes."""
    base = ["audit", "--example", "gauss2", "--quick"]
    rc, _ = _rc_err(capsys, base + ["--out", str(tmp_path / "r.md"), "--json", str(tmp_path / "r.json")])
    assert rc == 0 and (tmp_path / "r.md").read_text().startswith("#") and (tmp_path / "r.json").exists()
    rc, _ = _rc_err(capsys, base + ["--out", os.devnull, "--json", os.devnull])
    assert rc == 0
    same = str(tmp_path / "same.out")
    _refused_as_same_file(*_rc_err(capsys, base + ["--out", same, "--json", same]))
    assert not os.path.exists(same)
    os.symlink("same.out", tmp_path / "link.out")
    _refused_as_same_file(*_rc_err(capsys, base + ["--out", same, "--json", str(tmp_path / "link.out")]))


def test_verify_json_on_its_own_ledger_is_refused(capsys, tmp_path, monkeypatch):
    """``verify --json OUTDIR/claims-quick.md`` replaced the markdown ledger by the JSON records, and
    the summary line pointed at it for the findings. Refused before the ledger runs (a stand-in
    here); control: another --json path reaches the run."""
    from ldaspark.lab.reports import claims

    def reached(*a, **k):
        raise _Reached
    monkeypatch.setattr(claims, "run_ledger", reached)
    out = tmp_path / "rep"
    argv = ["verify", "--quick", "--jobs", "1", "--outdir", str(out)]
    with pytest.raises(_Reached):
        main(argv + ["--json", str(tmp_path / "records.json")])
    _refused_as_same_file(*_rc_err(capsys, argv + ["--json", str(out / "claims-quick.md")]))
    # the checkpoint's name: the records were written there, then removed with the checkpoint
    # once the ledger was written (exit 0 and no --json file)
    _refused_as_same_file(*_rc_err(capsys, argv + ["--json", str(out / "claims-quick.partial.jsonl")]))


def test_report_convergence_json_on_its_markdown_is_refused(capsys, tmp_path, monkeypatch):
    """``report convergence --json OUTDIR/convergence.md --outdir OUTDIR``: the report replaced the
    JSON records. Control: --json OUTDIR/convergence.json (the same records the section writes
    there) reaches the run."""
    from ldaspark.lab.reports import convergence

    def reached(*a, **k):
        raise _Reached
    monkeypatch.setattr(convergence, "compute", reached)
    out = tmp_path / "rep"
    argv = ["report", "convergence", "--scenes", "particle", "--methods", "gauss-1", "--t-end", "0.5",
            "--outdir", str(out)]
    with pytest.raises(_Reached):
        main(argv + ["--json", str(out / "convergence.json")])
    _refused_as_same_file(*_rc_err(capsys, argv + ["--json", str(out / "convergence.md")]))


def test_report_convergence_runs_a_repeated_scene_or_method_once(capsys, tmp_path, monkeypatch):
    """``--scenes particle particle --methods gauss-1 gauss-1`` computed the particle's reference
    twice and wrote every record four times (12 records for 3). Control: distinct names keep their
    order."""
    from ldaspark.lab.reports import convergence
    seen = []

    def compute(scenes, methods, t_end, workers):
        seen.append((list(scenes), list(methods)))
        raise _Reached
    monkeypatch.setattr(convergence, "compute", compute)
    base = ["report", "convergence", "--t-end", "0.5", "--json", str(tmp_path / "c.json")]
    for scenes, methods in ((["skate", "particle"], ["gauss-2", "gauss-1"]),
                            (["particle", "particle"], ["gauss-1", "gauss-1"])):
        with pytest.raises(_Reached):
            main(base + ["--scenes", *scenes, "--methods", *methods])
    assert seen == [(["skate", "particle"], ["gauss-2", "gauss-1"]), (["particle"], ["gauss-1"])]


def test_audit_command_reproduces_the_audit(capsys, tmp_path):
    """The JSON's ``command`` ("the command line that reproduces the audit", docs/audit.md) wrote a
    path with a space unquoted (three words) and left out --max-stages. Now it is shell-quoted and
    complete: run again, it gives the same checks. Control: a built-in's command keeps its words."""
    import json
    import shlex
    import shutil
    import ldaspark
    src = tmp_path / "a b ü.json"
    shutil.copy(os.path.join(os.path.dirname(ldaspark.__file__), "data", "tableaux", "gauss2.json"), src)
    first = tmp_path / "first.json"
    assert main(["audit", str(src), "--quick", "--max-stages", "25", "--json", str(first)]) == 0
    d = json.loads(first.read_text())
    words = shlex.split(d["command"])
    assert words[:3] == ["ldaspark", "audit", str(src)] and words[-2:] == ["--max-stages", "25"], d["command"]
    again = tmp_path / "again.json"
    assert main(words[1:] + ["--json", str(again)]) == 0
    e = json.loads(again.read_text())
    assert [(c["name"], c["status"]) for c in e["checks"]] == [(c["name"], c["status"]) for c in d["checks"]]
    assert main(["audit", "--method", "gauss-1", "--quick", "--json", str(tmp_path / "m.json")]) in (0, 1)
    assert json.loads((tmp_path / "m.json").read_text())["command"] == "ldaspark audit --method gauss-1 --dps 30 --quick"
    capsys.readouterr()


@pytest.mark.parametrize("section, stand_in, extra", [
    ("convergence", "compute", ["--scenes", "particle", "--methods", "gauss-1", "--t-end", "0.5"]),
    ("energy", "figure_data", ["--figure", "1", "--t-end", "1"]),
    ("systems", "build", ["--systems", "suslov"]),
    ("work-precision", "run_study", ["--quick"]),
    ("stability", "build_report", []),
])
def test_a_report_section_refuses_a_figures_path_that_is_no_directory_before_it_runs(
        capsys, tmp_path, monkeypatch, section, stand_in, extra):
    """``report SECTION --outdir D`` with D/figures a regular file computed the whole section, then
    failed on its first plot ("cannot write D/figures/convergence_gauss.png: Not a directory"; the
    systems section also reported its bicycle part failed). Now refused before the run (a stand-in
    here). Control: the same D without that file reaches the run."""
    import importlib
    mod = importlib.import_module("ldaspark.lab.reports." + section.replace("-", "_"))

    def reached(*a, **k):
        raise _Reached
    monkeypatch.setattr(mod, stand_in, reached)
    good, bad = tmp_path / "good", tmp_path / "bad"
    bad.mkdir()
    (bad / "figures").write_text("not a directory")
    with pytest.raises(_Reached):
        main(["report", section, *extra, "--outdir", str(good)])
    rc, err = _rc_err(capsys, ["report", section, *extra, "--outdir", str(bad)])
    assert rc == 2 and err.count("\n") == 1 and "figures is not a directory" in err, (rc, err)
    assert (bad / "figures").read_text() == "not a directory"


@pytest.mark.parametrize("section, stand_in, extra, name", [
    ("energy", "run_default", ["--t-end", "15"], "energy.md"),
    ("energy", "run_default", ["--t-end", "15"], "energy.json"),
    ("convergence", "compute", ["--scenes", "particle", "--methods", "gauss-1", "--t-end", "0.5"], "convergence.json"),
    ("systems", "build", ["--systems", "suslov"], "systems.md"),
    ("work-precision", "run_study", ["--quick"], "work_precision.md"),
    ("stability", "build_report", [], "stability.json"),
    ("claims", "run_ledger", ["--quick"], "claims-quick.md"),       # control: refused before too
    (None, "run_sections", [], "energy.md"),                        # the main job: every section's files
    (None, "run_sections", [], "claims.json"),
])
def test_a_report_section_refuses_its_own_report_path_that_is_no_file_before_it_runs(
        capsys, tmp_path, monkeypatch, section, stand_in, extra, name):
    """``report energy --outdir D`` with D/energy.md a directory computed every figure (minutes
    for the paper's intervals), wrote the PNGs, then failed on energy.md; likewise the other
    sections' .md / .json and the main job. Now refused before the run (a stand-in here). Control:
    the same D without that directory reaches the run."""
    import importlib
    import ldaspark.lab.reports.timing as timing
    mod = importlib.import_module("ldaspark.lab.reports." + (section or "jobs").replace("-", "_"))

    def reached(*a, **k):
        raise _Reached
    monkeypatch.setattr(mod, stand_in, reached)
    monkeypatch.setattr(timing, "probe_cpu", lambda: 1.0)     # the main job's CPU probe: not under test
    words = ["report", section, *extra] if section else ["report", "--workers", "1"]
    good, bad = tmp_path / "good", tmp_path / "bad"
    (bad / name).mkdir(parents=True)
    with pytest.raises(_Reached):
        main([*words, "--outdir", str(good)])
    rc, err = _rc_err(capsys, [*words, "--outdir", str(bad)])
    assert rc == 2 and err.count("\n") == 1 and f"{name}: it is a directory" in err, (rc, err)
    # nothing computed, nothing written: OUTDIR/figures is made (empty) by the check of that directory
    assert set(os.listdir(bad)) <= {name, "figures"} and not os.listdir(bad / name)
    assert not (bad / "figures").exists() or not os.listdir(bad / "figures")


def test_an_output_on_the_input_tableau_is_refused(capsys, tmp_path):
    """``audit t.json --json t.json`` and ``integrate ... custom --tableau t.json --out t.json``
    replaced the tableau file by the audit or the result (exit 0: the input was lost). Control:
    another output path runs, and the tableau is left as it was."""
    import shutil
    import ldaspark
    tab = tmp_path / "t.json"
    shutil.copy(os.path.join(os.path.dirname(ldaspark.__file__), "data", "tableaux", "gauss2.json"), tab)
    before = tab.read_bytes()
    integrate = ["integrate", "skate", "custom", "--tableau", str(tab), "--h", "0.5", "--t-end", "1"]
    assert main(integrate + ["--out", str(tmp_path / "r.json")]) == 0
    assert main(["audit", str(tab), "--quick", "--json", str(tmp_path / "a.json")]) == 0
    capsys.readouterr()
    _refused_as_same_file(*_rc_err(capsys, ["audit", str(tab), "--quick", "--json", str(tab)]))
    _refused_as_same_file(*_rc_err(capsys, ["audit", str(tab), "--quick", "--out", str(tab)]))
    _refused_as_same_file(*_rc_err(capsys, integrate + ["--out", str(tab)]))
    assert tab.read_bytes() == before


def test_report_convergence_refuses_a_comparator_the_scene_cannot_run_before_it_runs(capsys, tmp_path, monkeypatch):
    """``report convergence --scenes bicycle`` ran every method (5 min at --t-end 0.1), then
    mp-lobatto-iiib-a-2 (semi-implicit: the mechanical form) raised and nothing was written. Named
    in --methods it is refused now, one line, before any reference (a stand-in here); in the
    default list it is skipped on such a scene, with a line saying why (the general scenes' rule).
    Controls: the same method on the particle reaches the run and is measured there."""
    from ldaspark.lab.reports import convergence

    def reached(*a, **k):
        raise _Reached
    monkeypatch.setattr(convergence, "compute", reached)
    argv = ["report", "convergence", "--methods", "gauss-1", "mp-lobatto-iiib-a-2", "--t-end", "0.1",
            "--json", str(tmp_path / "c.json")]
    with pytest.raises(_Reached):
        main(argv + ["--scenes", "particle"])
    rc, err = _rc_err(capsys, argv + ["--scenes", "particle", "bicycle"])
    assert rc == 2 and err.count("\n") == 1, (rc, err)
    assert "mp-lobatto-iiib-a-2 cannot run on the scene bicycle" in err and "mechanical form" in err

    measured = []
    monkeypatch.setattr(convergence, "reference_for", lambda *a, **k: types.SimpleNamespace(kind="stand-in"))
    monkeypatch.setattr(convergence, "measure_errors", lambda meth, *a, **k: measured.append(meth) or {})
    monkeypatch.setattr(convergence, "order_records", lambda *a, **k: [])
    log = io.StringIO()
    convergence.run_scene("bicycle", ["mp-lobatto-iiib-a-2", "gauss-1"], 0.1, log=log)
    assert measured == ["gauss-1"] and "mp-lobatto-iiib-a-2" in log.getvalue() and "skipped" in log.getvalue()
    convergence.run_scene("particle", ["mp-lobatto-iiib-a-2"], 0.1, log=io.StringIO())
    assert measured == ["gauss-1", "mp-lobatto-iiib-a-2"]
