"""An mpmath parameter value (``params={"m": mpf}``) is written as a decimal string of the run's
``dps`` significant digits, as the arrays are (the file contract), in every format: it was
``str(mpf)``, printed at mpmath's global precision (15 digits), so the file of a dps = 30 run
held m = 1/3 to 15 digits and a rerun from the loaded params differed from the run at the 16th
digit. Cost ~3 s."""
import warnings

import mpmath
import pytest
import sympy as sp

import ldaspark
from ldaspark.core.resultio import load_result, save_result

FORMATS = (".json", ".npz", ".h5")


def _skate_with_mass():
    x, y, th, vx, vy, vth, m = sp.symbols("x y th vx vy vth m")
    return ldaspark.LagrangianSystem(m * (vx ** 2 + vy ** 2) / 2 + vth ** 2 / 2, [sp.sin(th) * vx - sp.cos(th) * vy],
                                     [x, y, th], [vx, vy, vth], params=[m], name="skate-m")


KW = dict(t0=0, t_end=1, q0=[0, 0, 0], v0=[1, 0, 1], h="0.5", dps=30)


@pytest.mark.parametrize("ext", FORMATS)
def test_an_mpmath_parameter_keeps_the_runs_digits(tmp_path, ext):
    if ext == ".h5":
        pytest.importorskip("h5py")
    sysm = _skate_with_mass()
    with mpmath.workdps(30):
        third = mpmath.mpf(1) / 3
        want = mpmath.nstr(third, 30, strip_zeros=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = ldaspark.integrate(sysm, "gauss-2", params={"m": third}, **KW)
        save_result(r, tmp_path / f"r{ext}")
        back = load_result(tmp_path / f"r{ext}")
        assert back.params == {"m": want}, back.params            # 30 digits, not str(mpf)'s 15
        again = ldaspark.integrate(sysm, "gauss-2", params=back.params, **KW)
    # the energy m (vx^2 + vy^2) / 2 + vth^2 / 2 at t0 = 1/3 * 1/2 + 1/2 = 2/3: the rerun from the
    # file's params agrees with the run to its 30 digits (15 digits of m gave a difference ~1e-16)
    with mpmath.workdps(30):
        assert abs(again.energy[0] - r.energy[0]) < mpmath.mpf(10) ** -28
        assert abs(r.energy[0] - mpmath.mpf(2) / 3) < mpmath.mpf(10) ** -28


@pytest.mark.parametrize("ext", FORMATS)
def test_control_other_parameter_values_are_written_as_before(tmp_path, ext):
    """Control: floats stay floats, sympy Rationals their exact text (unchanged by the fix)."""
    if ext == ".h5":
        pytest.importorskip("h5py")
    sysm = _skate_with_mass()
    for value, stored in ((2.5, 2.5), (sp.Rational(1, 3), "1/3")):
        r = ldaspark.integrate(sysm, "gauss-2", params={"m": value}, **KW)
        save_result(r, tmp_path / f"r{ext}")
        assert load_result(tmp_path / f"r{ext}").params == {"m": stored}


@pytest.mark.parametrize("ext", FORMATS)
def test_an_mpmath_step_keeps_the_runs_digits(tmp_path, ext):
    """The same for h given as an mpf (integrate keeps it as given in Result.h): h = 1/30 at
    dps = 30 was stored as '0.0333333333333333' (15 digits); the run's t is n h to 30 digits."""
    if ext == ".h5":
        pytest.importorskip("h5py")
    with mpmath.workdps(30):
        h = mpmath.mpf(1) / 30
        want = mpmath.nstr(h, 30, strip_zeros=False)
    r = ldaspark.integrate("skate", "gauss-2", t0=0, n_steps=3, h=h, dps=30)
    save_result(r, tmp_path / f"r{ext}")
    back = load_result(tmp_path / f"r{ext}")
    assert back.h == want, back.h
    with mpmath.workdps(30):     # the file's h gives the file's t to its 30 digits
        assert abs(3 * mpmath.mpf(back.h) - back.t[-1]) < mpmath.mpf(10) ** -28
    # control: a decimal-string step is stored as given
    r = ldaspark.integrate("skate", "gauss-2", t0=0, n_steps=3, h="0.1", dps=30)
    save_result(r, tmp_path / f"s{ext}")
    assert load_result(tmp_path / f"s{ext}").h == "0.1"
