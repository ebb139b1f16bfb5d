"""The ``systems`` report section (ldaspark/lab/reports/systems.py): its boundedness / drift verdicts on
synthetic series with known behaviour, and one cheap system job rendered into the table."""
import math

import numpy as np
import pytest

from ldaspark.lab.reports import systems
from ldaspark.lab.reports.markdown import table


def test_bounded_and_drift_verdicts_on_known_series():
    """A bounded oscillation is bounded, a linear drift (last/first quarter ~ 4) drifts, round-off
    noise (1e-16 per step, sqrt(N) growth) is at round-off; control: the drift is not bounded."""
    t = np.linspace(0, 100, 1001)
    osc = systems._bounded(t, 1e-6 * np.sin(3 * t), 1000, 1.0)
    assert osc["bounded"] and not osc["drift"] and not osc["roundoff"]
    lin = systems._bounded(t, 1e-6 * t * (1 + 0.1 * np.sin(t)), 1000, 1.0)
    assert lin["drift"] and not lin["bounded"] and 3 < lin["ratio"] < 6
    rng = np.random.default_rng(0)
    noise = systems._bounded(t, 1e-16 * np.cumsum(rng.standard_normal(1001)), 1000, 1.0)
    assert noise["roundoff"] and noise["bounded"]


@pytest.fixture(scope="module")
def job():
    return systems.system_job("contact-oscillator", t_long=200.0)


def test_system_job_row_and_markdown(job):
    """Orders of Gauss-2 / Lobatto IIIA-B 2, 3 within 0.3 of 4, 2, 4; the y-energy of Gauss-2 at
    round-off; Euler I's energy drifts; the row has the header's cell count."""
    for meth, p in systems.ORDER_METHODS:
        o = job["orders"][meth]
        assert abs(o["q"] - p) <= 0.3 and abs(o["v"] - p) <= 0.3, (meth, o)
    assert job["runs"]["gauss-2"]["invariants"]["y-energy"]["roundoff"]
    assert job["runs"]["euler-i"]["invariants"]["energy"]["drift"]
    row = systems._row(job)
    assert len(table(["c"] * 12, [row])) == 3
    md = systems.markdown({"contact-oscillator": job})
    assert "`contact-oscillator`" in md and "Pending" in md and not math.isnan(job["us_per_step_gauss2"])


def test_bicycle_hook_appends_the_section_or_its_failure(job, monkeypatch):
    """The hook for ``ldaspark.lab.reports.systems_bicycle.bicycle_section(outdir) -> (md, json)``: its
    markdown lands under "The Whipple bicycle" and its data under "bicycle"; a failure of that module
    is reported, not raised (control: without the module the section says it is pending)."""
    import sys
    import types
    fake = types.ModuleType(systems.BICYCLE_MODULE)
    fake.bicycle_section = lambda outdir: ("weave speed 4.29 m/s", {"weave": 4.29})
    monkeypatch.setitem(sys.modules, systems.BICYCLE_MODULE, fake)
    bike = systems.bicycle_job("unused")
    md = systems.markdown({"contact-oscillator": job}, bike)
    assert "## The Whipple bicycle\n\nweave speed 4.29 m/s" in md and "Pending" not in md
    assert systems._json({"contact-oscillator": job}, bike)["bicycle"] == {"weave": 4.29}
    fake.bicycle_section = lambda outdir: 1 / 0
    failed = systems.bicycle_job("unused")
    assert "ZeroDivisionError" in systems.markdown({"contact-oscillator": job}, failed)


def test_report_and_json_state_the_interval_that_ran(job):
    """``report systems --t-long 200`` wrote "over [0, 500]" into systems.md and ``"t_long": 500``
    into systems.json about runs over [0, 200] (the defaults, not the runs). Control: a job whose
    runs are the default length (the same job with T = 500 written in) says 500."""
    import copy
    assert job["runs"]["gauss-2"]["T"] == 200.0
    md = systems.markdown({"contact-oscillator": job})
    assert "each invariant over [0, 200]" in md and "[0, 500]" not in md
    assert systems._json({"contact-oscillator": job}, None)["t_long"] == 200.0
    default = copy.deepcopy(job)
    for r in default["runs"].values():
        r["T"] = systems.T_LONG if r is not default["runs"]["euler-i"] else r["T"]
    assert "each invariant over [0, 500]" in systems.markdown({"contact-oscillator": default})
    assert systems._json({"contact-oscillator": default}, None)["t_long"] == 500.0


class _Reached(Exception):
    pass


@pytest.mark.parametrize("given, runs", [("suslov", ("suslov",)),                 # control
                                         ("suslov,suslov", ("suslov",)),          # once, not twice
                                         ("", None), (",", None), (" , ", None)])  # refused
def test_systems_option_empty_subset_is_refused(monkeypatch, capsys, tmp_path, given, runs):
    """``--systems ''`` ran all seven systems (an empty value read as not given) and ``--systems ,``
    ran none and wrote a report without systems, both with exit 0."""
    from ldaspark.cli import main

    def build(outdir, systems_, t_long):
        raise _Reached(systems_)
    monkeypatch.setattr(systems, "build", build)
    argv = ["report", "systems", "--outdir", str(tmp_path), "--systems", given]
    if runs is not None:
        with pytest.raises(_Reached) as got:
            main(argv)
        assert got.value.args == (runs,)
    else:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "names no system" in err, err


def test_a_t_long_beyond_the_step_limit_is_one_line_before_any_system(monkeypatch, capsys, tmp_path):
    """``--t-long 1e9`` (1e10 steps of h = 0.1) set up the first system and printed its progress
    line, then the step limit: two lines on stderr. Control: 1e8 (1e9 steps, the limit) reaches
    the run (a stand-in)."""
    from ldaspark.cli import main

    def build(outdir, systems_, t_long):
        raise _Reached(t_long)
    monkeypatch.setattr(systems, "build", build)
    argv = ["report", "systems", "--outdir", str(tmp_path), "--systems", "suslov", "--t-long"]
    with pytest.raises(_Reached):
        main(argv + ["1e8"])
    assert main(argv + ["1e9"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "more than the limit" in err, err
