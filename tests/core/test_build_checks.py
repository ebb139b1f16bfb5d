"""Checks made when a LagrangianSystem is built: physical units are refused at once; velocities
along which L_vv vanishes identically are found and refused at the set-up of integrate (before
step 0), even where the saddle matrix (4) is regular."""
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark import LagrangianSystem
from ldaspark.core.errors import SingularSaddleError, SystemDefinitionError

x, y, th = sympy.symbols("x y th")
vx, vy, vth = sympy.symbols("vx vy vth")
Q0, V0 = [0.0, 0.0, 0.3], [1.0, float(np.sin(0.3)), 0.5]


def _toy(L):
    return LagrangianSystem(L, [vy - sympy.sin(th) * vx], [x, y, th], [vx, vy, vth], name="toy")


@pytest.mark.parametrize("engine", ["generic", "auto"])
def test_velocity_missing_from_L_is_named_at_set_up(engine, monkeypatch):
    """L without vy, K = (-sin th, 1, 0): (4) is regular, the stage equations are not solvable.
    The set-up names vy (one line); control: with the check switched off the run fails at step 0
    in Newton, and with vy in L it runs."""
    sysm = _toy((vx ** 2 + vth ** 2) / 2 - sympy.cos(th))
    assert "vy" in sysm.lvv_problem
    with pytest.raises(SingularSaddleError) as err:
        ldaspark.integrate(sysm, "gauss-2", n_steps=3, h=0.1, q0=Q0, v0=V0, engine=engine)
    msg = str(err.value)
    assert "L does not contain the velocities vy" in msg and "\n" not in msg
    monkeypatch.setattr(sysm, "lvv_problem", None)
    r = ldaspark.integrate(sysm, "gauss-2", n_steps=3, h=0.1, q0=Q0, v0=V0, engine="generic")
    assert r.status == -1 and "singular" in r.message and len(r.t) == 1
    ok = ldaspark.integrate(_toy((vx ** 2 + vy ** 2 + vth ** 2) / 2 - sympy.cos(th)), "gauss-2", n_steps=3, h=0.1,
                            q0=Q0, v0=V0, engine="generic")
    assert ok.success and ok.coordinate_names == ["x", "y", "th"]


def test_L_affine_in_a_velocity_is_named():
    """A gyroscopic term x vy makes L depend on vy, but only linearly: L_vv still vanishes along it."""
    sysm = _toy((vx ** 2 + vth ** 2) / 2 + x * vy)
    assert "L_vv vanishes along the velocities vy" in sysm.lvv_problem
    assert _toy((vx ** 2 + vth ** 2 + vy ** 2) / 2 + x * vy).lvv_problem is None


def test_physical_units_are_refused_at_build():
    from sympy.physics.units import kilogram, meter, second
    with pytest.raises(SystemDefinitionError) as err:
        _toy(kilogram * (vx ** 2 + vy ** 2 + vth ** 2) / 2 - 9.81 * meter / second ** 2 * x)
    msg = str(err.value)
    assert "physical units" in msg and "kilogram" in msg and "\n" not in msg
    with pytest.raises(SystemDefinitionError, match="physical units"):
        LagrangianSystem((vx ** 2 + vy ** 2 + vth ** 2) / 2, [vy - meter * vx], [x, y, th], [vx, vy, vth])
    assert _toy(2 * (vx ** 2 + vy ** 2 + vth ** 2) / 2 - x).lvv_problem is None     # control: numbers
