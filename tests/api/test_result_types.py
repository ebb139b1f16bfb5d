"""One field order for the result types: ``Result`` and the deprecated ``Solution``
(``core.spark.integrate``), ``FastSolution`` (``fast_integrate``, ``run_compiled``) and
``EnsembleResult`` (``ensemble_integrate``) start with the same six fields in the same order, psi
at position 5 in each (``result.LEADING_FIELDS``); the old positional order of FastSolution still
builds the same object."""
import dataclasses
import warnings

import numpy as np

import ldaspark
from ldaspark.compiled.runner import FastSolution
from ldaspark.core.result import LEADING_FIELDS, Result
from ldaspark.core.spark import Solution
from ldaspark.ensemble import EnsembleResult


def leading(cls) -> tuple:
    return tuple(f.name for f in dataclasses.fields(cls))[:len(LEADING_FIELDS)]


def test_every_result_type_leads_with_the_fields_of_result():
    assert LEADING_FIELDS == ("t", "q", "v", "energy", "constraint", "psi")
    for cls in (Result, Solution, FastSolution, EnsembleResult):
        assert leading(cls) == LEADING_FIELDS, cls.__name__


def test_negative_control_another_order_is_seen():
    @dataclasses.dataclass
    class Old:                       # the order Solution had: psi before energy
        t: int
        q: int
        v: int
        psi: int
        energy: int
        constraint: int
    assert leading(Old) != LEADING_FIELDS


def test_fast_solution_takes_the_old_positional_order():
    a = [np.zeros(2)] * 5
    st, psi = {"steps": 1}, np.ones((1, 2, 1))
    old = FastSolution(*a, st, psi)                   # (t, q, v, energy, constraint, stats, psi)
    new = FastSolution(*a, psi, st)
    assert old.stats is st and old.psi is psi and new.stats is st and new.psi is psi
    bare = FastSolution(*a, st)                       # (t, q, v, energy, constraint, stats)
    assert bare.stats is st and bare.psi is None
    assert list(old)[5] is st                         # unpacks as before: (t, q, v, energy, constraint, stats)


def test_the_legacy_entry_points_fill_the_fields_by_name():
    sc = ldaspark.get_scene("skate")
    res = ldaspark.integrate(sc, "gauss-2", h=0.1, n_steps=4, engine="compiled")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        fs = ldaspark.fast_integrate(sc, "gauss-2", h=0.1, n_steps=4)
    from ldaspark.core.families import get_method
    from ldaspark.core.spark import integrate
    t0, q0, v0 = sc.initial()
    sol = integrate(sc.system, get_method("gauss-2"), t0, q0, v0, 0.1, n_steps=4)
    for other in (fs, sol):
        assert isinstance(other.stats, dict) and np.shape(other.psi) == np.shape(res.psi) == (4, 2, 1)
        np.testing.assert_allclose(np.asarray(other.energy, float), res.energy, rtol=0, atol=1e-13)
    assert np.array_equal(fs.psi, res.psi)


def test_raise_for_status_of_a_batch_without_members():
    """A batched Result without its member Results (an ensemble file of an earlier version) raised
    numpy's ValueError ("truth value of an array ... is ambiguous"); now the first failed member's
    message as an LdasparkError, and nothing when every member succeeded."""
    import pytest

    from ldaspark.core.errors import LdasparkError
    z = np.zeros((2, 3, 1))
    bad = Result(np.zeros((2, 3)), z, z, np.zeros((2, 3)), z, status=np.array([0, -1]),
                 message=["The integration reached t_end.", "Newton failed at step 2"])
    with pytest.raises(LdasparkError, match="member 1: Newton failed at step 2"):
        bad.raise_for_status()
    good = dataclasses.replace(bad, status=np.array([0, 1]))
    assert good.raise_for_status() is good


