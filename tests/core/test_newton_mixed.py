"""Newton at mpmath precision with the Newton matrix in float64 (``newton="mixed"``): the residual
stays at full precision, so the iterates converge to the same solution of (21) as full Newton."""
import mpmath
import numpy as np
import pytest

from ldaspark.core.backend import Backend
from ldaspark.core.families import get_method
from ldaspark.models.scenes import get_scene
from ldaspark.core.spark import SparkMethod, integrate

CASES = [("skate", "gauss-3"), ("robot", "lobatto-iiia-iiib-3"), ("relativistic", "gauss-2"),
         ("friction-skate", "gauss-2"), ("rheonomic-skate", "lobatto-iiia-iiib-iiid-3")]


def _run(scene, method, newton, n_steps=6, dps=40):
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial(dps)
    return integrate(sc.system, get_method(method), t0, q0, v0, mpmath.mpf(1) / 20, n_steps=n_steps,
                     dps=dps, newton=newton)


def _diff(a, b):
    return max(abs(x - y) for x, y in zip(list(a.q[-1]) + list(a.v[-1]), list(b.q[-1]) + list(b.v[-1])))


@pytest.mark.parametrize("scene,method", CASES)
def test_mixed_newton_gives_the_full_newton_solution(scene, method):
    full, mixed = _run(scene, method, "full"), _run(scene, method, "mixed")
    assert _diff(full, mixed) < mpmath.mpf(10) ** -36
    assert mixed.stats["nlu"] >= mixed.stats["steps"]


def test_mixed_newton_never_factorises_at_full_precision(monkeypatch):
    """The cheap path is really taken: the arb / mpmath factorisation is never called."""
    orig = Backend.factor

    def refuse(self, J):
        if self.is_mp:
            raise AssertionError("full-precision factorisation called")
        return orig(self, J)
    monkeypatch.setattr(Backend, "factor", refuse)
    sol = _run("skate", "gauss-2", "mixed")
    assert sol.stats["steps"] == 6


def test_mixed_newton_with_a_poor_matrix_falls_back_to_full_precision(monkeypatch):
    """Negative control: a float64 matrix that is 30% off contracts too slowly; the step then
    switches to the full-precision matrix (mp factorisations happen) and still reaches the same
    solution. Without the fallback the run would need many more iterations."""
    orig = SparkMethod._float64_jacobian
    calls = {"mp": 0}
    monkeypatch.setattr(SparkMethod, "_float64_jacobian", lambda self, *a: orig(self, *a) * 1.3)
    orig_factor = Backend.factor

    def counting(self, J):
        calls["mp"] += self.is_mp
        return orig_factor(self, J)
    monkeypatch.setattr(Backend, "factor", counting)
    bad = _run("robot", "gauss-2", "mixed")
    assert calls["mp"] > 0
    assert _diff(bad, _run("robot", "gauss-2", "full")) < mpmath.mpf(10) ** -36


def test_mixed_is_full_newton_at_float64():
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial()
    a = integrate(sc.system, get_method("gauss-2"), t0, q0, v0, 0.05, n_steps=20, newton="mixed")
    b = integrate(sc.system, get_method("gauss-2"), t0, q0, v0, 0.05, n_steps=20, newton="full")
    assert np.array_equal(np.asarray(a.q, float), np.asarray(b.q, float))


def test_mixed_newton_at_a_thousand_digits_finishes_with_the_full_precision_matrix(monkeypatch):
    """The float64 matrix gains ~16 digits an increment: at 1000 digits a step needed more than
    max_iter = 50 increments and failed on the skate's easy first step. When the contraction leaves
    more increments than the budget, the rest of the step runs with the full-precision matrix
    (``_budget_short``): the step converges, to full Newton's solution. Control: at 40 digits the
    budget is never short (no full-precision factorisation)."""
    r = _run("skate", "gauss-2", "mixed", n_steps=2, dps=1000)
    f = _run("skate", "gauss-2", "full", n_steps=2, dps=1000)
    with mpmath.workdps(1000):
        assert max(abs(a - b) for a, b in zip(r.q[-1], f.q[-1])) < mpmath.mpf(10) ** -990
    assert r.stats["newton_iterations"] < 2 * 50
    full_precision = []
    orig = Backend.factor
    monkeypatch.setattr(Backend, "factor", lambda self, J: (self.is_mp and full_precision.append(1)) or orig(self, J))
    _run("skate", "gauss-2", "mixed", n_steps=2, dps=40)
    assert not full_precision
    _run("skate", "gauss-2", "mixed", n_steps=1, dps=1000)
    assert full_precision
