"""Dense output (measured orders against the skate's closed-form solution) and events (located
crossing times against the exact ones)."""
import numpy as np
import pytest

import ldaspark
from ldaspark.core.errors import InputError
from ldaspark.models.scenes import get_scene

SK = get_scene("skate")
TT = np.linspace(0, 2, 201)
EXACT = [SK.exact_solution(t) for t in TT]
QE = np.array([e[0] for e in EXACT])
VE = np.array([e[1] for e in EXACT])
T_STAR = np.arcsin(np.sqrt(0.6))   # q1(t) = -sin(t)^2 / 2 on the skate: q1 = -0.3 here


def _orders(method, engine, hs=(0.2, 0.1, 0.05), extension=None):
    errs = []
    for h in hs:
        r = ldaspark.integrate(SK, method, t_span=(0, 2), h=h, engine=engine, dense_output=True)
        q, v = r.sol(TT) if extension is None else extension(r, TT)
        errs.append((np.abs(q - QE).max(), np.abs(v - VE).max()))
    e = np.array(errs)
    return np.log2(e[-2] / e[-1])


#: measured orders of the stage polynomial corrected to the grid (module docstring of
#: ``ldaspark.core.dense``): (q, v, exact) -- exact: two-sided within 0.25; else at least the order
#: (gauss-4's v measures 4.4 between h = 0.1 and 0.05, 4.0 between 0.2 and 0.1)
ORDERS = {"gauss-2": (4, 3, True), "gauss-3": (4, 3, True), "gauss-4": (5, 4, False),
          "lobatto-iiia-iiib-2": (2, 2, True), "lobatto-iiia-iiib-3": (4, 3, True)}


@pytest.mark.parametrize("engine", ["generic", "compiled"])
@pytest.mark.parametrize("method", list(ORDERS))
def test_dense_output_order(method, engine):
    q_order, v_order, exact = ORDERS[method]
    oq, ov = _orders(method, engine)
    if exact:
        assert abs(oq - q_order) < 0.25 and abs(ov - v_order) < 0.25, (oq, ov)
    else:
        assert oq > q_order - 0.25 and ov > v_order - 0.25, (oq, ov)


def _uncorrected(r, t):
    """The stage polynomial without the correction to the grid (the generic engine's dense output
    before it; how files written before it still read)."""
    from ldaspark.core.dense import CollocationDense
    return CollocationDense(r.sol.t, r.sol.q, r.sol.c, r.sol.V)(t)


@pytest.mark.parametrize("method, q_order, v_order", [("gauss-2", 3, 2), ("lobatto-iiia-iiib-2", 2, 1)])
def test_order_control_the_uncorrected_polynomial_is_lower(method, q_order, v_order):
    """Negative control of the measurement above: the uncorrected stage polynomial measures one
    order lower in v (and in q for gauss-2), which ``test_dense_output_order`` would reject."""
    oq, ov = _orders(method, "generic", extension=_uncorrected)
    assert abs(oq - q_order) < 0.25 and abs(ov - v_order) < 0.25, (oq, ov)
    assert abs(ov - ORDERS[method][1]) > 0.75


def test_dense_order_is_below_nodal_and_control_fails():
    """Negative control: a piecewise-constant extension (q_n on the whole step) is caught as
    order 1 by the same measurement."""
    def constant(r, t):
        k = np.clip(np.searchsorted(r.t, t, side="right") - 1, 0, len(r.t) - 2)
        return r.q[k], r.v[k]
    oq, ov = _orders("gauss-2", "generic", extension=constant)
    assert abs(oq - 1) < 0.3 and abs(ov - 1) < 0.3


def test_dense_output_interpolates_the_steps():
    r = ldaspark.integrate(SK, "gauss-3", t_span=(0, 1), h=0.1, engine="generic", dense_output=True)
    q, v = r.sol(r.t)
    assert np.abs(q - r.q).max() < 1e-13 and np.abs(v - r.v).max() < 1e-13    # the grid values
    assert r.sol(0.5)[0].shape == (3,)
    with pytest.raises(InputError):
        r.sol(1.5)


def _g(t, q, v):
    return q[0] + 0.3


def test_events_located_at_the_exact_crossings():
    exact = np.array([T_STAR, np.pi - T_STAR, np.pi + T_STAR, 2 * np.pi - T_STAR])
    r = ldaspark.integrate(SK, "gauss-2", t_span=(0, 7), h=0.05, engine="generic", events=_g)
    te = r.t_events[0]
    assert r.status == 0 and len(te) == 4 and np.abs(te - exact).max() < 1e-5
    assert np.abs(r.q_events[0][:, 0] + 0.3).max() < 1e-12          # g = 0 on the dense output
    # control: the secant of the nodal g values misses by much more than the dense-output root
    k = int(T_STAR / 0.05)
    g0, g1 = r.q[k, 0] + 0.3, r.q[k + 1, 0] + 0.3
    secant = r.t[k] - g0 * 0.05 / (g1 - g0)
    assert abs(secant - T_STAR) > 20 * abs(te[0] - T_STAR)
    up = lambda t, q, v: _g(t, q, v)
    up.direction = 1
    r2 = ldaspark.integrate(SK, "gauss-2", t_span=(0, 7), h=0.05, engine="generic", events=[up, _g])
    assert np.allclose(r2.t_events[0], exact[[1, 3]], atol=1e-5) and len(r2.t_events[1]) == 4


