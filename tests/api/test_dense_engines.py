"""The dense output and the events are the same on every engine: the stage polynomial of each
SPARK step corrected to the grid (``ldaspark.core.dense``), the compiled engine solving each
step's stages again from its saved start. Each test has a negative control: the previous pair
(the generic engine's uncorrected stage polynomial, the compiled engine's cubic Hermite), or the
uncorrected polynomial alone, fails the same check."""
import numpy as np
import pytest
from scipy.optimize import brentq

import ldaspark
from ldaspark.core.dense import CollocationDense, HermiteDense
from ldaspark.core.errors import InputError
from ldaspark.models.scenes import get_scene

SK = get_scene("skate")
EPS = np.finfo(float).eps

#: (system, method, h, t_end)
CASES = [("skate", "gauss-2", 0.1, 3.0), ("skate", "gauss-8", 1.5, 15.0),
         ("pendulum", "lobatto-iiia-iiib-2", 0.1, 2.0), ("relativistic", "gauss-2", 0.05, 1.0)]


def _pair(system, method, h, t_end, **kw):
    return [ldaspark.integrate(system, method, t_span=(0, t_end), h=h, engine=e, dense_output=True, **kw)
            for e in ("generic", "compiled")]


def _old_generic(r):
    """The generic engine's dense output before the correction (the uncorrected stage polynomial)."""
    return CollocationDense(r.sol.t, r.sol.q, r.sol.c, r.sol.V)


def _old_compiled(r):
    """The compiled engine's dense output before: the cubic Hermite of the grid."""
    return HermiteDense(r.sol.t, r.sol.q, r.sol.v)


def _rel(a, b):
    (qa, va), (qb, vb) = a, b
    return max(np.abs(qa - qb).max() / (1 + np.abs(qa).max()), np.abs(va - vb).max() / (1 + np.abs(va).max()))


@pytest.mark.parametrize("system, method, h, t_end", CASES)
def test_engines_give_the_same_dense_output(system, method, h, t_end):
    g, c = _pair(system, method, h, t_end)
    assert c.engine == "compiled" and g.engine == "generic"
    assert isinstance(g.sol, CollocationDense) and isinstance(c.sol, CollocationDense)
    tt = np.linspace(0, t_end, 1001)
    new = _rel(g.sol(tt), c.sol(tt))
    assert new < 1e-11, new
    # control: the previous pair differs by far more (O(h^2) .. O(h^4) of the interpolants)
    old = _rel(_old_generic(g)(tt), _old_compiled(c)(tt))
    assert old > 1e4 * max(new, 1e-15), (old, new)


@pytest.mark.parametrize("engine", ["generic", "compiled"])
@pytest.mark.parametrize("every", [1, 3])
@pytest.mark.parametrize("system, method, h", [("pendulum", "lobatto-iiia-iiib-2", 0.1), ("skate", "gauss-3", 0.2),
                                               ("skate", "gauss-8", 1.5)])
def test_dense_output_reproduces_the_saved_grid(system, method, h, every, engine):
    r = ldaspark.integrate(system, method, n_steps=10, h=h, engine=engine, dense_output=True, save_every=every)
    q, v = r.sol(r.t)
    q0, v0 = r.sol(float(r.t[0]))
    for got, want in ((q, r.q), (v, r.v), (q0, r.q[0]), (v0, r.v[0])):
        assert np.all(np.abs(got - want) <= 8 * EPS * np.maximum(1, np.abs(want))), np.abs(got - want).max()
    if method == "lobatto-iiia-iiib-2":
        # control: the uncorrected stage polynomial misses v_n (its stage velocities are not v_n)
        qo, vo = _old_generic(r)(r.t)
        assert np.abs(vo - r.v).max() > 1e-3


def _down(t, q, v):
    return q[0] + 0.3


_down.direction = -1


def _pendulum_x(t, q, v):
    return q[0] - 0.5


@pytest.mark.parametrize("system, method, h, t_end, event", [
    ("skate", "gauss-2", 0.1, 7.0, _down), ("skate", "gauss-8", 1.5, 30.0, _down),
    ("pendulum", "lobatto-iiia-iiib-2", 0.1, 3.0, _pendulum_x)])
def test_event_times_agree_between_engines(system, method, h, t_end, event):
    g, c = [ldaspark.integrate(system, method, t_span=(0, t_end), h=h, engine=e, events=event)
            for e in ("generic", "compiled")]
    tg, tc = g.t_events[0], c.t_events[0]
    assert len(tg) == len(tc) >= 1
    assert np.abs(tg - tc).max() < 1e-10 * (1 + np.abs(tg).max()), np.abs(tg - tc).max()
    # control: the crossings located on the previous pair of interpolants differ by far more
    d = _pair(system, method, h, t_end)[0]
    old = []
    for sol in (_old_generic(d), _old_compiled(d)):
        k = int(np.searchsorted(d.t, tg[0])) - 1
        old.append(brentq(lambda t: event(t, *sol(t)), d.t[k], d.t[k + 1], xtol=1e-15))
    assert abs(old[0] - old[1]) > 1e-8, old


