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
