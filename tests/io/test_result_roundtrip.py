"""Round trips of result files: every format (.json, .npz, .h5) x float64 and
mpmath precision x every field (t, q, v, psi, energy, constraint, stats, events, dense-output
data) comes back digit for digit: float64 bit for bit; mpmath numbers as the same ``dps``
significant digits the file contract stores (``nstr(x, dps)``), as mpf at that precision, also
when HDF5 returns them as byte strings. Cost ~10 s (three short runs, nine files)."""
import mpmath
import numpy as np
import pytest

import ldaspark
from ldaspark.core.dense import CollocationDense, HermiteDense
from ldaspark.core.resultio import _from_numbers, _json_value, load_result, save_result

FORMATS = (".json", ".npz", ".h5", ".hdf5")
ARRAYS = ("t", "q", "v", "energy", "constraint", "psi")


def _down(t, q, v):                 # the skate's q1 = -sin(t)^2 / 2 passes -0.1 downward at ~0.46
    return q[0] + 0.1


_down.direction = -1


def _never(t, q, v):                # never crosses: its event arrays are empty, shape (0, n)
    return 1.0 + q[0] ** 2


class _Runs(dict):
    """The three runs, each made at first use (a test needing only the mpmath run does not pay
    for the compiled one)."""

    def __missing__(self, kind):
        kw = dict(t_span=(0, 1), dense_output=True, events=[_down, _never])
        if kind == "mp40-generic":
            r = ldaspark.integrate("skate", "gauss-2", h="0.1", dps=40, **kw)
        else:
            r = ldaspark.integrate("skate", "gauss-2", h=0.1, engine=kind.split("-")[1], **kw)
        self[kind] = r
        return r


@pytest.fixture(scope="module")
def runs():
    return _Runs()


def _same_numbers(a, b, dps):
    if a is None or b is None:
        assert a is None and b is None
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    if dps is None:
        assert b.dtype == float and np.array_equal(a.astype(float), b)
        return
    assert b.dtype == object and all(isinstance(x, mpmath.mpf) for x in b.reshape(-1))
    with mpmath.workdps(dps):
        sa = [mpmath.nstr(x, dps, strip_zeros=False) for x in a.reshape(-1)]
        sb = [mpmath.nstr(x, dps, strip_zeros=False) for x in b.reshape(-1)]
    assert sa == sb


@pytest.mark.parametrize("ext", FORMATS)
@pytest.mark.parametrize("kind", ["float64-generic", "mp40-generic", "float64-compiled"])
def test_every_field_round_trips(runs, tmp_path, ext, kind):
    r = runs[kind]
    assert len(r.t_events[0]) == 1 and len(r.t_events[1]) == 0          # the fixture has both cases
    p = tmp_path / f"r{ext}"
    save_result(r, p)
    back = load_result(p)
    for name in ARRAYS:
        _same_numbers(getattr(r, name), getattr(back, name), r.dps)
    assert (back.method, back.scene, back.h, back.dps, back.status, back.engine, back.save_every) == \
           (r.method, r.scene, r.h, r.dps, r.status, r.engine, r.save_every)
    assert (back.nfev, back.njev, back.nlu, back.newton_iterations) == (r.nfev, r.njev, r.nlu, r.newton_iterations)
    assert back.stats == _json_value(r.stats) and back.stats
    assert back.coordinate_names == r.coordinate_names == ["q1", "q2", "q3"]
    # events: one array per event function, bit for bit, shapes kept when empty
    assert len(back.t_events) == len(r.t_events) == 2
    for e in range(2):
        for name in ("t_events", "q_events", "v_events"):
            a, b = np.asarray(getattr(r, name)[e]), getattr(back, name)[e]
            assert a.shape == b.shape and np.array_equal(a, b), (name, e)
    # dense output: the same interpolant (type and data), the same values anywhere
    assert type(back.sol) is type(r.sol)
    # every engine's SPARK run: the stage polynomial corrected to the grid (velocities kept too)
    assert isinstance(r.sol, CollocationDense) and r.sol.v is not None
    keys = ("t", "q", "v") if isinstance(r.sol, HermiteDense) else ("t", "q", "v", "c", "V")
    for k in keys:
        assert np.array_equal(getattr(r.sol, k), getattr(back.sol, k)), k
    tt = np.linspace(0, 1, 37)
    assert all(np.array_equal(x, y) for x, y in zip(r.sol(tt), back.sol(tt)))


