"""The CLI on user errors: exit code 2, exactly one line on stderr starting with
"ldaspark: error:", no traceback, no warning lines, and no output file left behind."""
import json
import os
import subprocess
import sys

import pytest
import sympy

import ldaspark.models.scenes as scenes
from ldaspark.cli import main

OK = ["integrate", "skate", "gauss-1", "--h", "0.5", "--t-end", "1"]


def _one_error_line(capsys, argv, code=2, match=None):
    try:
        rc = main(argv)
    except SystemExit as exc:      # argparse usage errors exit from parse_args
        rc = exc.code
    out, err = capsys.readouterr()
    lines = err.strip("\n").split("\n")
    assert rc == code, (rc, err)
    assert len(lines) == 1 and lines[0].startswith("ldaspark: "), err
    assert "Traceback" not in err and "Warning" not in err
    if match:
        assert match in lines[0], lines[0]
    return lines[0]


def _tab(tmp_path, text):
    p = tmp_path / "t.json"
    p.write_text(text)
    return str(p)


USER_ERRORS = [
    (["--h", "0"], "nonzero"),
    (["--h", "nan"], "finite"),
    (["--h", "abc"], "must be numbers"),
    (["--t-end", "inf"], "finite"),            # was OverflowError traceback
    (["--t-end", "0.3"], "multiple"),
    (["--t-end", "-1"], "not reached"),
    (["--h", "1e-300"], "steps"),               # was a hang (1e300 steps)
    (["--dps", "2"], "dps"),
    (["--dps", "20.5"], "invalid int"),
    (["--ic", "3"], "--ic"),
    (["--newton", "secant"], "invalid choice"),     # quasi is a kind since issue 48
]


@pytest.mark.parametrize("extra, match", USER_ERRORS)
def test_integrate_user_errors(capsys, tmp_path, extra, match):
    out = tmp_path / "o.json"
    argv = OK + ["--out", str(out)]
    for i in range(0, len(extra), 2):   # replace or add the option
        if extra[i] in argv:
            argv[argv.index(extra[i]) + 1] = extra[i + 1]
        else:
            argv += extra[i:i + 2]
    _one_error_line(capsys, argv, match=match)
    assert not out.exists()


@pytest.mark.parametrize("argv, match", [
    (["integrate", "nosuch", "gauss-1", "--h", "0.5", "--t-end", "1", "--out", "X"], "unknown scene"),
    (["integrate", "skate", "gauss-x", "--h", "0.5", "--t-end", "1", "--out", "X"], "unknown method"),
    (["integrate", "skate", "gauss-0", "--h", "0.5", "--t-end", "1", "--out", "X"], "s >= 1"),
    (["integrate", "mp-particles", "gauss-1", "--ic", "99", "--h", "0.5", "--t-end", "1", "--out", "X"], "0..9"),
    (["integrate", "skate", "custom", "--h", "0.5", "--t-end", "1", "--out", "X"], "--tableau"),
    (["integrate", "skate", "gauss-1", "--tableau", "t.json", "--h", "0.5", "--t-end", "1", "--out", "X"], "custom"),
    (["integrate", "skate", "gauss-1", "--h", "0.5", "--t-end", "1"], "--out"),
    (["frobnicate"], "invalid choice"),
])
def test_argument_errors(capsys, tmp_path, argv, match):
    argv = [str(tmp_path / a) if a == "X" else a for a in argv]
    _one_error_line(capsys, argv, match=match)
    assert not (tmp_path / "X").exists()


@pytest.mark.parametrize("argv, name", [
    (["audit", "--method", "gauss-1", "--quick", "--json", ""], "--json"),
    (["audit", "--method", "gauss-1", "--quick", "--out", " "], "--out"),
    (["methods", "--json", ""], "--json"),
    (["audit", ""], "FILE"),
    (["integrate", "skate", "gauss-1", "--h", "0.5", "--t-end", "1", "--out", ""], "--out"),
])
def test_an_empty_output_path_is_refused_not_ignored(capsys, tmp_path, monkeypatch, argv, name):
    """An empty --json / --out was read as "not given" (the report went to stdout, exit 0): one
    line, exit 2, before any work; a real path runs (control: ``methods --json``)."""
    monkeypatch.chdir(tmp_path)
    _one_error_line(capsys, argv, match=f"{name} is an empty path")
    assert main(["methods", "--max-s", "1", "--json", "m.json"]) == 0 and (tmp_path / "m.json").is_file()


