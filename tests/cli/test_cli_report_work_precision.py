"""``ldaspark report work-precision --t-long``: honoured with --quick, refused before the study
when its long run cannot take it (found by probe t17)."""
import pytest

from ldaspark.cli import main
from ldaspark.lab.reports import work_precision as wp


class _Reached(Exception):
    pass


def _long_horizons(**kw):
    return {args[1] for key, fn, args, _ in wp.jobs(**kw) if fn == "long_part"}


def test_quick_keeps_a_given_t_long():
    """``--quick --t-long 100`` ran the long runs to 250 (the quick size replaced the option in
    silence). Controls: the defaults stay 2500 and, with --quick, 250."""
    assert _long_horizons() == {2500.0} and _long_horizons(quick=True) == {250.0}
    assert _long_horizons(quick=True, t_long=100.0) == {100.0}
    assert _long_horizons(t_long=100.0) == {100.0}


@pytest.mark.parametrize("t_long, ok", [("5", True), ("12", True), ("2500", True),
                                         ("3", False), ("4.99", False), ("7.25", False), ("1e12", False)])
def test_a_t_long_the_long_run_cannot_take_is_refused_before_the_study(monkeypatch, capsys, tmp_path, t_long, ok):
    """``--t-long 3`` ran the whole study, then its long run raised numpy's "zero-size array to
    reduction operation maximum" (no DOP853 sample, one every 5, in the second half): a traceback
    after minutes; 7.25 is no whole number of steps h = 0.1 (rounded to 7.2, the run ended
    elsewhere than it said); 1e12 is 1e13 steps, refused by the SPARK run only after the whole
    study. 5, 12 and 2500 (controls) reach the study."""
    def run_study(*a, **k):
        raise _Reached
    monkeypatch.setattr(wp, "run_study", run_study)
    argv = ["report", "work-precision", "--outdir", str(tmp_path), "--t-long", t_long]
    if ok:
        with pytest.raises(_Reached):
            main(argv)
        return
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and ("--t-long must be at least 5" in err or "more than the limit" in err), err


def test_the_long_run_itself_fails_on_such_a_t_long():
    """Why the check is needed (teeth of the test above): the DOP853 long run at t_long = 3 has no
    sample in its second half."""
    with pytest.raises(ValueError, match="zero-size"):
        wp.long_part("dop853", 3.0)