T_STAR = np.arcsin(np.sqrt(0.6))
DOWN = np.array([T_STAR, np.pi + T_STAR])          # q1 + 0.3 decreasing in t through 0
UP = np.array([np.pi - T_STAR, 2 * np.pi - T_STAR])


@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_backward_run_events_and_dense_output(engine):
    """h < 0 (t decreasing from 7 to 0): events and dense output as for h > 0, ``direction`` along
    the integration as in scipy's solve_ivp (+1: g increasing as the run proceeds, here the
    crossings where q1 + 0.3 decreases in t); the crossings come in the run's order."""
    q7, v7, _ = SK.exact_solution(7.0)
    up = lambda t, q, v: q[0] + 0.3      # noqa: E731
    up.direction = 1
    stop = lambda t, q, v: q[0] + 0.3    # noqa: E731
    stop.terminal = True
    both = lambda t, q, v: q[0] + 0.3    # noqa: E731
    r = ldaspark.integrate(SK, "gauss-3", t_span=(7, 0), q0=q7, v0=v7, h=-0.05, engine=engine,
                           dense_output=True, events=[both, up])
    assert r.status == 0 and r.t[0] == 7 and r.t[-1] == pytest.approx(0, abs=1e-12)
    allx = np.sort(np.r_[DOWN, UP])[::-1]
    assert np.abs(r.t_events[0] - allx).max() < 1e-6, r.t_events[0]
    assert np.abs(r.t_events[1] - DOWN[::-1]).max() < 1e-6, r.t_events[1]
    # control: the same direction in the forward run picks the other crossings
    fwd = ldaspark.integrate(SK, "gauss-3", t_span=(0, 7), h=0.05, engine=engine, events=up)
    assert np.abs(fwd.t_events[0] - UP).max() < 1e-6 and np.abs(fwd.t_events[0] - DOWN).min() > 0.1
    # the dense output on the decreasing grid: the exact solution, the grid values, the interval
    tt = np.linspace(0, 7, 71)
    q, v = r.sol(tt)
    qe = np.array([SK.exact_solution(t)[0] for t in tt])
    assert np.abs(q - qe).max() < 1e-6
    qg, vg = r.sol(r.t)
    assert np.abs(qg - r.q).max() <= 8 * EPS and np.abs(vg - r.v).max() <= 8 * EPS
    assert (r.sol.t_min, r.sol.t_max) == (pytest.approx(0, abs=1e-12), 7.0)
    with pytest.raises(InputError, match=r"defined on \[0, 7\]"):
        r.sol(7.5)
    with pytest.raises(InputError, match=r"defined on \[0, 7\]"):
        r.sol(-0.5)
    # a terminal event stops the backward run at its first crossing (the largest one)
    s = ldaspark.integrate(SK, "gauss-3", t_span=(7, 0), q0=q7, v0=v7, h=-0.05, engine=engine, events=stop)
    assert s.status == 1 and abs(s.t_events[0][0] - allx[0]) < 1e-6 and s.t[-1] < allx[0] < s.t[-2]


def test_the_compiled_engine_solves_only_the_steps_that_are_evaluated(monkeypatch):
    """Each step's stages are solved again (one kernel call, ~100 us) when the step is first
    evaluated: a 2000-step dense run costs the run, not 2000 solves; a pickled copy (process pools,
    save_result) carries every step's stages and gives the same numbers. Control: ``V`` of the
    original solves the rest."""
    import pickle
    from ldaspark.engines import compiled
    calls = []
    orig = compiled.SparkStages.__call__
    monkeypatch.setattr(compiled.SparkStages, "__call__", lambda self, *a: calls.append(1) or orig(self, *a))
    r = ldaspark.integrate("skate", "gauss-4", n_steps=2000, h=0.05, engine="compiled", dense_output=True)
    assert not calls
    q, v = r.sol(np.linspace(0.0, 0.5, 40))                # steps 0..10
    assert 1 <= len(calls) <= 11
    copy = pickle.loads(pickle.dumps(r.sol))
    assert len(calls) == 2000
    q2, v2 = copy(np.linspace(0.0, 0.5, 40))
    np.testing.assert_array_equal(q, q2)
    np.testing.assert_array_equal(v, v2)
    assert r.sol.V.shape == (2000, 4, 3) and len(calls) == 2000


# --- a run that the engines end differently after the event: L has sqrt(1.5 - t), so the step
# that reaches t = 1.5 is outside the domain of L (every engine fails there, status -3); a clock
# event g = t - 0.55 fires in step 5 (t 0.5 -> 0.6), long before
DIES = None