def test_terminal_event_stops_the_run():
    stop = lambda t, q, v: _g(t, q, v)
    stop.terminal = True
    for engine in ("generic", "compiled"):
        r = ldaspark.integrate(SK, "gauss-2", t_span=(0, 7), h=0.1, engine=engine, events=stop, save_every=3)
        assert r.status == 1 and r.success and abs(r.t_events[0][0] - T_STAR) < 1e-4
        assert r.t[-1] == pytest.approx(0.9) and r.t[-2] == pytest.approx(0.6)


# --- event direction: the three directions, terminal or not, several events,
# both engines; crossings known exactly from the skate's closed form q1(t) = -sin(t)^2 / 2 and a
# clock event g = t - 2.5 (upward only, exactly at 2.5)
DOWN = np.array([T_STAR, np.pi + T_STAR])          # g = q1 + 0.3 decreasing through 0
UP = np.array([np.pi - T_STAR, 2 * np.pi - T_STAR])   # increasing through 0
ENGINES = ("generic", "compiled")


def _event(direction=0, terminal=False, fn=_g):
    g = lambda t, q, v: fn(t, q, v)
    g.direction, g.terminal = direction, terminal
    return g


def _clock(t, q, v):
    return t - 2.5


@pytest.mark.parametrize("engine", ENGINES)
def test_event_directions_minus_zero_plus_at_once(engine):
    """direction -1 finds only the downward crossings, +1 only the upward, 0 both; the clock
    (increasing) fires for +1 and 0 and never for -1. Tolerance 1e-5: the located root of the
    dense output (the stage polynomial corrected to the grid, h = 0.05) is off by its interpolation error, ~1e-7."""
    evs = [_event(-1), _event(0), _event(1), _event(-1, fn=_clock), _event(1, fn=_clock), _event(0, fn=_clock)]
    r = ldaspark.integrate(SK, "gauss-2", t_span=(0, 7), h=0.05, engine=engine, events=evs)
    assert r.status == 0 and len(r.t_events) == 6
    assert len(r.t_events[0]) == 2 and np.abs(r.t_events[0] - DOWN).max() < 1e-5, r.t_events[0]
    assert len(r.t_events[1]) == 4 and np.abs(r.t_events[1] - np.sort(np.r_[DOWN, UP])).max() < 1e-5
    assert len(r.t_events[2]) == 2 and np.abs(r.t_events[2] - UP).max() < 1e-5, r.t_events[2]
    assert len(r.t_events[3]) == 0
    assert r.t_events[4] == pytest.approx([2.5], abs=1e-12) and r.t_events[5] == pytest.approx([2.5], abs=1e-12)
    # the states at the events lie on the exact trajectory
    for k in (0, 2):
        qe = np.array([SK.exact_solution(t)[0] for t in r.t_events[k]])
        assert np.abs(r.q_events[k] - qe).max() < 1e-5


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("direction,t_stop", [(-1, T_STAR), (1, np.pi - T_STAR), (0, T_STAR)])
def test_terminal_event_in_each_direction(engine, direction, t_stop):
    """A terminal event stops at its first crossing in its direction; the non-terminal events
    listed before and after it keep their crossings up to that point only."""
    # the last event (non-terminal, both directions) crosses in the same step as the terminal one:
    # it is recorded, and it must not cancel the stop
    evs = [_event(1), _event(direction, terminal=True), _event(-1, fn=_clock), _event(0)]
    r = ldaspark.integrate(SK, "gauss-2", t_span=(0, 7), h=0.05, engine=engine, events=evs)
    assert r.status == 1 and r.success
    assert len(r.t_events[1]) == 1 and abs(r.t_events[1][0] - t_stop) < 1e-5, r.t_events
    assert r.t[-1] == pytest.approx(0.05 * np.ceil(t_stop / 0.05), abs=1e-12)
    n_up = int(np.sum(UP < r.t[-1]))
    assert len(r.t_events[0]) == n_up and len(r.t_events[2]) == 0
    assert len(r.t_events[3]) == int(np.sum(np.r_[DOWN, UP] < r.t[-1])) and abs(r.t_events[3][-1] - t_stop) < 1e-5


@pytest.mark.parametrize("what", ["dense_output", "events"])
def test_dps_step_below_the_float64_grid_is_refused_before_the_run(what):
    """Dense output and events interpolate on a float64 grid (``core.dense``): at dps = 30,
    t0 = 1e6, h = 1e-15 advances t in 30 digits but not in float64, and the run was accepted, all
    its steps taken, then ended in 'dense output needs ... strictly monotone times' (events too,
    which the user had not asked to be dense). Now refused before any step, naming float64; the
    same run without them still runs (two-sided)."""
    kw = {"dense_output": True} if what == "dense_output" else {"events": lambda t, q, v: float(q[0]) - 2.0}
    with pytest.raises(InputError, match="float64"):
        ldaspark.integrate("particle", "gauss-2", t0=1e6, h=1e-15, n_steps=3, dps=30, **kw)
    r = ldaspark.integrate("particle", "gauss-2", t0=1e6, h=1e-15, n_steps=3, dps=30)
    assert r.status == 0 and len(set(r.t)) == 4
    r = ldaspark.integrate("particle", "gauss-2", t0=1e6, h=1e-9, n_steps=3, dps=30, **kw)
    assert r.status == 0