@pytest.mark.parametrize("argv, name", [
    (["methods", "--json", "-"], "--json"),
    (["verify", "--json", "-"], "--json"),
    (["audit", "--method", "gauss-1", "--quick", "--json", "-"], "--json"),
    (["audit", "--method", "gauss-1", "--quick", "--out", "-"], "--out"),
    (["integrate", "skate", "gauss-1", "--h", "0.5", "--t-end", "1", "--out", "-"], "--out"),
    (["report", "energy", "--json", "-"], "--json"),
    (["report", "claims", "--outdir", "-"], "--outdir"),
    (["report", "--outdir", "-", "energy"], "--outdir"),      # the main job's option, given to a section
    (["mutants", "--outdir", "-"], "--outdir"),
])
def test_a_dash_output_path_is_refused_not_written_as_a_file(capfd, tmp_path, monkeypatch, argv, name):
    """``verify --json -`` (and every other output option) wrote a regular file (or made a
    directory) named "-": one line, exit 2, before any work, and nothing named "-" made. Controls:
    ``./-`` is a file named "-", and /dev/stdout is standard output."""
    import ldaspark.cli as cli
    import ldaspark.lab.mutants.command as mutants
    import ldaspark.lab.reports.claims as claims
    import ldaspark.lab.reports.energy as energy
    import ldaspark.lab.theory.audit as audit

    def work(args):
        raise AssertionError("the command ran before its output path was checked")
    for mod, attr in ((cli, "_run_integrate"), (mutants, "run"), (claims, "run"), (energy, "run"), (audit, "run")):
        monkeypatch.setattr(mod, attr, work)        # the parser takes them when it is built, in main()
    monkeypatch.chdir(tmp_path)
    _one_error_line(capfd, argv, match=f"{name} -: '-' is not standard output")     # fd 1 and 2 captured
    assert not os.path.lexists(tmp_path / "-")
    monkeypatch.undo()
    monkeypatch.chdir(tmp_path)
    assert main(["methods", "--max-s", "1", "--json", "./-"]) == 0 and (tmp_path / "-").is_file()
    capfd.readouterr()
    assert main(["methods", "--max-s", "1", "--json", "/dev/stdout"]) == 0
    assert '"method": "gauss-1"' in capfd.readouterr().out


def test_the_help_of_each_output_option_says_what_a_dash_means(capsys):
    """One line of help (the epilog) on every command with --out / --json / --outdir, and none on
    a command without them (control: the walk looks at the options, not at every parser)."""
    from ldaspark.cli import _DASH_HELP, build_parser
    parser = build_parser()
    subs = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction").choices
    for name in ("integrate", "methods", "verify", "audit", "mutants", "report"):
        assert subs[name].epilog == _DASH_HELP, name
    sections = next(a for a in subs["report"]._actions if a.__class__.__name__ == "_SubParsersAction").choices
    assert all(p.epilog == _DASH_HELP for p in sections.values())
    assert parser.epilog is None


@pytest.mark.parametrize("argv", [
    ["methods", "\x1b[31mred\nline two"],                 # unrecognized arguments: quoted raw
    ["integrate", "skate", "gauss-1", "--h", "0.5", "--t-end", "1", "--out", "o.json", "x\x1b]0;t\x07\ry"],
    ["methods", "--max-s", "1", "--bogus\x1b[2J"],
])
def test_argparse_errors_escape_the_users_control_characters(capsys, tmp_path, monkeypatch, argv):
    """argparse's own usage errors quote the user's words raw ("unrecognized arguments: ..."): a
    line break gave two lines on stderr, an ESC reached the terminal. One line now, with the
    controls written as escapes (as every LdasparkError message writes them)."""
    monkeypatch.chdir(tmp_path)
    line = _one_error_line(capsys, argv, match="unrecognized arguments")
    assert not any(ord(c) < 0x20 or ord(c) == 0x7f for c in line), repr(line)
    assert "\\x1b" in line                       # the escape is shown, not dropped