def _dies():
    global DIES
    if DIES is None:
        from ldaspark.core.system import LagrangianSystem
        DIES = LagrangianSystem("vx**2/2 + vy**2/2 + x*sqrt(1.5 - t)", ["vy - x*vx/10"], ["x", "y"], ["vx", "vy"],
                                name="dies at t = 1.5")
    return DIES


def _clock(at, terminal=True):
    g = lambda t, q, v: t - at       # noqa: E731
    g.terminal = terminal
    return g


#: every engine and path: generic float64 and mpmath, compiled with Newton and the quasi-Newton
#: iteration, compiled in blocks of 4 steps (the event in the second block, the failure in the fourth),
#: a comparator (the block engine of the comparators, post-processed as the compiled engine)
PATHS = {"generic": dict(engine="generic"), "mpmath": dict(engine="generic", dps=20),
         "compiled": dict(engine="compiled"), "quasi": dict(engine="compiled", newton="quasi"),
         "chunked": dict(engine="compiled", chunk=4),
         "comparator": dict(engine="generic", method="gauss-irk-2")}


def _run_path(monkeypatch, path, **kw):
    from ldaspark.core import chunks
    opts = dict(PATHS[path])
    monkeypatch.setattr(chunks, "COMPILED_CHUNK", opts.pop("chunk", chunks.COMPILED_CHUNK))
    return ldaspark.integrate(_dies(), opts.pop("method", "gauss-2"), t_span=(0, 3), h=0.1, q0=[0, 0], v0=[0, 0],
                              **opts, **kw)


@pytest.mark.parametrize("path", list(PATHS))
def test_a_terminal_event_ends_the_run_before_a_later_failure(monkeypatch, path):
    """The run ends at the terminal event (status 1, no error) on every engine: the stepping
    engine never takes the failing step. Before, the compiled engine (which runs the whole grid,
    then looks for events in the prefix before its failure) cut the trajectory at the event but
    kept the failure's status -3, message and error (of step 15, t = 1.5, past the end of the
    returned run), and raise_on_failure=True raised it; the generic engine said status 1."""
    r = _run_path(monkeypatch, path, events=_clock(0.55), raise_on_failure=True)
    assert (r.status, r.message, r.error) == (1, "A termination event occurred.", None), (r.status, r.message)
    assert r.success and r.stats["steps"] == 6 and float(r.t[-1]) == pytest.approx(0.6, abs=1e-15)
    # the clock g = t - 0.55 is linear in t: brentq's xtol 4 eps max(1, |t|) bounds the error
    assert len(r.t_events[0]) == 1 and abs(r.t_events[0][0] - 0.55) < 1e-14, r.t_events
    # control: without the event, the same run fails later (step 14 or 15: t_n + h and t0 + (n + 1) h
    # straddle t = 1.5 by an ulp); a non-terminal event keeps that failure, its crossing recorded
    f = _run_path(monkeypatch, path, events=_clock(0.55, terminal=False))
    assert f.status == -3 and f.error is not None and float(f.t[-1]) >= 1.4 - 1e-12
    assert abs(f.t_events[0][0] - 0.55) < 1e-14


@pytest.mark.parametrize("path", list(PATHS))
def test_the_dense_output_of_a_run_ended_by_a_terminal_event_ends_at_its_last_step(monkeypatch, path):
    """A block engine runs past a terminal event and the driver cuts the run at the event's step
    (``_post_process``): the dense output is built on the kept steps only, [t0, t_6] on every path,
    as the stepping engine's; one step more (t_7 on the comparator's cubic Hermite) went unseen,
    no test asked a cut run for its dense output's domain. Control: the same run without the event
    has its dense output up to its failure, further."""
    r = _run_path(monkeypatch, path, events=_clock(0.55), dense_output=True)
    assert r.status == 1 and len(r.t) == 7
    assert (r.sol.t_min, r.sol.t_max) == (float(r.t[0]), float(r.t[-1])), (r.sol.t_min, r.sol.t_max, r.t[-1])
    with pytest.raises(InputError, match="defined on"):
        r.sol(float(r.t[-1]) + 0.05)
    f = _run_path(monkeypatch, path, dense_output=True)
    assert f.status == -3 and f.sol.t_max == float(f.t[-1]) > float(r.t[-1]) + 0.5