def test_a_loaded_failure_raises_the_class_of_its_status(tmp_path):
    """``raise_for_status`` of a Result read back from a file (which keeps status and message, not
    the exception object) raised a bare LdasparkError where the run's own Result raised
    NewtonError: ``except NewtonError`` caught the failure of the run and missed the same failure
    saved and loaded. Now the class of the documented status: -1 NewtonError, -2
    SingularSaddleError, -4 RootMismatchError (-3 and others: LdasparkError), batch or single."""
    import pytest

    import ldaspark
    from ldaspark.core.errors import LdasparkError, NewtonError, SingularSaddleError
    from ldaspark.core.guard import RootMismatchError
    r = ldaspark.integrate("pendulum", "gauss-2", n_steps=3, h=0.2, engine="generic", guard=False,
                           newton=ldaspark.Newton(max_iter=2))
    assert r.status == -1 and isinstance(r.error, NewtonError)
    for ext in ("json", "npz"):
        ldaspark.save_result(r, tmp_path / f"f.{ext}")
        back = ldaspark.load_result(tmp_path / f"f.{ext}")
        assert back.error is None
        with pytest.raises(NewtonError, match="did not converge"):
            back.raise_for_status()
    z = np.zeros((1, 2, 1))
    for status, cls in ((-1, NewtonError), (-2, SingularSaddleError), (-4, RootMismatchError), (-3, LdasparkError)):
        one = Result(np.zeros(2), z[0], z[0], np.zeros(2), z[0], status=status, message="why")
        with pytest.raises(cls, match="why") as info:
            one.raise_for_status()
        assert type(info.value) is cls
        batch = Result(np.zeros((1, 2)), z, z, np.zeros((1, 2)), z, status=np.array([status]), message=["why"])
        with pytest.raises(cls, match="member 0: why") as info:
            batch.raise_for_status()
        assert type(info.value) is cls


def test_steps_between_counts_in_the_run_numbers():
    """round((t_b - t_a) / h) as the driver, the guard and the det (4) scan count steps: float64
    inputs in float64; mpf times and a decimal-string h (a run at dps digits) in mpmath at the
    precision the grid needs. In float64 h = 1e-400 is 0.0 (ZeroDivisionError before); 1 + 7e-25
    is 1.0 (0 steps, wrong) at 53 bits."""
    import mpmath
    from ldaspark.core.grid import steps_between
    assert steps_between(0.0, 0.30000000000000004, 0.1) == 3            # float64 control
    assert steps_between(0, mpmath.mpf("3e-400"), "1e-400") == 3
    with mpmath.workdps(40):
        t1 = mpmath.mpf(1) + 7 * mpmath.mpf("1e-25")
        far = mpmath.mpf(-5) + 123456789 * mpmath.mpf("1e-30")
    assert steps_between(mpmath.mpf(1), t1, "1e-25") == 7
    assert steps_between(-5, far, "1e-30") == 123456789
    assert steps_between(mpmath.mpf(1), t1, 1e-25) == 7                  # a float h beside mpf times


def test_steps_between_spans_the_grids_whole_range_of_magnitudes():
    """A grid at 1e100 with h = 1e-100 (a run at 250 digits) needs ~670 bits to tell t0 + 7 h from
    t0: steps_between divides at log2(|t| / h) + 128 bits. Controls: the same quotient at a fixed
    128 bits (what a precision that ignores the span gives) rounds the 7 steps away, and at
    log3 instead of log2 of the span (419 + 128 bits) as well."""
    import mpmath
    from ldaspark.core.grid import steps_between
    with mpmath.workdps(250):
        t0 = mpmath.mpf(10) ** 100
        t1 = t0 + 7 * mpmath.mpf("1e-100")
        assert t1 != t0
    assert steps_between(t0, t1, "1e-100") == 7
    assert steps_between(t1, t0, "1e-100") == -7
    for bits in (128, int(mpmath.log(t0 / mpmath.mpf("1e-100"), 3)) + 128):
        with mpmath.workprec(bits):
            assert int(mpmath.nint((mpmath.mpf(t1) - mpmath.mpf(t0)) / mpmath.mpf("1e-100"))) != 7