@pytest.mark.parametrize("text, match", [
    ("{not json", "not valid JSON"),
    ('{"c": [0.5]}', "missing"),
    ('{"c": [0.5], "A": [[0.5, 1]], "A_hat": [[0.5]], "A_tilde": [[0.5]], "b": [1], "b_hat": [1], "b_tilde": [1]}',
     "A must be"),
    ('{"c": ["x"], "A": [[0.5]], "A_hat": [[0.5]], "A_tilde": [[0.5]], "b": [1], "b_hat": [1], "b_tilde": [1]}',
     "not a number"),
    ('{"c": [NaN], "A": [[0.5]], "A_hat": [[0.5]], "A_tilde": [[0.5]], "b": [1], "b_hat": [1], "b_tilde": [1]}',
     "not finite"),
])
def test_bad_tableau_files(capsys, tmp_path, text, match):
    argv = ["integrate", "skate", "custom", "--tableau", _tab(tmp_path, text), "--h", "0.5", "--t-end", "1",
            "--out", str(tmp_path / "o.json")]
    _one_error_line(capsys, argv, match=match)


def test_missing_tableau_file(capsys, tmp_path):
    argv = ["integrate", "skate", "custom", "--tableau", str(tmp_path / "none.json"), "--h", "0.5", "--t-end", "1",
            "--out", str(tmp_path / "o.json")]
    _one_error_line(capsys, argv, match="not found")


def test_singular_newton_matrix_one_line_no_linalg_warning(capsys, tmp_path):
    # A_tilde = b_tilde = 0: the multipliers drop out of (21b, d), the Newton matrix is exactly
    # singular; scipy used to add a LinAlgWarning line next to the error.
    t = _tab(tmp_path, '{"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [[0]], '
                       '"b": [1], "b_hat": [1], "b_tilde": [0]}')
    argv = ["integrate", "skate", "custom", "--tableau", t, "--h", "0.1", "--t-end", "1",
            "--out", str(tmp_path / "o.json")]
    line = _one_error_line(capsys, argv, match="singular")
    assert "step 0" in line and "iteration 1" in line


def test_newton_divergence_one_line(capsys, tmp_path):
    argv = ["integrate", "robot", "gauss-2", "--h", "4", "--t-end", "8", "--out", str(tmp_path / "o.json")]
    line = _one_error_line(capsys, argv, match="Newton did not converge")
    assert "step 0" in line and "t = 0" in line and "residual" in line and "iterations" in line
    assert not (tmp_path / "o.json").exists()


@pytest.fixture
def inconsistent_skate(monkeypatch):
    def factory():
        sc = scenes.skate()
        sc.v0 = [0, sympy.Rational(3, 10), 1]
        return sc
    monkeypatch.setitem(scenes.SCENES, "skate", factory)


def test_inconsistent_initial_data_and_project_opt_in(capsys, tmp_path, inconsistent_skate):
    out = tmp_path / "o.json"
    line = _one_error_line(capsys, OK + ["--out", str(out)], match="inconsistent")
    assert "3.000e-01" in line and "--project" in line and not out.exists()
    assert main(OK + ["--out", str(out), "--project"]) == 0
    d = json.loads(out.read_text())
    assert max(abs(x) for row in d["constraint"] for x in row) < 1e-14
    assert d["v"][0] == pytest.approx([0.0, 0.0, 1.0], abs=1e-15)


