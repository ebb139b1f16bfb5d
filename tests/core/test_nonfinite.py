"""No NaN, infinity or complex number comes out of the generic engine: a step whose values or
whose energy (8) are not finite real numbers stops the run with NonFiniteError naming the step
and its time (float64 and mpmath alike). A passage through a singularity of L that leaves finite
values (1/q1) is seen only by the opt-in energy_jump monitor; without it the run completes and the
jump is visible in the energy, as documented in docs/reliability.md."""
import numpy as np
import pytest
import sympy

from ldaspark.core.errors import LdasparkError, NonFiniteError
from ldaspark.core.families import get_method
from ldaspark.models.scenes import get_scene
from ldaspark.core.spark import SparkMethod, integrate
from ldaspark.core.system import LagrangianSystem


def _system(potential):
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    return LagrangianSystem(sum(x ** 2 for x in v) / 2 - potential(q), [v[2] - q[1] * v[0]], q, v)


@pytest.fixture(scope="module")
def log_system():
    return _system(lambda q: -sympy.log(1 - q[0]))       # U = -log(1 - q1): defined for q1 < 1


@pytest.mark.parametrize("dps", [None, 30])
def test_leaving_the_domain_of_L_stops_with_step_and_time(log_system, dps):
    # before: float64 raised a raw ValueError from the energy, dps=30 returned mpc energies
    h = 0.1 if dps is None else "0.1"
    with pytest.raises(NonFiniteError, match=r"step 3 \(t = 0.3 -> 0.4\).*not a finite real number") as ei:
        integrate(log_system, get_method("gauss-2"), 0, [0, 0, 0], [3, 0, 0], h, n_steps=20, dps=dps)
    assert ei.value.step == 3 and ei.value.time == pytest.approx(0.3)
    assert isinstance(ei.value, LdasparkError)


def test_inside_the_domain_the_same_system_runs(log_system):
    # control: the check does not fire while q1 < 1
    sol = integrate(log_system, get_method("gauss-2"), 0, [0, 0, 0], [0.5, 0, 0], 0.1, n_steps=20)
    assert np.all(np.isfinite(sol.energy)) and np.max(sol.q[:, 0]) < 1


def test_nan_from_a_step_is_a_named_error(monkeypatch):
    # any NaN in the step's values (e.g. a kernel returning NaN) is caught by the per-step check
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    orig = SparkMethod._finish

    def finish(self, t0, q0, h, x, it, res, step_index):
        if step_index == 2:
            x = x.copy()
            x[0] = np.nan
        return orig(self, t0, q0, h, x, it, res, step_index)
    monkeypatch.setattr(SparkMethod, "_finish", finish)
    with pytest.raises(NonFiniteError, match=r"step 2 \(t = 0.2 -> 0.3\) produced NaN"):
        integrate(sc.system, get_method("gauss-2"), t0, q0, v0, 0.1, n_steps=5)


@pytest.fixture(scope="module")
def coulomb():
    return _system(lambda q: -1 / q[0])                     # attracting U = -1/q1, singular at q1 = 0


def test_collision_through_1_over_q1_passes_silently_by_default(coulomb):
    # documented behaviour: finite values and a regular (4) on both sides of q1 = 0, so neither the
    # finiteness check nor the det (4) monitor sees the collision; the energy shows it
    sol = integrate(coulomb, get_method("gauss-2"), 0, [1, 0, 0], [-1, 0, 0], 0.1, n_steps=30)
    E = sol.energy.astype(float)
    assert E[0] == pytest.approx(-0.5) and np.max(E) > 100 and np.min(sol.q[:, 0]) < 0


def test_energy_jump_monitor_catches_the_collision(coulomb):
    with pytest.raises(NonFiniteError, match=r"step 5 \(t = 0.5 -> 0.6\): energy jumped from -0.51"):
        integrate(coulomb, get_method("gauss-2"), 0, [1, 0, 0], [-1, 0, 0], 0.1, n_steps=30, energy_jump=0.1)


def test_energy_jump_monitor_at_dps_judges_the_change_at_the_runs_digits():
    # at 30 digits the monitor compared float64 energies: the particle's change of 2.2e-19 .. 1.1e-18
    # a step (gauss-2, h = 1e-3; below float64's resolution of E = 1.5, 2.2e-16) was 0, so
    # energy_jump = 1e-21 (x 2.5 = 2.5e-21, 90x below the change) never fired. Control: 1e-16
    # (2.5e-16, 200x above the largest change) runs the 3 steps.
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial(30)
    kw = dict(n_steps=3, dps=30)
    with pytest.raises(NonFiniteError, match=r"step 0 .*energy jumped from 1.5 to 1.5 \(by 2.2\de-19"):
        integrate(sc.system, get_method("gauss-2"), t0, q0, v0, "1e-3", energy_jump=1e-21, **kw)
    sol = integrate(sc.system, get_method("gauss-2"), t0, q0, v0, "1e-3", energy_jump=1e-16, **kw)
    assert len(sol.t) == 4


def test_energy_jump_monitor_is_quiet_on_a_regular_run():
    # negative control: the monitor does not fire on the skate (energy error ~1e-6 per step at h = 0.1)
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    sol = integrate(sc.system, get_method("gauss-2"), t0, q0, v0, 0.1, n_steps=20, energy_jump=1e-3)
    assert len(sol.energy) == 21


@pytest.mark.parametrize("bad", [0, -1, float("nan"), "x"])
def test_energy_jump_must_be_positive(bad):
    sc = get_scene("skate")
    with pytest.raises(LdasparkError, match="energy_jump"):
        SparkMethod(sc.system, get_method("gauss-2"), energy_jump=bad)


@pytest.mark.parametrize("name, dps", [("lobatto-iiia-iiib-2-leapfrog", None), ("lobatto-iiia-iiib-2-leapfrog", 30),
                                       ("gauss-irk-2", None)])
def test_comparators_leaving_the_domain_stop_with_step_and_time(name, dps):
    from ldaspark.core.comparators import integrate_comparator
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    sysm = LagrangianSystem.mechanical_form(sympy.eye(3), -sympy.log(1 - q[0]), [[0, -q[1], 1]], q=q, v=v)
    with pytest.raises(NonFiniteError, match=r"step 3 \(t = 0.3 -> 0.4\)"):
        integrate_comparator(name, sysm, 0, [0, 0, 0], [3, 0, 0], 0.1 if dps is None else "0.1", 20, dps=dps)
