"""Neighbours of the round-4 representatives, tried as an attacker would: other number types in
event values, other exported functions taking dps, guesses and index lists, and the arrays in
error messages. One refusal per assertion, each with a valid neighbour that is still accepted."""
from __future__ import annotations

from fractions import Fraction

import mpmath
import numpy as np
import pytest

import ldaspark
from ldaspark import LdasparkError
from ldaspark.core.errors import InputError


def _point():
    t0, q0, v0 = ldaspark.get_scene("skate").initial(None)
    return [float(x) for x in q0], [float(x) for x in v0]


# --- valid input refused: an event's value and direction of any real number type --------------
@pytest.mark.parametrize("engine", ["generic", "compiled"])
@pytest.mark.parametrize("kind", [mpmath.mpf, Fraction, np.float32])
def test_event_values_of_every_real_number_type(engine, kind):
    def g(t, q, v):
        return kind(t) - kind("0.05") if kind is not Fraction else Fraction(t) - Fraction(1, 20)
    g.direction = Fraction(1)
    r = ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=2, engine=engine, events=g)
    # the event g = t - 0.05 crosses zero once, inside the first step (its root to the event
    # solver's tolerance, far below the step 0.1)
    assert len(r.t_events[0]) == 1 and abs(float(r.t_events[0][0]) - 0.05) < 1e-6


@pytest.mark.parametrize("bad", ["0.5", b"1", 1j, True, np.array([0.5]), float("nan")])
def test_event_values_that_are_not_real_numbers_are_refused(bad):
    with pytest.raises(InputError, match="event 0"):
        ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=1, engine="generic", events=lambda t, q, v: bad)


# --- error messages stay one line when the value is an array ----------------------------------
def test_an_array_in_a_message_is_one_line():
    with pytest.raises(InputError) as exc:
        ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, tangent=np.zeros((3, 3)))
    assert "\n" not in str(exc.value)
    # valid neighbour: a 2n x r tangent
    assert ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, tangent=np.eye(6)[:, :2],
                                  select=[0, 1]).full.shape == (6, 6)


# --- the theory checks: dps of NumPy's integer types, one dps where one is read -----------------
@pytest.mark.parametrize("fn", ["theorem1_residuals", "check_symmetry"])
def test_theory_checks_take_a_numpy_dps_and_refuse_a_tuple(fn):
    q0, v0 = _point()
    kw = dict(max_refine=0) if fn == "theorem1_residuals" else {}
    f = getattr(ldaspark, fn)
    with pytest.raises(InputError, match="one integer"):
        f("skate", "gauss-1", 0, q0, v0, "0.1", dps=(20, 30), **kw)
    assert isinstance(f("skate", "gauss-1", 0, q0, v0, "0.1", dps=np.int64(20), **kw), dict)


def test_classify_wellposedness_takes_numpy_precisions():
    q0, v0 = _point()
    ldaspark.classify_wellposedness("skate", "gauss-1", 0, q0, v0, "0.1", dps=(np.int64(16), np.int32(20)))


def test_discrete_lagrangian_checks_its_guesses():
    q0, _ = _point()
    q1 = [x + 0.01 for x in q0]
    for kw in (dict(x_guess=[0.0]), dict(x_guess=[float("nan")]), dict(v0_guess=[0.0]), dict(gauge_ref="ab")):
        with pytest.raises(InputError):
            ldaspark.discrete_lagrangian("skate", "gauss-1", 0, q0, "0.1", q1, dps=16, **kw)
    d = ldaspark.discrete_lagrangian("skate", "gauss-1", 0, q0, "0.1", q1, dps=16, v0_guess=[0.1, 0.0, 0.1])
    assert d.p0.shape == (3,)


# --- silent numbers: flow_jacobian's t0 with a scene, dependent without coords / rates ---------
def test_flow_jacobian_uses_the_t0_it_is_given():
    with pytest.raises(InputError, match="does not advance t"):
        ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, t0=1e17)
    assert ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, t0=1.0).full.shape == (6, 6)


def test_flow_jacobian_dependent_needs_coords_or_rates():
    with pytest.raises(InputError, match="dependent"):
        ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, dependent=[0])
    fj = ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, coords=[0])
    assert fj.J.shape[1] == 1


def test_all_errors_derive_from_ldasparkerror():
    assert issubclass(InputError, LdasparkError)