def test_keyboard_interrupt_no_output(capsys, tmp_path, monkeypatch):
    import ldaspark.solve as solve

    def interrupted(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(solve, "integrate", interrupted)
    out = tmp_path / "o.json"
    _one_error_line(capsys, OK + ["--out", str(out)], code=130, match="interrupted")
    assert not out.exists() and os.listdir(tmp_path) == []


def test_unwritable_output(capsys, tmp_path):
    _one_error_line(capsys, OK + ["--out", str(tmp_path)], match="cannot write")   # a directory
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _one_error_line(capsys, OK + ["--out", str(blocker / "o.json")], match="cannot write")


def test_success_is_not_an_error(capsys, tmp_path):
    # negative control for the helper: a valid run exits 0 with nothing on stderr
    assert main(OK + ["--out", str(tmp_path / "o.json")]) == 0
    assert capsys.readouterr().err == ""


def test_subprocess_real_process_exit_code_and_stderr(tmp_path):
    # the real entry point, stderr as the user sees it (warnings included)
    cmd = [sys.executable, "-m", "ldaspark.cli", "integrate", "robot", "gauss-2", "--h", "4", "--t-end", "8",
           "--out", str(tmp_path / "o.json")]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("ldaspark: error:") and "Traceback" not in r.stderr


from hypothesis import given, settings, strategies as st  # noqa: E402


@settings(max_examples=8)
@given(st.one_of(st.text(max_size=8), st.sampled_from(["-0", "1e400", "-inf", "0x10", "1_0", " 0.5", "5e-324"])))
def test_any_step_string_is_rc0_or_one_line_rc2(h):
    # property: whatever the user types for --h, no traceback: success or one line + exit 2
    import tempfile
    from contextlib import redirect_stderr
    from io import StringIO
    with tempfile.TemporaryDirectory() as d:
        err = StringIO()
        with redirect_stderr(err):
            try:
                rc = main(["integrate", "skate", "gauss-1", "--h", h, "--t-end", "1", "--out", os.path.join(d, "o.json")])
            except SystemExit as exc:
                rc = exc.code
        e = err.getvalue()
        assert rc in (0, 2), (h, rc, e)
        if rc == 2:
            assert e.count("\n") == 1 and e.startswith("ldaspark: error:") and "Traceback" not in e
        else:
            assert os.path.exists(os.path.join(d, "o.json"))


def test_ctrl_c_while_the_signal_handling_loads_is_one_line(capsys, monkeypatch):
    """``cli.main`` imported its signal handling before its own try: a Ctrl-C there printed a
    traceback (and once exit 1). One line and 130 now; control: the same call without the
    interrupt runs."""
    import importlib.abc
    import sys as _sys

    class Interrupt(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name == "ldaspark.core.lifecycle":
                raise KeyboardInterrupt
            return None
    import ldaspark.core
    monkeypatch.delitem(_sys.modules, "ldaspark.core.lifecycle", raising=False)
    monkeypatch.delattr(ldaspark.core, "lifecycle", raising=False)
    monkeypatch.setattr(_sys, "meta_path", [Interrupt()] + _sys.meta_path)
    assert main(["methods", "--max-s", "1"]) == 130
    err = capsys.readouterr().err
    assert err == "ldaspark: interrupted\n"
    monkeypatch.undo()
    assert main(["methods", "--max-s", "1"]) == 0


@pytest.mark.parametrize("argv, match", [
    (["report", "convergence", "--scenes", "particle", "--methods", "gauss-1", "--t-end", "1e308"], "--t-end must be"),
    (["report", "convergence", "--scenes", "particle", "--methods", "nosuch-3"], "unknown method"),
    (["report", "convergence", "--scenes", "particle", "--methods", "gauss-1", "--json", "DIR"], "is a directory"),
    (["verify", "--quick", "--jobs", "1", "--json", "DIR", "--outdir", "OUT"], "is a directory"),
])
def test_long_reports_refuse_their_bad_arguments_before_the_run(capsys, tmp_path, argv, match):
    """--t-end 1e308 computed until killed; an unknown method was found after the reference; a
    --json that is a directory after the whole run (the markdown of the pair already written).
    Each is one line before any work now: nothing is written (control: the directory stays empty)."""
    (tmp_path / "DIR").mkdir()
    argv = [str(tmp_path / a) if a in ("DIR", "OUT") else a for a in argv]
    _one_error_line(capsys, argv, match=match)
    assert not (tmp_path / "OUT").exists() or not any((tmp_path / "OUT").iterdir())


def test_a_comparator_no_engine_runs_is_one_line_not_a_notice_and_an_error(tmp_path):
    """`integrate relativistic mp-lobatto-iiib-a-2` printed the fallback notice ('needs a system in
    mechanical form; using the generic engine') and then the generic comparator's refusal: two
    lines for one error. The refusal alone now (one line, exit 2); control: the modified method of
    8.4, which the generic engine runs on general systems, falls back with its notice and runs."""
    import subprocess
    import sys
    base = [sys.executable, "-m", "ldaspark", "integrate", "relativistic"]
    tail = ["--h", "0.1", "--t-end", "0.3", "--out", str(tmp_path / "o.json")]
    p = subprocess.run(base + ["mp-lobatto-iiib-a-2"] + tail, capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "mechanical form" in p.stderr, p.stderr
    assert not (tmp_path / "o.json").exists()
    p = subprocess.run(base + ["lobatto-iiia-iiib-2-modified"] + tail, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and "using the generic engine" in p.stderr and (tmp_path / "o.json").exists()
    # the same with --newton quasi where the compiled engine cannot run the method: the notice of
    # the fallback, then the refusal of quasi on the generic engine (two lines); one now
    skate = [sys.executable, "-m", "ldaspark", "integrate", "skate", "gauss-irk-2", "--newton", "quasi"]
    p = subprocess.run(skate + tail, capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "quasi" in p.stderr and "no compiled kernel" in p.stderr, \
        p.stderr
    # and a Newton option the comparator engine refuses: its refusal alone (the notice of the
    # fallback was printed first; it now waits until the fallback engine has taken the run)
    p = subprocess.run(skate[:-2] + ["--newton", "full"] + tail, capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "refuses Newton kind='full'" in p.stderr, p.stderr


@pytest.mark.parametrize("value", ["0", "-1", "6", str(10 ** 30)])
def test_methods_max_s_names_its_own_range(capsys, value):
    """``methods --max-s 0`` said "must be an integer between 1 and 1e+09" (the generic count
    bound) and 6 then "between 1 and 5": two ranges for one option. Control: 5 runs."""
    line = _one_error_line(capsys, ["methods", "--max-s", value])
    assert "between 1 and 5" in line and "1e+09" not in line, line
    assert main(["methods", "--max-s", "5"]) == 0


def test_methods_json_refused_before_the_table_is_printed(capsys, tmp_path):
    """``methods --json DIR`` printed the whole table, then refused DIR (exit 2 after output on
    stdout). Control: a file path gets the table and the file."""
    assert main(["methods", "--max-s", "2", "--json", str(tmp_path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "it is a directory" in err, (out, err)
    assert main(["methods", "--max-s", "2", "--json", str(tmp_path / "m.json")]) == 0
    assert "gauss-2" in capsys.readouterr().out and (tmp_path / "m.json").is_file()


def test_without_a_command_the_error_names_every_command(capsys):
    """``ldaspark`` alone: the error line lists the commands the parser has, the lab's registered
    ones too (it listed five of the six: ``mutants`` was missing). Control: the line starts as
    before and names integrate."""
    from ldaspark.cli import build_parser, plugin_commands
    line = _one_error_line(capsys, [], match="give a command")
    commands = ["integrate", "methods", *plugin_commands()]
    assert "mutants" in commands and "integrate" in line
    named = line.split("(", 1)[1].rstrip(")").split(", ")
    assert sorted(named) == sorted(commands), line
    sub = next(a for a in build_parser()._actions if isinstance(a, __import__("argparse")._SubParsersAction))
    assert sorted(sub.choices) == sorted(commands)
