"""The `ldaspark integrate` and `ldaspark methods` contracts."""
import json

import mpmath
import pytest

from ldaspark.cli import main


def test_integrate_json_contract(tmp_path):
    out = tmp_path / "o.json"
    assert main(["integrate", "skate", "gauss-2", "--h", "0.1", "--t-end", "1", "--out", str(out)]) == 0
    d = json.loads(out.read_text())
    for key in ("t", "q", "v", "energy", "constraint", "scene", "method", "h", "dps"):
        assert key in d
    assert len(d["t"]) == 11 and len(d["q"]) == 11 and len(d["q"][0]) == 3
    assert len(d["constraint"]) == 11 and len(d["constraint"][0]) == 1
    assert d["dps"] is None and isinstance(d["t"][1], float)
    assert max(abs(r[0]) for r in d["constraint"]) < 1e-14


def test_integrate_dps_t_end_keeps_its_digits(tmp_path, capsys):
    """With --dps, --h kept its digits but --t-end was read as a float: --t-end 2e-420 at 400
    digits became 0.0 ('t_end = 0.0 is not reached', exit 2) while --h 1e-420 was fine. Now the
    run takes its 2 steps and ends at 2e-420; a t_end off the grid is still one line, exit 2."""
    out = tmp_path / "o.json"
    assert main(["integrate", "particle", "gauss-1", "--h", "1e-420", "--t-end", "2e-420", "--dps", "400",
                 "--engine", "generic", "--out", str(out)]) == 0
    d = json.loads(out.read_text())
    with mpmath.workdps(400):
        assert len(d["t"]) == 3 and abs(mpmath.mpf(d["t"][-1]) - mpmath.mpf("2e-420")) <= mpmath.mpf("1e-819")
    assert main(["integrate", "particle", "gauss-1", "--h", "0.10000000001", "--t-end", "1", "--dps", "30",
                 "--out", str(out)]) == 2
    assert "integer multiple" in capsys.readouterr().err


def test_integrate_dps_strings_carry_precision(tmp_path):
    out = tmp_path / "o.json"
    assert main(["integrate", "skate", "gauss-2", "--h", "0.1", "--t-end", "0.3", "--dps", "40", "--out", str(out)]) == 0
    d = json.loads(out.read_text())
    assert isinstance(d["q"][-1][0], str) and len(d["q"][-1][0].lstrip("-0.")) >= 35
    with mpmath.workdps(40):
        assert abs(mpmath.mpf(d["constraint"][-1][0])) < mpmath.mpf(10) ** -38


def test_integrate_mp_particles_ic_and_custom(tmp_path):
    out = tmp_path / "o.json"
    assert main(["integrate", "mp-particles", "lobatto-iiia-iiib-2", "--h", "0.05", "--t-end", "0.2",
                 "--ic", "3", "--out", str(out)]) == 0
    tab = tmp_path / "t.json"
    tab.write_text(json.dumps({"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]],
                               "b": [1], "b_hat": [1], "b_tilde": [1]}))
    assert main(["integrate", "particle", "custom", "--tableau", str(tab), "--h", "0.1", "--t-end", "0.5",
                 "--out", str(out)]) == 0


@pytest.mark.parametrize("argv", [
    ["integrate", "nope", "gauss-2", "--h", "0.1", "--t-end", "1", "--out", "x.json"],
    ["integrate", "skate", "gauss-0", "--h", "0.1", "--t-end", "1", "--out", "x.json"],
    ["integrate", "skate", "custom", "--h", "0.1", "--t-end", "1", "--out", "x.json"],
    ["integrate", "skate", "gauss-2", "--h", "abc", "--t-end", "1", "--out", "x.json"],
    ["integrate", "skate", "gauss-2", "--h", "0", "--t-end", "1", "--out", "x.json"],
    ["integrate", "skate", "gauss-2", "--h", "0.1", "--t-end", "1"],
])
def test_integrate_user_errors_exit_2_one_line(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) if "--out" not in argv else _noraise():
        rc = main(argv)
        assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0]
    assert not (tmp_path / "x.json").exists()


class _noraise:
    def __enter__(self):
        return self

    def __exit__(self, *a):
        return False


def test_methods_lists_22_23(capsys):
    assert main(["methods", "--max-s", "2"]) == 0
    out = capsys.readouterr().out
    assert "gauss-2" in out and "euler-i" in out
    line = [l for l in out.splitlines() if l.startswith("euler-i ")][0]
    assert line.split()[-2:] == ["yes", "no"]


@pytest.mark.parametrize("target", ["dir", "link-to-dir", "socket"])
def test_integrate_refuses_an_unwritable_out_before_the_run(target, capsys, tmp_path, monkeypatch):
    """--out naming a directory (or a link to one, a socket) is refused before any step: it used to
    run the whole integration (20 s for --h 1e-5 --t-end 20) and refuse the path at the end."""
    import os
    import socket
    import ldaspark.solve
    ran = []
    monkeypatch.setattr(ldaspark.solve, "integrate", lambda *a, **k: ran.append(1))
    out = tmp_path / "o"
    if target == "dir":
        out.mkdir()
    elif target == "link-to-dir":
        (tmp_path / "d").mkdir()
        os.symlink(tmp_path / "d", out)
    else:
        monkeypatch.chdir(tmp_path)        # AF_UNIX paths are short: a relative one
        sock = socket.socket(socket.AF_UNIX)
        sock.bind("o")
        monkeypatch.undo()
    rc = main(["integrate", "particle", "gauss-1", "--h", "0.1", "--t-end", "1", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "refusing to replace it" in err[0], err
    assert ran == []


def test_integrate_help_says_what_the_compiled_engine_does(tmp_path):
    """--newton is the root finder of every engine (the compiled kernels run "full" when asked)
    and the compiled engine writes psi; the help said "generic engine's Newton variant" and
    "(psi needs the generic engine)"."""
    from ldaspark.cli import build_parser
    sub = next(a for a in build_parser("integrate")._actions if a.dest == "command").choices["integrate"]
    helps = {a.dest: a.help for a in sub._actions}
    out = tmp_path / "c.json"
    assert main(["integrate", "pendulum", "gauss-2", "--h", "0.1", "--t-end", "0.3", "--engine", "compiled",
                 "--newton", "full", "--out", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["engine"] == "compiled" and len(d["psi"]) == 3 and d["stats"]["root_finder"]["runs"] == "full"
    assert "generic engine" not in helps["newton"] and "psi needs" not in helps["out"], helps


def test_integrate_offers_every_root_finder_kind(tmp_path, capsys):
    """--newton offered full, simplified, auto, mixed but not quasi (ldaspark.Newton's fifth kind, the
    compiled engine's root finder of issue 48): 'invalid choice', exit 2. The choices are the kinds
    of core.rootfinder.KINDS; quasi runs and says so in the file's stats, and on the generic engine
    it is refused in one line (as the API refuses it)."""
    import argparse
    from ldaspark.cli import build_parser
    from ldaspark.core.rootfinder import KINDS
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    newton = next(a for a in sub.choices["integrate"]._actions if a.dest == "newton")
    assert sorted(newton.choices) == sorted(KINDS)
    out = tmp_path / "o.json"
    assert main(["integrate", "skate", "gauss-2", "--h", "0.1", "--t-end", "0.3", "--newton", "quasi",
                 "--engine", "compiled", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["stats"]["root_finder"]["kind"] == "quasi"
    assert main(["integrate", "skate", "gauss-2", "--h", "0.1", "--t-end", "0.3", "--newton", "quasi",
                 "--engine", "generic", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "quasi" in err and err.count("\n") == 1
