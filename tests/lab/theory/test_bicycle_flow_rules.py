"""Rules of ``ldaspark.lab.theory.bicycle_flow`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import math
import pytest


# ================================================================================================
# bicycle_flow and bicycle_benchmark
# ================================================================================================
def test_weave_and_capsize_picks():
    from ldaspark.lab.theory import bicycle_flow as bf
    eigs = [complex(-14, 0), complex(-0.8, 4.5), complex(-0.8, -4.5), complex(-0.3, 0)]
    assert bf.weave_real_part(eigs) == -0.8
    assert bf.capsize_eigenvalue(eigs) == -0.3                 # the largest real one, not the most negative
    assert math.isnan(bf.weave_real_part([1.0 + 0j, -2.0 + 0j]))
    # a pair with an imaginary part 5e-10 counts as real (tolerance 1e-9), 2e-9 as complex
    assert math.isnan(bf.weave_real_part([complex(3, 5e-10)]))
    assert bf.weave_real_part([complex(3, 2e-9), complex(-1, 1)]) == 3
    assert bf.capsize_eigenvalue([complex(3, 5e-10), complex(7, 2e-9)]) == 3
    # exactly 1e-9 is still "real" for both rules
    assert bf.capsize_eigenvalue([complex(3, 1e-9), complex(-1, 0)]) == 3
    assert math.isnan(bf.weave_real_part([complex(3, 1e-9), complex(-1, 0)]))
    assert bf.match_error([1, 2j, -1, 5], [5, -1, 2j, 1.5]) == pytest.approx(0.5)


def test_critical_speeds_secant_on_synthetic_modes(monkeypatch):
    from ldaspark.lab.theory import bicycle_flow as bf
    vw, vc = 4.29238253634111, 6.02426201538837
    calls = []

    def fake(v, method, h, model=None):
        calls.append((method, h, model))
        w = 0.7 * (vw - v) + 0.05 * (vw - v) ** 2             # weave real part: positive below vw
        c = 0.4 * (v - vc)                                      # capsize: positive above vc
        return [complex(-14, 0), complex(w, 4.0), complex(w, -4.0), complex(c, 0)]
    monkeypatch.setattr(bf, "spark_eigenvalues", fake)
    model = object()
    a, b = bf.critical_speeds("gauss-2", 0.02, model=model, xtol=1e-12)
    assert a == pytest.approx(vw, abs=1e-10) and b == pytest.approx(vc, abs=1e-10)
    assert set(calls) == {("gauss-2", 0.02, model)}
    # the stopping test: a loose xtol stops after fewer evaluations than a tight one
    n_tight = len(calls)
    calls.clear()
    # the default tolerance 1e-9 stops the secant on a smooth root well before its 30 steps
    spy = []
    monkeypatch.setattr(bf, "spark_eigenvalues", lambda v, *a, **k: spy.append(v) or fake(v, *a, **k))
    a, b = bf.critical_speeds("gauss-2", 0.02, model=model)
    assert a == pytest.approx(vw, abs=1e-8) and b == pytest.approx(vc, abs=1e-8) and len(spy) < 2 * 32
    for seq in ([v for v in spy if v < 5], [v for v in spy if v > 5]):
        # it stops at the first secant step <= 1e-9: the step before was larger
        assert abs(seq[-1] - seq[-2]) <= 1e-9 < abs(seq[-2] - seq[-3])
    monkeypatch.setattr(bf, "spark_eigenvalues", fake)
    calls.clear()
    bf.critical_speeds("gauss-2", 0.02, model=model, xtol=1e-2)
    assert len(calls) < n_tight


def test_critical_speeds_stops_after_thirty_secant_steps(monkeypatch):
    """A triple root: the secant iteration converges only linearly; with xtol < 0 it never stops
    early and takes its 30 steps (2 starting values + 30 evaluations per speed)."""
    from ldaspark.lab.theory import bicycle_flow as bf
    calls = []

    def fake(v, method, h, model=None):
        calls.append(v)
        w, c = (4.3 - v) ** 3, (v - 6.02) ** 3
        return [complex(w, 1.0), complex(w, -1.0), complex(c, 0.0), complex(-9.0, 0.0)]
    monkeypatch.setattr(bf, "spark_eigenvalues", fake)
    a, b = bf.critical_speeds(model=object(), xtol=-1.0)
    assert len(calls) == 2 * 32
    assert abs(a - 4.3) < 1e-2 and abs(b - 6.02) < 1e-2


def test_secant_brackets_and_inclusive_tolerance(monkeypatch):
    """The documented brackets 4 - 4.5 and 6 - 6.1; a linear weave function is solved by the first
    secant step (c = 4.25 exactly), whose length 0.25 then meets xtol = 0.25 (<=): 3 evaluations."""
    from ldaspark.lab.theory import bicycle_flow as bf
    calls = []

    def fake(v, method, h, model=None):
        calls.append(v)
        w, c = 4.25 - v, v - 6.0625
        return [complex(w, 1.0), complex(w, -1.0), complex(c, 0.0)]
    monkeypatch.setattr(bf, "spark_eigenvalues", fake)
    a, b = bf.critical_speeds(model=object(), xtol=0.25)
    weave = [v for v in calls if v < 5]
    assert weave == [4.0, 4.5, 4.25] and a == 4.25
    assert [v for v in calls if v > 5][:2] == [6.0, 6.1]
