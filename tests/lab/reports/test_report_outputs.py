"""Where the report writers write: every section takes --outdir, the quick ledger never
overwrites the full one, and the main job's job runner writes each section from its jobs'
results (with the run's CPU time in the file). Cost: ~3 s (fake ledger, one tiny fake section)."""
import sys
import types

import pytest

from ldaspark.cli import build_parser, main
from ldaspark.lab.reports import claims, jobs
from ldaspark.lab.reports.driver import available_sections
from ldaspark.lab.claims.ledger import record


def _fake_ledger(monkeypatch):
    rec = record("22a", "gauss-1", "-", "pass", 0.0, "pass", note="tangential |k| = 0")
    monkeypatch.setattr(claims, "run_ledger", lambda *a, **k: [dict(rec)])
    monkeypatch.setattr(claims, "extra_records", lambda *a, **k: [])


def test_verify_quick_writes_its_own_files(tmp_path, monkeypatch, capsys):
    _fake_ledger(monkeypatch)
    full = tmp_path / "claims.md"
    full.write_text("the full ledger\n")
    assert main(["verify", "--quick", "--outdir", str(tmp_path)]) == 0
    assert full.read_text() == "the full ledger\n"                  # untouched
    assert (tmp_path / "claims-quick.md").exists() and (tmp_path / "claims-quick.json").exists()
    assert not (tmp_path / "claims.json").exists()
    assert "claims-quick.md" in capsys.readouterr().out
    text = (tmp_path / "claims-quick.md").read_text()
    assert "tangential \\|k\\| = 0" in text                           # pipes in notes escaped
    # negative control: the full run writes claims.md
    assert main(["verify", "--outdir", str(tmp_path)]) == 0
    assert full.read_text() != "the full ledger\n"


@pytest.mark.parametrize("section", sorted(available_sections()))
def test_every_section_takes_outdir(section):
    args = build_parser("report").parse_args(["report", section, "--outdir", "somewhere"])
    assert args.outdir == "somewhere"


def test_main_job_takes_outdir_full_and_workers():
    args = build_parser("report").parse_args(["report", "--outdir", "x", "--full", "--workers", "1"])
    assert args.outdir == "x" and args.full and args.workers == 1 and args.section is None


def _section_dests(parser, section):
    """The option dests of ``ldaspark report SECTION`` (its subparser's own options)."""
    import argparse
    rep = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices["report"]
    sub = next(a for a in rep._actions if isinstance(a, argparse._SubParsersAction)).choices[section]
    return {a.dest for a in sub._actions if a.option_strings}


