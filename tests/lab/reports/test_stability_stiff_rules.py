"""Rules of ``ldaspark.lab.reports.stability_stiff`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import math
import types
import numpy as np
import pytest
from ldaspark.core.errors import NewtonError
from ldaspark.lab.reports import stability_stiff as ss
# --- lab/reports/stability_stiff.py -----------------------------------------------------------------
from ldaspark.lab.reports import stability_stiff as SS  # noqa: E402
from stability_fakes import _fake_fast
from run_helpers import two_line_error


# ================================================================================================
# a fake ``ldaspark.compiled.fast`` (the real one compiles numba kernels: minutes on a cold cache)
# ================================================================================================
class _Sol:
    def __init__(self, energy, constraint, stats=None, q=None, v=None):
        self.energy, self.constraint = energy, constraint
        self.stats = stats or {}
        self.q, self.v = q, v


# ================================================================================================
# stability_stiff
# ================================================================================================
def test_classify_thresholds_are_strict():
    row = lambda g, e, o="ok": {"outcome": o, "dE_growth": g, "max_rel_dE": e}  # noqa: E731
    assert ss.classify(row(ss.DE_GROWTH * 1.01, 1e-3)) == "growing"
    assert ss.classify(row(ss.DE_GROWTH, 1e-3)) == "bounded"              # exactly the factor: not growing
    assert ss.classify(row(100.0, 1e-8)) == "bounded"                     # at the round-off bound: not judged
    assert ss.classify(row(100.0, 2e-8)) == "growing"
    assert ss.classify(row(None, 1.0)) == "bounded"
    assert ss.classify(row(100.0, 1.0, "NewtonError")) == "failed"


def test_why_names_the_cause():
    base = {"class": "failed", "rho": 1.0, "dE_before": None}
    assert ss.why(dict(base, **{"class": "bounded", "rho": 5.0})) == ""
    assert ss.why(dict(base, rho=1 + 2e-9)) == "linear instability"
    assert ss.why(dict(base, rho=1 + 0.5e-9, **{"class": "growing"})) == "energy growth"
    assert ss.why(base) == "Newton"
    assert ss.why(dict(base, dE_before=ss.DE_BOUND * 0.99)) == "Newton"
    assert ss.why(dict(base, dE_before=ss.DE_BOUND)) == "energy growth, then Newton"


def test_stiff_run_growth_ratio_and_failure_context(monkeypatch):
    n_calls = []

    def fake(system, method, t0, q0, v0, h, n, every, kernel):
        n_calls.append((method, h, n))
        if n > 100:
            raise two_line_error(NewtonError, "Newton failed at step 7", "second line", step=7)
        E = np.ones(n + 1)
        E[1] = 1.02           # relative to E[0] = 1, not to E[1]
        E[2] = 1.1            # first half (samples 0 .. half - 1): max rel dE 0.1
        E[(n + 1) // 2] = 0.5  # second half starts at sample half: 0.5 -> growth 5
        E[-1] = 0.7
        return _Sol(E, np.array([[1e-16], [-3e-16]]), {"mean_iterations": 2.5, "max_iterations": 4,
                                                      "generic_steps": 1})
    _fake_fast(monkeypatch, fast_integrate=fake)
    r = ss.stiff_run("stiff-particle", "gauss-1", 2.0, n=10, omega=100)
    assert n_calls[-1] == ("gauss-1", 0.02, 10)
    assert r["outcome"] == "ok" and r["max_rel_dE"] == pytest.approx(0.5, rel=1e-12)
    assert r["dE_growth"] == pytest.approx(5.0, rel=1e-12)                   # second / first, not first / second
    assert r["max_k"] == 3e-16 and r["iterations"] == 2.5 and r["max_iterations"] == 4
    assert r["generic_steps"] == 1 and r["full_newton_steps"] == 0
    # a constant energy in the first half: no ratio
    def flat(system, method, t0, q0, v0, h, n, every, kernel):
        E = np.ones(n + 1); E[-1] = 2.0
        return _Sol(E, np.zeros((2, 1)), {"mean_iterations": 1.0, "max_iterations": 1})
    _fake_fast(monkeypatch, fast_integrate=flat)
    assert ss.stiff_run("stiff-particle", "gauss-1", 2.0, n=10)["dE_growth"] is None
    _fake_fast(monkeypatch, fast_integrate=fake)
    bad = ss.stiff_run("stiff-particle", "gauss-1", 2.0, n=1000)
    assert bad["outcome"] == "NewtonError" and bad["step"] == 7 and bad["message"] == "Newton failed at step 7"

    def long_msg(*a, **k):
        raise NewtonError("x" * 170 + "\nsecond line", step=3)
    _fake_fast(monkeypatch, fast_integrate=long_msg)
    assert ss.stiff_run("stiff-particle", "gauss-1", 2.0, n=10)["message"] == "x" * 160    # the first line, cut at 160
    assert ss.tiny_step_run("skate", "gauss-1", 1e-4, 10)["message"] == "x" * 160
    _fake_fast(monkeypatch, fast_integrate=fake)
    # the context reruns the same scene, method and h omega up to the step before the failure
    n_calls.clear()
    assert ss.failure_context(bad) == pytest.approx(0.5, rel=1e-12) and n_calls == [("gauss-1", 0.02, 7)]
    assert ss.failure_context(dict(bad, step=0)) is None and ss.failure_context(r) is None and len(n_calls) == 1


def test_stiff_job_labels_each_row(monkeypatch):
    rows = [{"hw": 1.0, "outcome": "ok", "class": "bounded", "rho": 1.0},
            {"hw": 3.0, "outcome": "NewtonError", "class": "failed", "rho": 1.5, "step": 3}]
    monkeypatch.setattr(ss, "stiff_sweep", lambda scene, method, hws, n: [dict(r) for r in rows])
    monkeypatch.setattr(ss, "failure_context", lambda r: None if r["outcome"] == "ok" else 0.9)
    out = ss.stiff_job("stiff-skate", "gauss-2", (1.0, 3.0), 10)
    assert [(r["dE_before"], r["why"]) for r in out] == [(None, ""), (0.9, "linear instability")]


def test_stiff_sweep_attaches_class_and_linear_prediction(monkeypatch):
    monkeypatch.setattr(ss, "stiff_run", lambda scene, method, hw, n: {"hw": hw, "outcome": "ok", "dE_growth": hw,
                                                                        "max_rel_dE": 1.0})
    out = ss.stiff_sweep("stiff-skate", "lobatto-iiia-iiib-2", hws=(1.0, 2.5, 5.0), n=10)
    assert [r["class"] for r in out] == ["bounded", "bounded", "growing"]
    # Stormer-Verlet: rho = 1 below z = 2, > 1 above; no R (A != A_hat)
    assert out[0]["rho"] == pytest.approx(1.0, abs=1e-12) and out[1]["rho"] > 1.5 and out[0]["R"] is None


def test_tiny_step_run_and_grid(monkeypatch):
    seen = []

    def fake(scene, method, h, n_steps, every):
        seen.append((method, h, n_steps, every))
        if method == "euler-i":
            raise two_line_error(NewtonError, "stopped", "more")
        return _Sol(np.array([2.0, 2.5, 1.0, 2.0]), np.array([[1e-17, -4e-17], [0.0, 0.0]]),
                    {"kernel": "spark", "mean_iterations": 2.0, "full_newton_steps": 3} if h > 1e-6
                    else {"kernel": "spark", "mean_iterations": 2.0})
    _fake_fast(monkeypatch, fast_integrate=fake)
    r = ss.tiny_step_run("skate", "gauss-2", 1e-5, 50)
    assert seen[-1] == ("gauss-2", 1e-5, 50, 1)                 # every = max(1, n // 100)
    assert r["outcome"] == "ok" and r["max_dE"] == 1.0 and r["max_k"] == 4e-17 and r["full_newton_steps"] == 3
    assert r["generic_steps"] == 0 and r["kernel"] == "spark" and r["seconds"] >= 0
    ss.tiny_step_run("skate", "gauss-2", 1e-5, 1000)
    assert seen[-1][3] == 10
    ss.tiny_step_run("skate", "gauss-2", 1e-5, 150)
    assert seen[-1][3] == 1 and type(seen[-1][3]) is int           # n // 100, not n / 100 = 1.5
    r0 = ss.tiny_step_run("skate", "gauss-2", 1e-7, 50)
    assert r0["full_newton_steps"] == 0 and r0["generic_steps"] == 0       # counters absent: none taken
    f = ss.tiny_step_run("skate", "euler-i", 1e-5, 50)
    assert f["outcome"] == "NewtonError" and f["message"] == "stopped" and "max_dE" not in f
    grid = ss.tiny_step_grid(7, methods=("gauss-1", "euler-i"), hs=(1e-4, 1e-6), scenes=("skate", "robot"))
    assert [(g["scene"], g["method"], g["h"], g["N"]) for g in grid] == [
        (s, m, h, 7) for s in ("skate", "robot") for m in ("gauss-1", "euler-i") for h in (1e-4, 1e-6)]


def test_error_floor_steps_and_error_measure(monkeypatch):
    qe, ve = ss._skate_exact(0.1)
    assert qe.shape == (3,) and ve.shape == (3,)
    seen = []

    def fake(scene, method, h, n_steps, every, compensated):
        seen.append((h, n_steps, every, compensated))
        q = np.tile(qe, (3, 1)) + 1.0; v = np.tile(ve, (3, 1)) + 1.0     # only the last row is at T
        q[-1], v[-1] = qe, ve
        q[-1, 0] += 1e-6 if compensated else 3e-6       # position error
        v[-1, 2] -= 2e-6                                 # velocity error: larger than Kahan's q error
        return _Sol(None, None, q=q, v=v)
    _fake_fast(monkeypatch, fast_integrate=fake)
    out = ss.error_floor("gauss-1", hs=(0.01, 0.03), T=0.1)
    assert out["h"] == [0.01, 0.03] and out["N"] == [10, 3]
    assert [s[1:] for s in seen] == [(10, 10, False), (10, 10, True), (3, 3, False), (3, 3, True)]
    assert seen[2][0] == pytest.approx(0.1 / 3, rel=1e-15)         # h = T / N, not the requested h
    assert out["plain"] == [pytest.approx(3e-6, rel=1e-6)] * 2
    assert out["kahan"] == [pytest.approx(2e-6, rel=1e-6)] * 2


@pytest.mark.parametrize("name", ["stiff-skate", "stiff-particle"])
def test_stiff_scenes_are_the_documented_oscillators(name):
    """Section 7's text: stiff-skate U = omega^2 |q|^2 / 2, q0 = (1, 0, 1/2), v0 = (0, 0, omega/2);
    stiff-particle U = omega^2 (q1^2 + q2^2) / 2, q0 = (1, 0, 0), v0 = (0, omega, 0); T = |v|^2 / 2;
    initial data consistent with k."""
    import sympy
    w = 7
    system, t0, q0, v0 = ss.stiff_scene(name, w)
    q, v = system.q, system.v
    U = -system.L.subs({x: 0 for x in v})
    T = system.L.subs({x: 0 for x in q})
    assert sympy.expand(T - sum(x ** 2 for x in v) / 2) == 0
    pot = q[:3] if name == "stiff-skate" else q[:2]
    assert sympy.expand(U - w ** 2 * sum(x ** 2 for x in pot) / 2) == 0
    # the constraints of 8.2 (blade direction q3) and 8.1
    want_k = (sympy.cos(q[2]) * v[1] - sympy.sin(q[2]) * v[0] if name == "stiff-skate" else v[2] - q[1] * v[0])
    assert len(system.k) == 1 and sympy.simplify(system.k[0] - want_k) == 0
    if name == "stiff-skate":
        assert (q0, v0) == ([1.0, 0.0, 0.5], [0.0, 0.0, w / 2])
    else:
        assert (q0, v0) == ([1.0, 0.0, 0.0], [0.0, float(w), 0.0])
    subs = dict(zip(q + v, q0 + v0))
    assert all(abs(float(kk.subs(subs))) < 1e-15 for kk in system.k) and t0 == 0.0
    with pytest.raises(ValueError):
        ss.stiff_scene("stiff-robot", w)


@pytest.mark.parametrize("z", [0.5, 1.9, 3.0])
def test_linear_stability_against_closed_forms(z):
    """Stormer-Verlet (lobatto-iiia-iiib-2) on the oscillator: trace M = 2 - z^2, det M = 1, so
    rho = 1 for z < 2 and rho = |1 - z^2/2| + sqrt((1 - z^2/2)^2 - 1) beyond; implicit midpoint
    (gauss-1): R(i z) = (1 + i z/2) / (1 - i z/2), modulus 1, rho = 1."""
    rho, R = ss.linear_stability("lobatto-iiia-iiib-2", z)
    a = 1 - z * z / 2
    want = 1.0 if abs(a) <= 1 else abs(a) + math.sqrt(a * a - 1)
    assert R is None and rho == pytest.approx(want, rel=1e-7)
    rho, R = ss.linear_stability("gauss-1", z)
    assert rho == pytest.approx(1.0, abs=1e-12) and R == pytest.approx(1.0, abs=1e-12)


def test_stiff_sweep_grids_are_positive_and_strictly_monotone():
    assert all(h > 0 for h in SS.HW) and all(a < b for a, b in zip(SS.HW, SS.HW[1:]))
    assert all(h > 0 for h in SS.FLOOR_H) and all(a > b for a, b in zip(SS.FLOOR_H, SS.FLOOR_H[1:]))


def test_classify_growth_needs_more_than_the_bounds():
    row = {"outcome": "ok", "dE_growth": SS.DE_GROWTH, "max_rel_dE": 1e-3}
    assert SS.classify(row) == "bounded"
    assert SS.classify({**row, "dE_growth": SS.DE_GROWTH * 1.01}) == "growing"
    assert SS.classify({**row, "dE_growth": 10.0, "max_rel_dE": 1e-8}) == "bounded"
    assert SS.classify({**row, "dE_growth": 10.0, "max_rel_dE": 2e-8}) == "growing"


# --- the stiffness study's growth ratio --------------------------------------------------------------
def _stiff_row(monkeypatch, energy):
    from ldaspark.compiled import fast
    from ldaspark.lab.reports import stability_stiff as st
    sol = types.SimpleNamespace(energy=np.asarray(energy, float), constraint=np.zeros(len(energy)),
                                stats={"mean_iterations": 2.0, "max_iterations": 3})
    monkeypatch.setattr(fast, "fast_integrate", lambda *a, **k: sol)
    return st.stiff_run("stiff-particle", "gauss-2", 0.5, n=len(energy) - 1)


def test_the_growth_ratio_is_second_half_over_first_half(monkeypatch):
    from ldaspark.lab.reports.stability_stiff import DE_GROWTH, classify
    # E0 = 2: relative errors 0, 1e-6, 2e-6, 1e-6, | 5e-6, 1e-5, 4e-6, 3e-6  (half = 4)
    rel = [0, 1e-6, 2e-6, 1e-6, 5e-6, 1e-5, 4e-6, 3e-6]
    row = _stiff_row(monkeypatch, [2 * (1 + x) for x in rel])
    assert row["outcome"] == "ok"
    assert row["dE_growth"] == pytest.approx(5.0, rel=1e-9)            # 1e-5 / 2e-6, not 2e-6 / 1e-5
    assert row["max_rel_dE"] == pytest.approx(1e-5, rel=1e-9)
    assert DE_GROWTH < 5.0 and classify(row) == "growing"
    # the same errors in reverse order: decaying, ratio 1/5, bounded
    row = _stiff_row(monkeypatch, [2 * (1 + x) for x in [0, 3e-6, 4e-6, 1e-5, 5e-6, 1e-6, 2e-6, 1e-6]])
    assert row["dE_growth"] == pytest.approx(0.5, rel=1e-9)            # 5e-6 / 1e-5
    assert classify(row) == "bounded"
    # energy errors below the round-off threshold are not judged, whatever their ratio
    row = _stiff_row(monkeypatch, [2 * (1 + x) for x in [0, 1e-12, 1e-12, 1e-12, 1e-10, 1e-10, 1e-10, 1e-10]])
    assert row["dE_growth"] == pytest.approx(100.0, rel=1e-3) and classify(row) == "bounded"


def test_the_growth_classification_thresholds():
    from ldaspark.lab.reports.stability_stiff import DE_GROWTH, classify
    ok = {"outcome": "ok", "max_rel_dE": 1e-3}
    assert classify(dict(ok, dE_growth=DE_GROWTH * 1.01)) == "growing"
    assert classify(dict(ok, dE_growth=DE_GROWTH)) == "bounded"         # strictly above
    assert classify(dict(ok, dE_growth=None)) == "bounded"
    assert classify(dict(ok, dE_growth=10.0, max_rel_dE=1e-9)) == "bounded"
    assert classify({"outcome": "NewtonError"}) == "failed"


def test_growth_below_the_round_off_threshold_is_bounded_at_the_threshold():
    from ldaspark.lab.reports.stability_stiff import classify
    row = {"outcome": "ok", "dE_growth": 10.0}
    assert classify(dict(row, max_rel_dE=1e-8)) == "bounded"           # strictly above 1e-8 is judged
    assert classify(dict(row, max_rel_dE=1.01e-8)) == "growing"