@pytest.mark.parametrize("path", list(PATHS))
def test_events_of_a_run_that_fails_in_its_first_step(monkeypatch, path):
    """One (empty) array per event function on every engine when the first step fails (the run
    from t0 = 1.45: its first step reaches t = 1.55). Before, the compiled engine returned
    t_events = [] (no entry per event: t_events[0] an IndexError), the generic engine [array([])]
    per event; a terminal event does not hide the failure (it never fired)."""
    from ldaspark.core import chunks
    opts = dict(PATHS[path])
    monkeypatch.setattr(chunks, "COMPILED_CHUNK", opts.pop("chunk", chunks.COMPILED_CHUNK))
    r = ldaspark.integrate(_dies(), opts.pop("method", "gauss-2"), t0=1.45, n_steps=5, h=0.1, q0=[0, 0], v0=[0, 0],
                           events=[_clock(2.0), _clock(1.5, terminal=False)], dense_output=True, **opts)
    assert r.status == -3 and len(r.t) == 1 and r.sol is None
    for name in ("t_events", "q_events", "v_events"):
        got = getattr(r, name)
        assert len(got) == 2 and all(len(a) == 0 for a in got), (name, got)
    assert r.q_events[0].shape == (0, 2)


@pytest.mark.parametrize("path", ["generic", "mpmath", "compiled"])
def test_events_far_from_t_zero(path):
    """t0 = 1000, h = 0.05: the run's grid t0 + 2 h is one ulp (1.1e-13) above (t0 + h) + h, and
    the generic engine located an event of step 1 on a piece built on [t_1, t_1 + h], then asked
    it for g at the grid's t_2, outside by more than its slack (1e-12 of the step, 5e-14): every
    event crossing in such a step (every other step here) ended the run with InputError 'dense
    output is defined on [1000.05, 1000.1], got t outside it'. The compiled engine built its piece
    on [t_1, t_2] and was right."""
    t0, h = 1000.0, 0.05
    assert (t0 + h) + h < t0 + 2 * h           # the grid that made the generic piece miss its end
    clock = lambda t, q, v: t - (t0 + 1.5 * h)     # noqa: E731  (crosses in step 1)
    opts = dict(PATHS[path])
    r = ldaspark.integrate("particle", "gauss-2", t0=t0, n_steps=4, h=h, events=clock, dense_output=True, **opts)
    # g linear in t: brentq's xtol 4 eps max(1, |t|) = 9e-13 bounds the error
    assert r.status == 0 and len(r.t_events[0]) == 1 and abs(r.t_events[0][0] - (t0 + 1.5 * h)) < 1e-12
    # the state at the event is the dense output's there (the same piece of the same step)
    q, v = r.sol(r.t_events[0][0])
    assert np.abs(r.q_events[0][0] - q).max() <= 8 * EPS and np.abs(r.v_events[0][0] - v).max() <= 8 * EPS
    # control: a crossing in step 0, where (t0 + 0 h) + h is the grid's t_1, was located before too
    at0 = ldaspark.integrate("particle", "gauss-2", t0=t0, n_steps=4, h=h, events=lambda t, q, v: t - (t0 + 0.5 * h),
                             **opts)
    assert abs(at0.t_events[0][0] - (t0 + 0.5 * h)) < 1e-12


def test_the_compiled_engine_s_stages_are_the_kernel_s_one_step_solve(monkeypatch):
    """``SparkStages`` takes the SPARK kernel's one-step solve where its end point is the run's
    saved one, else the generic full-Newton step: two paths to the same root. The kernel's was
    never checked to be taken (comparing v_1 with q_1, it was refused at every step and the
    generic step solved them again, the same numbers). Control: with the kernel solver
    unavailable the generic step solves every evaluated step, and the dense output agrees."""
    from ldaspark.compiled import runner
    from ldaspark.core.errors import LdasparkError
    from ldaspark.core.guard import ROOT_AGREE
    from ldaspark.core.spark import SparkMethod
    ts = (np.arange(10) + 0.5) * 0.05                      # the midpoints of steps 0..9
    calls, real = [], SparkMethod.step
    monkeypatch.setattr(SparkMethod, "step", lambda self, *a, **kw: calls.append(1) or real(self, *a, **kw))
    r = ldaspark.integrate("skate", "gauss-4", n_steps=20, h=0.05, engine="compiled", dense_output=True)
    q, v = r.sol(ts)
    assert r.status == 0 and not calls

    def no_kernel(*a, **kw):
        raise LdasparkError("no stage kernel")
    monkeypatch.setattr(runner, "StageSolver", no_kernel)
    g = ldaspark.integrate("skate", "gauss-4", n_steps=20, h=0.05, engine="compiled", dense_output=True)
    qg, vg = g.sol(ts)
    assert len(calls) == 10
    # both V solve the same step to its end point within same_root's bound (ROOT_AGREE relative to
    # 1 + |state|, state ~ 1 on the skate); the interpolant is q0 + h sum b_i(theta) V_i with
    # sum |b_i| <= ~2 over a step: 4 ROOT_AGREE bounds the difference
    assert np.abs(q - qg).max() <= 4 * ROOT_AGREE and np.abs(v - vg).max() <= 4 * ROOT_AGREE
