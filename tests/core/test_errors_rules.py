"""Rules of ``ldaspark.core.errors`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import pytest
from verification import strategies as ST
from fractions import Fraction
import numpy as np
import ldaspark
from ldaspark.core.errors import InputError
import mpmath
import sympy
from ldaspark.core.errors import InputError, SystemDefinitionError
from system_fakes import FakeSystem, _run, fake_system  # noqa: F401 (pytest fixtures)




def _lowest_case(monkeypatch, **kw):
    return _run(monkeypatch, ST.general_systems(**kw), "low")


@pytest.mark.filterwarnings("ignore:Using `assume` outside")
def test_general_systems_rejects_bad_base_points(fake_system, monkeypatch):
    """The base point is kept only when the projection converges, the saddle matrix (4) passes
    with rcond = 1e-6 and |v0|_inf < 3 (strict)."""
    from hypothesis.errors import UnsatisfiedAssumption
    for mode, accepted in ((dict(raise_=True), False), (dict(rc=1e-7), False), (dict(rc=1e-6), False),
                           (dict(rc=1e-5), True), (dict(v=[3, 0]), False), (dict(v=[-3.5, 0]), False),
                           (dict(v=[2.9, -1]), True), (dict(v=[0, -2.99]), True)):
        FakeSystem.mode = {("raise" if k == "raise_" else k): x for k, x in mode.items()}
        if accepted:
            c = _lowest_case(monkeypatch, n_range=(2, 2))
            assert c.dps == 60 and c.system.n == 2
            if "v" in mode:
                assert [float(x) for x in c.v0] == [float(x) for x in mode["v"]]
        else:
            with pytest.raises(UnsatisfiedAssumption):
                _lowest_case(monkeypatch, n_range=(2, 2))


def _point():
    t0, q0, v0 = ldaspark.get_scene("skate").initial(None)
    return [float(x) for x in q0], [float(x) for x in v0]


# --- the theory checks: dps of NumPy's integer types, one dps where one is read -----------------
@pytest.mark.parametrize("fn", ["theorem1_residuals", "check_symmetry"])
def test_theory_checks_take_a_numpy_dps_and_refuse_a_tuple(fn):
    q0, v0 = _point()
    kw = dict(max_refine=0) if fn == "theorem1_residuals" else {}
    f = getattr(ldaspark, fn)
    with pytest.raises(InputError, match="one integer"):
        f("skate", "gauss-1", 0, q0, v0, "0.1", dps=(20, 30), **kw)
    assert isinstance(f("skate", "gauss-1", 0, q0, v0, "0.1", dps=np.int64(20), **kw), dict)


def test_discrete_lagrangian_checks_its_guesses():
    q0, _ = _point()
    q1 = [x + 0.01 for x in q0]
    for kw in (dict(x_guess=[0.0]), dict(x_guess=[float("nan")]), dict(v0_guess=[0.0]), dict(gauge_ref="ab")):
        with pytest.raises(InputError):
            ldaspark.discrete_lagrangian("skate", "gauss-1", 0, q0, "0.1", q1, dps=16, **kw)
    d = ldaspark.discrete_lagrangian("skate", "gauss-1", 0, q0, "0.1", q1, dps=16, v0_guess=[0.1, 0.0, 0.1])
    assert d.p0.shape == (3,)


# --- result files: the .json extra arrays checked like every other field ------------------------
@pytest.mark.parametrize("bad", ["x", 3, [1], {"t_events_0": [1]}, {"t_events_0": {"shape": [2], "data": [1]}},
                                 {"t_events_0": {"shape": [-1], "data": []}},
                                 {"t_events_0": {"shape": [1], "data": ["1"]}}])
def test_json_extra_arrays_are_checked(tmp_path, bad):
    import json
    r = ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=3, engine="generic",
                           events=lambda t, q, v: t - 0.15)
    p = tmp_path / "r.json"
    ldaspark.save_result(r, p)
    assert len(ldaspark.load_result(p).t_events[0]) == 1          # valid neighbour: the file as written
    d = json.loads(p.read_text())
    d["extra_arrays"] = bad
    p.write_text(json.dumps(d))
    with pytest.raises(InputError):
        ldaspark.load_result(p)


# --- SparkTableau.with_entry: a coefficient, indices in range, a finite real delta ---------------
@pytest.mark.parametrize("exact", [True, False])
@pytest.mark.parametrize("args", [("Z", 0, 0, "1"), ("A", 5, 0, "1"), ("A", -1, 0, "1"), ("A", 0.0, 0, "1"),
                                  ("A", 0, None, "1"), ("b", 0, 0, "1"), ("A", 0, 0, float("nan")), ("A", 0, 0, 1j),
                                  ("A", True, 0, "1")])
def test_with_entry_refuses_what_would_wrap_or_raise(exact, args):
    from ldaspark.core.errors import TableauError
    g = ldaspark.gauss(2, exact=exact)
    with pytest.raises(TableauError):
        g.with_entry(*args)
    # valid neighbours: an index of NumPy's type, a vector entry, a Fraction delta
    assert g.with_entry("A", np.int64(1), 0, Fraction(1, 10)).s == 2
    assert g.with_entry("b", 0, None, "1/10").s == 2


@pytest.mark.parametrize("delta", ["sqrt(2)/1000", "1/3", Fraction(1, 10), np.float64(0.25), np.int64(1)])
def test_with_entry_same_delta_on_exact_and_computed(delta):
    """A delta means the same number on an exact and on a computed tableau: the computed one added
    mpmath.mpf(delta), so "sqrt(2)/1000", a Fraction or a NumPy scalar passed with_entry and raised
    ValueError / TypeError at the first arrays()."""
    import mpmath
    ex = ldaspark.gauss(2, exact=True).with_entry("A", 0, 1, delta).arrays(40)
    nu = ldaspark.gauss(2).with_entry("A", 0, 1, delta).arrays(40)
    with mpmath.workdps(40):
        assert abs(ex.A[0, 1] - nu.A[0, 1]) < mpmath.mpf(10) ** -38


@pytest.mark.parametrize("exact", [True, False])
def test_with_entry_refuses_text_that_is_not_a_number(exact):
    from ldaspark.core.errors import TableauError
    with pytest.raises(TableauError, match="not a number"):
        ldaspark.gauss(2, exact=exact).with_entry("A", 0, 1, "abc")


def _skate_point():
    t0, q0, v0 = ldaspark.get_scene("skate").initial(None)
    return [float(x) for x in q0], [float(x) for x in v0]


# --- root 4: silent wrong numbers --------------------------------------------------------------
X, Y, VX, VY = sympy.symbols("x y vx vy")


def test_theorem1_and_wellposedness_refuse_h0_and_take_a_scene_name():
    skate = ldaspark.get_scene("skate")
    q0, v0 = _skate_point()
    tab = ldaspark.get_method("gauss-1")
    for fn in (ldaspark.theorem1_residuals, ldaspark.check_symmetry):
        with pytest.raises(InputError, match="h must be nonzero"):
            fn(skate.system, tab, 0, q0, v0, 0, dps=20)
    with pytest.raises(InputError, match="h must be nonzero"):
        ldaspark.classify_wellposedness(skate.system, tab, 0, q0, v0, 0, dps=(16, 20))
    by_name = ldaspark.theorem1_residuals("skate", "gauss-1", 0, None, None, "0.1", dps=20, max_refine=0)
    by_obj = ldaspark.theorem1_residuals(skate.system, tab, 0, q0, v0, "0.1", dps=20, max_refine=0)
    assert by_name["theorem1-q0"] < 1e-15 and by_obj["theorem1-q0"] < 1e-15
    cls = ldaspark.classify_wellposedness("skate", "gauss-1", 0, None, None, "0.1", dps=(16, 20))
    assert "sigma" in cls
    with pytest.raises(InputError, match="system"):
        ldaspark.theorem1_residuals(3, tab, 0, q0, v0, "0.1")
    with pytest.raises(InputError, match="h_factors"):
        ldaspark.classify_wellposedness("skate", "gauss-1", 0, None, None, "0.1", dps=(16, 20), h_factors=(1,))


def test_parameter_declarations_are_checked():
    L = "a*vx**2/2 + vy**2/2"
    for bad in (dict(params={"a": True}), dict(params={"a": np.bool_(False)}), dict(params=["x"]),
                dict(params=["t"]), dict(params=["a", "a"]), dict(params={"a": float("nan")})):
        with pytest.raises(SystemDefinitionError):
            ldaspark.LagrangianSystem(L, ["vx - vy"], [X, Y], [VX, VY], **bad)
    ok = ldaspark.LagrangianSystem(L, ["vx - vy"], [X, Y], [VX, VY], params={"a": 2.0})
    with pytest.raises(SystemDefinitionError, match="bool"):
        ok.with_params(a=True)
    with pytest.raises(InputError, match="bool"):
        ldaspark.integrate(ok, "gauss-1", q0=[0, 0], v0=[1, 1], h=0.1, n_steps=1, params={"a": True})
    res = ldaspark.integrate(ok, "gauss-1", q0=[0, 0], v0=[1, 1], h=0.1, n_steps=1, engine="generic",
                             params={"a": 3})
    assert res.status == 0


# --- root 7: valid input that was refused --------------------------------------------------------
def test_dense_output_at_mpf_and_fraction_times():
    res = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=3, dense_output=True, engine="generic")
    ref = res.sol(0.05)
    for t in (mpmath.mpf("0.05"), Fraction(1, 20), sympy.Rational(1, 20), np.float32(0.05)):
        q, v = res.sol(t)
        assert np.allclose(q, ref[0], atol=1e-7) and np.allclose(v, ref[1], atol=1e-7)
    q, _ = res.sol([mpmath.mpf("0.05"), Fraction(1, 10)])
    assert q.shape == (2, 3)
    for bad in ("0.05", mpmath.mpf("nan"), Fraction(10 ** 400, 1), [mpmath.mpc(1, 1)], True):
        with pytest.raises(InputError):
            res.sol(bad)
