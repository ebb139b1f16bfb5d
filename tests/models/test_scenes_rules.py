"""Rules of ``ldaspark.models.scenes`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import math
import types
import numpy as np
from ldaspark.lab.theory import audit_checks as ac
from ldaspark.lab.theory import variational as var
import pytest
import ldaspark
import ldaspark.models.scenes as scenes_mod
from verification import systems_checks as SC
# --- core/validate.py ---------------------------------------------------------------------------
from ldaspark.core import validate as V  # noqa: E402
from types import SimpleNamespace


# ==== audit_checks: numerical checks ==========================================================
class _Sol:
    def __init__(self, q, v, k=(0.0,), energy=None):
        self.q, self.v = [np.array([0.0]), np.array(q, dtype=float)], [np.array([0.0]), np.array(v, dtype=float)]
        self.constraint = np.array(k, dtype=float)
        self.energy = energy


def test_initial_point_base_and_perturbed():
    from ldaspark.models.scenes import get_scene
    from ldaspark.analysis.discrete import perturbed_initial
    sc = get_scene("skate")
    t0, q0, v0 = var.initial_point("skate", "base", 30)
    assert (t0, list(q0), list(v0)) == (sc.initial(30)[0], list(sc.initial(30)[1]), list(sc.initial(30)[2]))
    t0p, q0p, v0p = var.initial_point("skate", "perturbed", 30)
    assert list(q0p) == list(perturbed_initial(sc, 30)[1]) and list(q0p) != list(q0)


def test_observed_order_zero_error_on_either_side_is_no_slope(monkeypatch):
    from ldaspark.models import scenes
    sc = types.SimpleNamespace(exact=object(), system="S", exact_solution=lambda t, dps: ([1.0], [2.0], None))
    monkeypatch.setattr(scenes, "get_scene", lambda name: sc)
    for e4, e8 in ((0.0, 1e-3), (1e-3, 0.0)):
        errs = {4: e4, 8: e8}
        monkeypatch.setattr(ac, "_run", lambda tab, scene, N, t, dps: _Sol([1.0 + errs[N]], [2.0]))
        r = ac.observed_order(None, "x", [4, 8], 1, None, 0.0)
        assert math.isnan(r["slopes"][0]) and math.isnan(r["observed"])


EPS = 2.0 ** -52


def _fake_runs(monkeypatch, kmax=1.0, engine="compiled", success=True, dq=0.0, drift=11.0):
    """The compiled run: q = (t - 2, -2 t), v = (1, 1/2) on [0, 200] (bound 100 eps 401 * 2);
    constraint = kmax * bound; the generic run's q(2) off by dq; RK4 drift = drift * bound."""
    bound = 100 * EPS * 401 * 2
    log = []

    def fake_integrate(name, method, t_span, h, engine=None, **kw):
        log.append((name, method, tuple(t_span), h, engine))
        N = int(round((t_span[1] - t_span[0]) / h))
        t = t_span[0] + h * np.arange(N + 1)
        q = np.stack([t - 2.0, -2 * t], axis=1)
        if engine == "generic":
            q[-1, 0] += dq
            return type("Res", (), dict(q=q, engine="generic", success=True))()
        v = np.tile([1.0, 0.5], (N + 1, 1))
        k = np.zeros(N + 1)
        k[N // 2] = -kmax * bound
        return type("Res", (), dict(q=q, v=v, t=t, constraint=k, engine=engine_out, success=success))()
    engine_out = engine
    monkeypatch.setattr(ldaspark, "integrate", fake_integrate)
    monkeypatch.setattr(scenes_mod, "get_scene", lambda name: ("scene", name))
    monkeypatch.setattr(SC, "rk4_constraint_drift", lambda sc, h, n: log.append(("rk4", sc, h, n)) or drift * bound)
    return log


@pytest.mark.parametrize("kw, ok", [
    ({}, True), (dict(kmax=1.0, dq=0.99e-12, drift=10 * (1 + 1e-9)), True),
    (dict(kmax=1 + 1e-12), False), (dict(engine="generic"), False), (dict(success=False), False),
    (dict(dq=1e-12), False), (dict(dq=-2e-12), False), (dict(drift=10.0), False), (dict(drift=5.0), False)])
def test_check_constraint_roundoff_and_engines_verdict(monkeypatch, kw, ok):
    log = _fake_runs(monkeypatch, **kw)
    if ok:
        SC.check_constraint_roundoff_and_engines("scn")
        assert log == [("scn", "gauss-2", (0, 200), 0.1, None), ("scn", "gauss-2", (0, 2), 0.1, "generic"),
                       ("rk4", ("scene", "scn"), 0.1, 20)], log
    else:
        with pytest.raises(AssertionError):
            SC.check_constraint_roundoff_and_engines("scn")


def test_point_takes_only_the_missing_v0_from_the_scene():
    from ldaspark.models.scenes import get_scene
    sc = get_scene("pendulum")
    ts, qs, vs = sc.initial(None)
    t0, q0, v0 = V.point(sc.system, 0.0, [0.6, -0.8], None, scene=sc)
    assert (t0, q0) == (0.0, [0.6, -0.8])
    assert list(v0) == list(vs)


def _close(x, rel=1e-9):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny numbers."""
    return pytest.approx(x, rel=rel, abs=0.0)


def test_observed_order_reports_the_largest_constraint_violation(monkeypatch):
    import ldaspark.models.scenes as scenes
    fake_scene = SimpleNamespace(exact=True, exact_solution=lambda t, dps: ([0.0, 0.0], [0.0, 0.0], None))
    monkeypatch.setattr(scenes, "get_scene", lambda name: fake_scene)

    def run(tab, sc, N, t_end, dps):
        return SimpleNamespace(q=[np.array([1.0 / N ** 2, 0.0])], v=[np.array([0.0, 0.0])],
                               constraint=np.array([[1e-3 / N, 1e-12], [1e-9, 0.0]]))
    monkeypatch.setattr(ac, "_run", run)
    res = ac.observed_order(None, "skate", [4, 8, 16], 1, None, 1e-14)
    assert res["max_constraint"] == _close(1e-3 / 4, rel=1e-12)
    assert res["observed"] == _close(2.0, rel=1e-9)


# --- flow_jacobian: the default start time, and no non-finite entry returned ---------------------
def test_flow_jacobian_of_a_bare_system_starts_at_t0_zero_by_default():
    from ldaspark.models.scenes import get_scene
    from ldaspark.analysis.flow_jacobian import flow_jacobian
    sc = get_scene("skate")
    _, q0, v0 = sc.initial(None)
    a = flow_jacobian(sc.system, "gauss-1", q0, v0, 0.1)            # a bare system, no t0: t0 = 0
    b = flow_jacobian(sc.system, "gauss-1", q0, v0, 0.1, t0=0)
    assert a.full.shape == (2 * sc.system.n, 2 * sc.system.n)
    assert np.array_equal(np.asarray(a.full, dtype=float), np.asarray(b.full, dtype=float))


# ==== scene builders: their arguments ==========================================================
@pytest.mark.parametrize("kw", [dict(m="3"), dict(m=None), dict(m=2.5), dict(m=10 ** 9), dict(J="9"),
                                dict(j="1"), dict(j=1.5), dict(J=9, j=10)])
def test_mp_particles_takes_integer_sizes_and_indices(kw):
    """m, J and j of ``mp_particles`` are integers (m in 2..500, n = 2m + 1 <= 1001; 0 <= j <= J):
    m = "3", None or 2.5 raised a TypeError from a comparison or an index, j = 1.5 built the
    initial condition cos(1.5 pi / 18) as if it were one of the J + 1, and m = 10**9 started
    building a billion symbols (m = 400 ran for more than 20 s). Control: m = 2, J = 0, j = 0."""
    from ldaspark.core.errors import InputError
    with pytest.raises(InputError):
        scenes_mod.mp_particles(**kw)
    assert scenes_mod.mp_particles(m=2, J=0, j=0).system.n == 5


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), 1j, complex(1, 0), np.float64("nan"), True])
def test_scene_parameters_are_finite_real_numbers(bad):
    """A scene parameter given as a number is a finite real one, as the system's own parameters
    are (``_checked_param``): skate(m=nan) and skate(m=1j) built a skate of mass nan or 1j
    without a word. Control: 1/2 as a string and as a float."""
    from ldaspark.core.errors import LdasparkError
    with pytest.raises(LdasparkError, match="parameter"):
        scenes_mod.skate(m=bad)
    with pytest.raises(LdasparkError, match="parameter"):
        scenes_mod.relativistic(B=bad)
    # the classic scenes' parameters too: chaplygin_sleigh(m=nan) raised TypeError "Invalid NaN
    # comparison" from sympy, contact_oscillator(epsilon=1j) was built
    from ldaspark.models import systems_classic
    with pytest.raises(LdasparkError, match="parameter"):
        systems_classic.chaplygin_sleigh(m=bad)
    with pytest.raises(LdasparkError, match="parameter"):
        systems_classic.contact_oscillator(epsilon=bad)
    assert float(scenes_mod.skate(m="1/2").params["m"]) == float(scenes_mod.skate(m=0.5).params["m"]) == 0.5