def test_hdf5_gives_byte_strings_and_they_parse_to_full_precision(runs, tmp_path):
    """HDF5 returns the decimal strings of an mpmath run as bytes (dtype S): the parser must
    read them as mpf at the stored precision, not as float64."""
    h5py = pytest.importorskip("h5py")
    r = runs["mp40-generic"]
    save_result(r, tmp_path / "m.h5")
    with h5py.File(tmp_path / "m.h5", "r") as f:
        raw = f["q"][()]
    assert raw.dtype.kind == "S"
    back = _from_numbers(raw, 40)
    _same_numbers(r.q, back, 40)
    with mpmath.workdps(40):        # control: float64 parsing would lose ~24 digits
        assert max(abs(x - mpmath.mpf(float(x))) for x in back.reshape(-1)) > mpmath.mpf(10) ** -30


def test_mpmath_strings_in_the_file_are_the_dps_digit_strings(runs, tmp_path):
    """The stored strings are nstr(x, dps) of the run's numbers (the file contract); reading
    them back and writing again gives the same file content (idempotent)."""
    import json
    r = runs["mp40-generic"]
    save_result(r, tmp_path / "a.json")
    d = json.loads((tmp_path / "a.json").read_text())
    with mpmath.workdps(40):
        assert d["q"][-1][0] == mpmath.nstr(r.q[-1, 0], 40, strip_zeros=False)
    save_result(load_result(tmp_path / "a.json"), tmp_path / "b.json")
    d2 = json.loads((tmp_path / "b.json").read_text())
    assert {k: v for k, v in d2.items() if k != "version"} == {k: v for k, v in d.items() if k != "version"}


# --- a distinguishing fixture for the time origin: every scene starts at t0 = 0,
# where t_n = n h and t_n = t0 + n h agree; a restart at t0 = 0.2 of a time-dependent system must
# continue the run exactly (L and k of the rheonomic skate depend on t)
@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_restart_at_a_nonzero_time_continues_a_time_dependent_run(engine):
    kw = dict(h=0.1, engine=engine)
    full = ldaspark.integrate("rheonomic-skate", "gauss-2", n_steps=4, **kw)
    rest = ldaspark.integrate("rheonomic-skate", "gauss-2", t0=float(full.t[2]), q0=full.q[2], v0=full.v[2],
                              n_steps=2, **kw)
    assert np.allclose(rest.t, full.t[2:], rtol=0, atol=1e-15)
    # same steps from the same state: agreement to the Newton tolerance (measured ~1e-16)
    assert np.abs(rest.q - full.q[2:]).max() < 1e-12 and np.abs(rest.v - full.v[2:]).max() < 1e-12
    assert np.abs(rest.energy - full.energy[2:]).max() < 1e-12
    # control: the same restart with the clock reset to 0 is a different run (the system sees t)
    wrong = ldaspark.integrate("rheonomic-skate", "gauss-2", t0=0.0, q0=full.q[2], v0=full.v[2], n_steps=2,
                               project=True, **kw)
    assert np.abs(wrong.q[-1] - full.q[-1]).max() > 1e-6


# --- a run stopped by the step-acceptance guard (status -4, ``ldaspark.core.guard``): the file
# save_result writes must read back (the reader accepted statuses -3..1 only, so every format
# refused the file it had just written)
@pytest.mark.parametrize("ext", FORMATS)
def test_a_guard_stop_round_trips(tmp_path, ext):
    import warnings

    import sympy as sp

    from ldaspark.core import guard
    x, y, vx, vy = sp.symbols("x y vx vy")
    # the double well of tests/core/test_guard.py: Newton from zero increments lands on another
    # root of (21) at a later step
    well = ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - (x ** 4 / 4 - x ** 2 / 2), [vy], [x, y], [vx, vy],
                                     name="double-well")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = ldaspark.integrate(well, "gauss-1", engine="generic", newton=ldaspark.Newton(predictor="zero"), t0=0.0,
                               q0=[1.2, 0.0], v0=[1.5, 0.0], h=2.5, n_steps=30)
    assert r.status == guard.STATUS_GUARD, r.message
    save_result(r, tmp_path / f"g{ext}")
    back = load_result(tmp_path / f"g{ext}")
    assert (back.status, back.message) == (r.status, r.message) and not back.success
    assert np.array_equal(back.q, r.q)


@pytest.mark.parametrize("ext", FORMATS)
def test_a_step_given_as_a_zero_dimensional_array_round_trips(tmp_path, ext):
    """integrate takes h as a NumPy 0-d array (``validate.real_number``) and keeps it as given in
    ``Result.h``; writing the metadata raised a raw TypeError ('float' object is not iterable)
    from the JSON conversion of the array (``tolist()`` of a 0-d array is a number)."""
    res = ldaspark.integrate("skate", "gauss-2", n_steps=3, h=np.array(0.1), engine="generic")
    save_result(res, tmp_path / f"r{ext}")
    back = load_result(tmp_path / f"r{ext}")
    assert back.h == 0.1 and type(back.h) is float
    assert np.array_equal(np.asarray(back.q, float), np.asarray(res.q, float))
