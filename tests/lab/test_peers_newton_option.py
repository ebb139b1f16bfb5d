"""benchmarks/peers.py --newton quasi: the strongest-peers study's public SPARK runs
(``lab.reports.peers.prepare_spark``, which imports ``ldaspark.solve.integrate`` when it prepares
a run) use the quasi-Newton root finder; without the option they use the default one."""
import os
import sys

from ldaspark import solve
from ldaspark.lab.reports import peers as P
from ldaspark.models.scenes import get_scene

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks"))
import peers as bench  # noqa: E402


def _kind():
    go, _ = P.prepare_spark(get_scene("skate"), "gauss-2", 0.5, 5.0, 1, public=True)
    r = go()
    return r.stats["root_finder"]["kind"], r.stats.get("quasi_steps")


def test_newton_option_reaches_the_public_runs(monkeypatch):
    monkeypatch.setattr(solve, "integrate", solve.integrate)     # restored after the test
    # control: the default root finder by name ("auto", which runs the quasi iteration on the skate)
    assert _kind() == ("auto", 10)
    bench._use_newton("quasi")
    assert _kind() == ("quasi", 10)


def test_newton_option_refuses_other_kinds(capsys):
    import pytest
    with pytest.raises(SystemExit):
        bench.main(["--newton", "full", "--quick"])
    assert "invalid choice" in capsys.readouterr().err