def test_theory_checks_use_the_t0_they_are_given_with_a_scene():
    with pytest.raises(InputError, match="does not advance t"):
        ldaspark.check_symmetry("skate", "gauss-1", 1e17, None, None, 1, dps=16)
    assert isinstance(ldaspark.check_symmetry("skate", "gauss-1", 1.0, None, None, "0.1", dps=16), dict)


def test_fast_integrate_refuses_steps_that_do_not_advance_t():
    with pytest.raises(InputError, match="does not advance t"):
        ldaspark.fast_integrate("skate", "gauss-2", t0=1e17, h=1.0, n_steps=3)
    # valid neighbour: 32 is twice the spacing of the float64 numbers near 1e17
    assert len(set(ldaspark.fast_integrate("skate", "gauss-2", t0=1e17, h=32.0, n_steps=3).t.tolist())) == 4


# --- the mechanical form: one system for every engine, shapes checked -------------------------
def _mech(**kw):
    import sympy
    x, y, vx, vy = sympy.symbols("x y vx vy")
    d = dict(M=sympy.Matrix([[1, 0], [0, 2]]), U=y, K=sympy.Matrix([[1, -x]]))
    d.update(kw)
    return ldaspark.LagrangianSystem(vx ** 2 / 2 + vy ** 2 - y, [vx - x * vy], [x, y], [vx, vy], mechanical=d)


@pytest.mark.parametrize("part", ["U", "K", "b", "Uv"])
def test_mechanical_parts_must_match_L_and_k(part):
    import sympy
    x, y, vx = sympy.symbols("x y vx")
    bad = {"U": dict(U=2 * y), "K": dict(K=sympy.Matrix([[1, -2 * x]])), "b": dict(b=sympy.Matrix([1])),
           "Uv": dict(U=y + vx)}[part]
    with pytest.raises(LdasparkError, match="mechanical"):
        _mech(**bad)
    assert _mech().mechanical is not None          # the matching parts are accepted


@pytest.mark.parametrize("args", [
    dict(M=[[1, 0, 0], [0, 2, 0]], U="q1", K=[[1, "-q0"]]),          # M not square
    dict(M=[[1, 0], [0, 2]], U="q1", K=[[1, "-q0", 3]]),              # K of the wrong width
    dict(M=[[1, 0], [0, 2]], U="q1", K=[[1, "-q0"]], b=[1, 2]),       # b of the wrong height
    dict(M=[[1, 0], [0, 2]], U=["q1", "q1"], K=[[1, "-q0"]]),         # U not a scalar
])
def test_mechanical_form_checks_shapes(args):
    with pytest.raises(LdasparkError):
        ldaspark.LagrangianSystem.mechanical_form(**args)
    ldaspark.LagrangianSystem.mechanical_form([[1, 0], [0, 2]], "q1", [[1, "-q0"]], b=["q0"])


def test_with_params_takes_a_dict():
    import sympy
    s = ldaspark.LagrangianSystem("vx**2/2 + vy**2/2 - a*y", ["vx - x*vy"], ["x", "y"], ["vx", "vy"], params=["a"])
    for bad in ([1], "a", 3):
        with pytest.raises(LdasparkError, match="dict"):
            s.with_params(bad)
    assert s.with_params({"a": 1}).param_values() == {sympy.Symbol("a"): 1}


# --- checkpoints: the reader's depth check is linear in the line ----------------------------------
def test_checkpoint_depth_check_is_linear_on_a_forged_line():
    import time
    from ldaspark.executors import _json_depth
    # an unclosed string of escaped quotes: the former regular expression retried it at every
    # quote (quadratic: 18 s at 80 kB, hours at the 8 MiB line bound); now one pass
    forged = '"' + '\\"' * 400_000
    t = time.process_time()
    assert _json_depth(forged) == 0
    # bound: a linear pass over 800 kB takes milliseconds; 20 s is what the quadratic scan
    # needed for a tenth of this line (a hang caught, not a timing)
    assert time.process_time() - t < 20
    # valid neighbours: the depth of ordinary lines, brackets inside strings not counted
    assert _json_depth('[1, "a]", {"b": [2]}]') == 3 and _json_depth('["\\\\", [[]]]') == 3
    assert _json_depth('{"unit": "x", "value": "[[[["}') == 1


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