@pytest.mark.parametrize("section", sorted(available_sections()))
def test_main_job_options_before_a_section_reach_it_or_are_refused(section, tmp_path, monkeypatch, capsys):
    """``ldaspark report --outdir X systems`` parsed to outdir = reports (the section's default
    overwrote X in silence: the section wrote into the repository's reports/); ``--workers 3
    convergence`` ran with 2 workers, ``--full convergence`` / ``--workers 3 stability`` were
    ignored. The section now gets the value when it has the option, else one line and exit 2."""
    from ldaspark.core.errors import InputError
    from ldaspark.lab.reports import driver
    monkeypatch.chdir(tmp_path)
    p = build_parser("report")
    own = _section_dests(p, section)
    seen = {}
    for opt, val, want in (("--outdir", str(tmp_path / "x"), str(tmp_path / "x")), ("--workers", "3", 3),
                           ("--full", None, True), ("--scheduler", "tcp://127.0.0.1:1", "tcp://127.0.0.1:1")):
        dest = opt[2:]
        args = p.parse_args(["report", opt] + ([val] if val else []) + [section])
        args.section_run = lambda a: seen.update(value=getattr(a, dest, None)) or 0     # the section's work
        seen.clear()
        if dest in own:
            assert driver.run(args) == 0 and seen["value"] == want, (opt, seen)
        else:
            with pytest.raises(InputError, match="option of the main job"):
                driver.run(args)
            assert not seen
    # through the command line: one line, exit 2, before any work (nothing written)
    if "full" not in own:
        assert main(["report", "--full", section]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "--full is an option of the main job" in err
    if "outdir" in own:
        args = p.parse_args(["report", "--outdir", "a", section, "--outdir", "b"])
        with pytest.raises(InputError, match="before and after"):
            driver.run(args)
    assert [f for f in tmp_path.rglob("*") if not f.is_dir()] == []       # OUTDIR made, nothing written


@pytest.mark.parametrize("argv", [["report", "--outdir", "/proc/ldaspark-no-such-dir"],
                                  ["report", "energy", "--figure", "2", "--outdir", "/proc/ldaspark-no-such-dir"],
                                  ["report", "systems", "--outdir", "/proc/ldaspark-no-such-dir"]])
def test_an_outdir_that_cannot_be_written_is_refused_before_the_run(argv, capsys, monkeypatch):
    """``ldaspark report --outdir /proc/x`` (a directory that cannot be made or written) ran the
    sections (energy 15 s, the main job to the end) and then failed writing; one line and exit 2
    before any work now (the sections' work is replaced by a marker that must not run)."""
    import os
    from ldaspark.lab.reports import driver
    if not os.path.isdir("/proc/self"):
        pytest.skip("needs procfs")
    from ldaspark.core.errors import LdasparkError
    ran = []
    args = build_parser("report").parse_args(argv)
    monkeypatch.setattr(driver, "available_sections", lambda: {})
    monkeypatch.setattr("ldaspark.lab.reports.jobs.run_sections", lambda *a, **k: ran.append(1) or {})
    monkeypatch.setattr("ldaspark.lab.reports.timing.probe_cpu", lambda: ran.append(1))
    if getattr(args, "section", None):
        args.section_run = lambda a: ran.append(1) or 0
    with pytest.raises(LdasparkError, match="ldaspark-no-such-dir"):
        driver.run(args)
    assert ran == []


def _fake_section():
    mod = types.ModuleType("ldaspark_fake_section")
    mod.square = lambda x: x * x

    def _jobs(full=False):
        return [(("sq", i), "square", (i,), float(i)) for i in range(5)]

    def _write(results, outdir, full=False, clock=None, command=None):
        mod.written = (dict(results), clock.cpu, clock.shared, command)
    mod.jobs, mod.write = _jobs, _write
    sys.modules[mod.__name__] = mod          # the forked workers find it by name
    return mod


def test_run_sections_pools_jobs_and_writes_each_section(tmp_path):
    mod = _fake_section()
    try:
        stats = jobs.run_sections({"fake": mod}, str(tmp_path), workers=2, say=lambda *a: None)
    finally:
        del sys.modules[mod.__name__]
    results, cpu, shared, command = mod.written
    assert results == {("sq", i): i * i for i in range(5)}
    assert shared and command == "ldaspark report" and cpu >= 0 and stats["fake"]["jobs"] == 5
    # longest first
    assert [p[2] for p in jobs.plan({"fake": mod}, "x")] == [("sq", i) for i in (4, 3, 2, 1, 0)]


def test_compiled_jobs_start_after_the_kernels_compile_once():
    """A section's COMPILED_JOBS run after every other job, behind one job that compiles the
    kernels (so that the workers load them from numba's cache instead of compiling them twice);
    without compiled jobs there is no such job (control)."""
    mod = _fake_section()
    try:
        plain = jobs.plan({"fake": mod}, "x")
        mod.COMPILED_JOBS = ("_sq",)
        mod.jobs = lambda full=False: [(("sq", i), "_sq", (i,), float(i)) for i in range(3)] + \
            [(("cube", i), "_cube", (i,), 0.1) for i in range(2)]
        p = jobs.plan({"fake": mod}, "x")
    finally:
        del sys.modules[mod.__name__]
    assert all(q[1] != "prelude" for q in plain)
    assert p[0][1] == "prelude" and p[0][4] == "warm_kernels"
    assert [q[2] for q in p[1:]] == [("cube", 0), ("cube", 1), ("sq", 2), ("sq", 1), ("sq", 0)]


def test_inline_executor_delivers_results_and_errors():
    ex = jobs.InlineExecutor()
    assert ex.submit(pow, 2, 10).result() == 1024
    with pytest.raises(ZeroDivisionError):
        ex.submit(lambda: 1 / 0).result()


@pytest.mark.exhaustive
def test_claims_jobs_give_the_serial_ledger(tmp_path, monkeypatch):
    # the main job's claims jobs, concatenated in job order, are the records of one serial run
    # (s = 1, particle only, and the claim groups: ~45 s)
    import functools
    import json
    from ldaspark.lab.claims import ledger
    monkeypatch.setattr(claims, "MAX_S", 1)
    monkeypatch.setattr(ledger, "LEDGER_SCENES", ("particle",))
    if not hasattr(ledger, "_ledger_task"):
        monkeypatch.setattr(claims, "run_ledger", functools.partial(ledger.run_ledger, scenes=("particle",)))
    jobs.run_sections({"claims": claims}, str(tmp_path), workers=2, say=lambda *a: None)
    got = json.loads((tmp_path / "claims.json").read_text())
    ser = ledger.run_ledger(max_s=1, scenes=("particle",)) + ledger.extra_records()   # + the groups, serially
    strip = lambda rs: [{k: v for k, v in r.items() if k != "seconds"} for r in rs]   # noqa: E731
    assert strip(got) == strip(ser)


@pytest.mark.parametrize("figure", ["2", "4"])
def test_report_energy_checks_json_before_the_figure_is_computed(figure, tmp_path, monkeypatch, capsys):
    """``report energy --figure N --json DIR``: refused before the runs (Fig. 4 integrates to
    t = 50000; the directory was refused after it), one line and exit 2."""
    from ldaspark.lab.reports import energy
    ran = []
    monkeypatch.setattr(energy, "figure4", lambda **k: ran.append(4))
    monkeypatch.setattr(energy, "figure_data", lambda *a, **k: ran.append(int(figure)))
    rc = main(["report", "energy", "--figure", figure, "--json", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "directory" in err[0], err
    assert ran == []


@pytest.mark.parametrize("section", ["stability", "systems"])
def test_report_outdir_that_is_not_a_directory_is_refused_before_the_section(section, tmp_path, monkeypatch,
                                                                             capsys):
    """``report SECTION --outdir FILE``: one line, exit 2, before the section's runs (they ran in
    full and the writer failed on FILE/figures at the end); the file is untouched."""
    import importlib
    mod = importlib.import_module(available_sections()[section])
    ran = []
    monkeypatch.setattr(mod, "run", lambda args: ran.append(1) or 0)
    monkeypatch.setattr(mod, "build_report", lambda *a, **k: ran.append(1), raising=False)
    f = tmp_path / "notadir"
    f.write_text("keep\n")
    rc = main(["report", section, "--outdir", str(f)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "not a directory" in err[0], err
    assert ran == [] and f.read_text() == "keep\n"


def test_local_worker_counts_with_a_scheduler_are_refused(tmp_path, monkeypatch, capsys):
    """``verify --jobs N --scheduler ADDR`` and ``report --workers N --scheduler ADDR`` ran on the
    cluster's workers and dropped N (accepted and ignored). One line and exit 2 before any work now
    (the ledger and the jobs are replaced by markers that record a run). Controls: each count
    alone, and the scheduler alone, reach the work."""
    ran = []

    def verify(outdir, quick, js, cmd, jobs_, where=None, resume=True):
        ran.append(("verify", jobs_, where))
        return []

    def sections(modules, outdir, full=False, workers=2, say=print, where=None):
        ran.append(("report", workers, where))
        return {}
    monkeypatch.setattr(claims, "run_verify", verify)
    monkeypatch.setattr(jobs, "run_sections", sections)
    from ldaspark.lab.reports import driver, timing
    monkeypatch.setattr(timing, "probe_cpu", lambda: {})
    monkeypatch.setattr(driver, "write_run_timing", lambda *a, **k: None)
    out, addr = str(tmp_path), "tcp://127.0.0.1:1"
    assert main(["verify", "--jobs", "2", "--scheduler", addr, "--outdir", out]) == 2
    assert main(["report", "--workers", "2", "--scheduler", addr, "--outdir", out]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert ran == [] and len(err) == 2
    assert "--jobs sets the local worker processes" in err[0] and "--workers sets the local" in err[1]
    assert main(["verify", "--jobs", "2", "--outdir", out]) == 0
    assert main(["verify", "--scheduler", addr, "--outdir", out]) == 0
    assert main(["report", "--workers", "2", "--outdir", out]) == 0
    assert main(["report", "--scheduler", addr, "--outdir", out]) == 0
    assert ran[0] == ("verify", 2, None) and ran[1] == ("verify", None, addr)
    assert ran[2] == ("report", 2, None) and ran[3][2] == addr
