"""``ldaspark report energy --t-end``: the interval asked for is the one run and recorded, or one
line that says which values the figure takes (found by probe t17)."""
import json

import pytest

from ldaspark.cli import main
from run_helpers import main_rc_err


class _Reached(BaseException):
    """Fig. 4 started (a stand-in; BaseException: ``fig4_job`` reports an Exception in energy.md)."""


@pytest.fixture
def fig4_stand_in(monkeypatch):
    from ldaspark.lab.reports import energy

    def figure4(t_end=50000.0, **kw):
        raise _Reached(t_end)
    monkeypatch.setattr(energy, "figure4", figure4)
    monkeypatch.setattr(energy, "fig4_available", lambda: True)


def _rc_err(capsys, argv):
    return main_rc_err(capsys, argv)


@pytest.mark.parametrize("extra", [["--figure", "4", "--t-end", "12"],     # 240 steps, not whole samples
                                   ["--figure", "4", "--t-end", "10"],     # 2 samples, the fit takes 3
                                   ["--t-end", "1"]])                      # the default run has Fig. 4 too
def test_a_t_end_fig4_cannot_take_is_one_line_in_the_options_words(capsys, tmp_path, fig4_stand_in, extra):
    """Before: "n_steps = 240 must be a multiple of every = 100" and "growth fit window [0.1, 10.0]
    holds fewer than 3 samples", names no option sets; and ``--t-end 1`` without --figure ran the
    paper's Fig. 4 in full. Control: 15 (3 samples of 5) reaches Fig. 4 with that t_end."""
    with pytest.raises(_Reached) as got:
        main(["report", "energy", "--figure", "4", "--t-end", "15", "--json", str(tmp_path / "ok.json")])
    assert got.value.args == (15.0,)
    rc, err = _rc_err(capsys, ["report", "energy", *extra, "--outdir", str(tmp_path / "r")])
    assert rc == 2 and err.count("\n") == 1, err
    assert "--t-end of Fig. 4 must be a multiple of 5" in err and "at least 15" in err, err


def test_the_default_run_shortens_fig4_too(capsys, tmp_path, fig4_stand_in):
    """``report energy --t-end 15`` ran Figs. 1-3 to t = 15 and Fig. 4 to the paper's t = 50000
    (3 methods x 10 runs x 1e6 steps per constraint). Control: the paper's length without --t-end."""
    from ldaspark.lab.reports import energy
    with pytest.raises(_Reached) as got:
        energy.run_default(str(tmp_path / "a"), t_end=None)
    assert got.value.args == (50000.0,)
    with pytest.raises(_Reached) as got:
        main(["report", "energy", "--t-end", "15", "--outdir", str(tmp_path / "b")])
    assert got.value.args == (15.0,)


def test_figs_1_to_3_run_to_the_t_end_they_record(capsys, tmp_path):
    """``--figure 1 --t-end 1.1`` (h = 0.2) rounded to 6 steps: the data ended at t = 1.2 and the
    JSON said t_end 1.1. Control: 0.6 = 3 steps (0.6000000000000001 in float64 arithmetic) runs,
    and its last time is its t_end to rounding (5 ulps of 1: the sum of 3 steps of 0.2)."""
    ok = tmp_path / "ok.json"
    rc, err = _rc_err(capsys, ["report", "energy", "--figure", "1", "--t-end", "0.6", "--json", str(ok)])
    assert rc == 0, err
    d = json.loads(ok.read_text())
    assert all(abs(r["t"][-1] - d["t_end"]) < 5 * 2.2e-16 for r in d["methods"].values())
    rc, err = _rc_err(capsys, ["report", "energy", "--figure", "1", "--t-end", "1.1", "--json",
                               str(tmp_path / "bad.json")])
    assert rc == 2 and err.count("\n") == 1 and "not a multiple of Fig. 1's step h = 0.2" in err, err
    assert not (tmp_path / "bad.json").exists()


@pytest.mark.parametrize("extra", [["--figure", "1", "--t-end", "1"], ["--t-end", "15"]])
def test_mp_constraint_without_figure_4_is_refused_not_ignored(capsys, tmp_path, fig4_stand_in, monkeypatch, extra):
    """``--mp-constraint nonholonomic`` chooses Fig. 4's scene: with --figure 1 it was accepted and
    ignored, and without --figure Fig. 4 ran both constraints whatever it said. Control: with
    --figure 4 it reaches Fig. 4 (and --figure 4 alone keeps the printed constraint)."""
    from ldaspark.lab.reports import energy
    seen = []

    def figure4(t_end=50000.0, constraint="printed", **kw):
        seen.append(constraint)
        raise _Reached(t_end)
    monkeypatch.setattr(energy, "figure4", figure4)
    for c in (["--mp-constraint", "nonholonomic"], []):
        with pytest.raises(_Reached):
            main(["report", "energy", "--figure", "4", "--t-end", "15", *c, "--json", str(tmp_path / "f.json")])
    assert seen == ["nonholonomic", "printed"]
    rc, err = _rc_err(capsys, ["report", "energy", *extra, "--mp-constraint", "nonholonomic",
                               "--outdir", str(tmp_path / "r")])
    assert rc == 2 and err.count("\n") == 1 and "--mp-constraint chooses the scene of Fig. 4" in err, err