def test_a_huge_integer_in_a_message_is_its_size():
    from ldaspark.core import validate
    for x in (10 ** 400, -(10 ** 5000)):
        with pytest.raises(InputError, match="about 10"):
            validate.check_dps(x)
    with pytest.raises(InputError, match="100000"):
        validate.check_dps(100000)


# --- Dask addresses: the whole rest is host[:port] ----------------------------------------------
@pytest.mark.parametrize("addr", ["tcp://[::1]x", "tcp://[::1]x:1", "tcp://1.2.3.4.5:1", "tcp://[zz]:1",
                                  "tcp://999.1.1.1:8786"])
def test_addresses_with_text_urlsplit_ignores_are_refused(addr):
    from ldaspark.executors import check_where
    with pytest.raises(InputError, match="malformed"):
        check_where(addr)


@pytest.mark.parametrize("addr", ["tcp://[::1]:8786", "tcp://127.0.0.1:8786", "tls://h.example:1", "tcp://h",
                                  "TCP://h:1", "tcp://h:1/"])
def test_well_formed_addresses_still_pass(addr):
    from ldaspark.executors import check_where
    check_where(addr)


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


# --- the last neighbours: a misspelt option, the user's own event code, a flag's type, an
# executor that was shut down, a URL's trailing slash -----------------------------------------
def test_a_misspelt_integrate_option_is_one_line_naming_the_closest():
    with pytest.raises(InputError, match=r"unknown option 'tole' \(did you mean tol\?\)") as ei:
        ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=1, tole=1e-10)
    assert "\n" not in str(ei.value)
    r = ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=1, tol=1e-10)     # the neighbour
    assert r.status == 0


@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_an_event_that_raises_is_named_with_its_error_kept_as_cause(engine):
    def g(t, q, v):
        raise ZeroDivisionError("inside the user's event")
    with pytest.raises(InputError, match=r"event 0 raised ZeroDivisionError at t = 0: inside the user's event") as ei:
        ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=2, engine=engine, events=g)
    assert isinstance(ei.value.__cause__, ZeroDivisionError)


@pytest.mark.parametrize("bad", ["yes", "no", 1, 0.0, None])
def test_get_method_exact_must_be_a_bool(bad):
    with pytest.raises(LdasparkError, match="exact must be True or False"):
        ldaspark.get_method("gauss-2", exact=bad)
    assert ldaspark.get_method("gauss-2", exact=np.True_).exact is not None
    assert ldaspark.get_method("gauss-2", exact=False).s == 2


def test_an_executor_that_was_shut_down_is_refused_before_any_work():
    from concurrent.futures import ThreadPoolExecutor
    from ldaspark.ensemble import RunSpec
    q0, v0 = _point()
    Q, V = np.array([q0, q0]), np.array([v0, v0])
    ex = ThreadPoolExecutor(1)
    ex.shutdown()
    with pytest.raises(InputError, match="shut down"):
        ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=2, q0=Q, v0=V, executor=ex)

    class Refusing:     # an executor of another kind: its RuntimeError at submit is named
        def submit(self, *a, **k):
            raise RuntimeError("cannot schedule new futures after shutdown")

        def map(self, *a, **k):
            raise RuntimeError("cannot schedule new futures after shutdown")
    for engine in ("generic", "compiled"):
        with pytest.raises(InputError, match="refused new work") as ei:
            ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=2, q0=Q, v0=V, executor=Refusing(), engine=engine)
        assert isinstance(ei.value.__cause__, RuntimeError)
    with pytest.raises(InputError, match="refused new work"):
        ldaspark.run_many([RunSpec("skate", "gauss-1", 0.0, Q, V, 0.1, 2)], executor=Refusing())
    with ThreadPoolExecutor(1) as live:     # the neighbour: a live pool runs
        assert ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=2, q0=Q, v0=V, executor=live).success


def test_a_scheduler_address_with_a_trailing_slash_reaches_dask_without_it(monkeypatch):
    distributed = pytest.importorskip("distributed")
    from ldaspark import executors as workers
    seen = []

    def fake_client(addr, **kw):
        seen.append(addr)
        raise OSError("no scheduler here")
    monkeypatch.setattr(distributed, "Client", fake_client)
    for where in ("tcp://127.0.0.1:1/", "tcp://127.0.0.1:1"):
        with pytest.raises(InputError, match="cannot reach"):
            workers._Place(where, None, None)
    assert seen == ["tcp://127.0.0.1:1", "tcp://127.0.0.1:1"]
