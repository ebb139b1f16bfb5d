"""Rules of ``ldaspark.lab.reports.peers`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import math
import os
import sys
import types
from types import SimpleNamespace
import numpy as np
import pytest
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark.lab.reports import peers
import json
import pathlib
# --- lab/reports/peers.py ---------------------------------------------------------------------------
from ldaspark.lab.reports import peers as P  # noqa: E402
from scene_fakes import _Osc, _Scene
from run_helpers import two_line_error


# =============================================================================================
# peers: stand-ins
# =============================================================================================


def _f(t, y, W):
    return np.array([y[1], -y[0]])


def _fi(t, y, yp, W):
    yp[0], yp[1] = y[1], -y[0]


class _Mod:
    """A generated ODE module's interface for ``_Osc`` (what ``compiled_ode_module`` returns)."""
    HAS_CLOSED = True
    CLOSED_INFO = "stand-in"
    rhs_solve = rhs_closed = staticmethod(_f)
    rhs_into_solve = rhs_into_closed = staticmethod(_fi)

    @staticmethod
    def rhs(t, y):
        return _f(t, y, None)

    @staticmethod
    def psi_of(t, y):
        return np.array([7.0])

    @staticmethod
    def dae_residual(t, z, zp, res):
        res[0] = zp[0] - z[1]
        res[1] = zp[1] + z[0]
        res[2] = z[2] - 7.0


@pytest.fixture
def osc(monkeypatch):
    monkeypatch.setattr(peers, "_module", lambda system: _Mod)
    return _Osc()


Y0 = np.array([1.0, 0.0])


class _Clock:
    """A CPU clock that only the tasks advance (by their scripted costs)."""

    def __init__(self):
        self.now = 0.0

    def process_time(self):
        return self.now


@pytest.fixture
def clock(monkeypatch):
    c = _Clock()
    monkeypatch.setattr(peers, "time", c)
    return c


def _fake_cyrk(result):
    mod = types.ModuleType("CyRK")
    mod.calls = []

    def solver(name):
        def solve(fn, span, y0, **kw):
            mod.calls.append((name, span, kw))
            r = result()
            return SimpleNamespace(success=r[0], y=r[1], message=r[2])
        return solve
    mod.nbsolve_ivp, mod.pysolve_ivp = solver("nb"), solver("py")
    return mod


class _SkResult(SimpleNamespace):
    pass


def _fake_sundials(state):
    """scikit-sundae's CVODE and IDA: record the arguments, answer with rows numbered by output time
    (row i = [i, 10 i, 100 i, ...]) so that the rows and columns kept are visible."""
    sk = types.SimpleNamespace(made=[], solved=[])

    def result(tspan, width):
        rows = np.array([[i * 10.0 ** j for j in range(width)] for i in range(len(tspan))])
        t = tspan if state.get("complete", True) else tspan[:-1]
        return _SkResult(success=state.get("success", True), t=np.asarray(t), y=rows, nfev=33, message="gave up")

    class CVODE:
        def __init__(self, fn, **kw):
            sk.made.append(("cvode", kw))

        def solve(self, tspan, y0):
            sk.solved.append(("cvode", np.array(tspan), None))
            return result(tspan, len(y0))

    class IDA:
        def __init__(self, res, **kw):
            self.res = res
            sk.made.append(("ida", kw))

        def solve(self, tspan, z0, zp0):
            out = np.zeros(len(z0))
            self.res(tspan[0], z0, zp0, out)
            sk.solved.append(("ida", np.array(tspan), (np.array(z0), np.array(zp0), out.copy())))
            return result(tspan, len(z0))
    sk.cvode, sk.ida = SimpleNamespace(CVODE=CVODE), SimpleNamespace(IDA=IDA)
    return sk


# =============================================================================================
# peers: rows of a run
# =============================================================================================


def _spark_result(energy, q, k):
    return SimpleNamespace(energy=np.asarray(energy, float), q=np.asarray(q, float), constraint=np.asarray(k, float))


# =============================================================================================
# peers: the study
# =============================================================================================
def _row_of(kind, method, param, cpu, err):
    return {"kind": kind, "method": method, "param": param, "cpu": cpu, "q_final": [1.0 - err],
            "energy_error": err, "constraint": 0.0, "nfev": None}


@pytest.fixture
def study_env(monkeypatch):
    import ldaspark.models.scenes as scenes
    env = SimpleNamespace(batches=[], spark=[], peer=[])
    monkeypatch.setattr(scenes, "get_scene", lambda name: _Scene())
    monkeypatch.setattr(peers, "plan", lambda quick=False: {
        "t_end": 1.0, "t_long": 2.0, "n_out_long": 3,
        "hs": {m: (0.5, 0.25) for m in peers.SPARK_METHODS + peers.COMPARATORS},
        "hs_long": {m: (0.5,) for m in peers.SPARK_METHODS + peers.COMPARATORS},
        "rtols": (1e-3, 1e-6), "rtols_long": (1e-4,)})
    monkeypatch.setattr(peers, "sundials", lambda: None)
    monkeypatch.setattr(peers, "cyrk", lambda: object())
    monkeypatch.setattr(peers, "rhs_choice", lambda system, y0: {"form": "solve", "ns_per_call": {"solve": 1.0}})
    monkeypatch.setattr(peers, "reference_final", lambda sc, t_end: (np.array([1.0]), "ref", None))
    monkeypatch.setattr(peers, "_mechanical", lambda sc: True)

    def prepare_spark(sc, m, h, t_end, n_out=1, public=False):
        env.spark.append((m, h, t_end, n_out, public))
        if m == "gauss-3" and h == 0.25:
            raise LdasparkError("no point at this h")
        kind = "comparator" if m in peers.COMPARATORS else ("spark" if public else "spark-fast")
        err = h ** 4 * (2 if public else 1)
        return (lambda: None), (lambda cpu, out: _row_of(kind, m, h, 1.0 / h, err))

    def prepare_peer(sc, p, tol, t_end, n_out=1):
        env.peer.append((p, tol, t_end, n_out))
        if p == "ode-lsoda" and tol == 1e-6:
            raise peers.PeerFailure("lsoda refused")

        def go():
            if p == "cyrk-nbsolve2-Vern8":
                raise peers.PeerFailure("stopped")
        return go, (lambda cpu, out: _row_of("peer", p, tol, -math.log10(tol), tol * 10))
    monkeypatch.setattr(peers, "prepare_spark", prepare_spark)
    monkeypatch.setattr(peers, "prepare_peer", prepare_peer)
    real = peers.run_interleaved

    def ri(tasks, rounds=3, short=0.5, failed=None):
        env.batches.append(([t[0] for t in tasks], rounds))
        return real(tasks, rounds=1, short=short, failed=failed)
    monkeypatch.setattr(peers, "run_interleaved", ri)
    return env


# =============================================================================================
# peers: speed-ups recomputed, the section's words
# =============================================================================================
def _law(kind, method, c0, errors):
    return [{"kind": kind, "method": method, "param": e, "cpu": c0 * e ** -0.25, "error": e,
             "energy_error": e} for e in errors]


def _section_doc(**kw):
    d = {"command": "c", "date": "d", "cpu_count": 2, "load_average_1min_at_end": 2.0, "versions": {},
         "peers": {}, "atol": "a", "studies": []}
    d.update(kw)
    return "\n".join(peers.section(d))


# =============================================================================================
# peers: availability, the CPU clock, the interleaved rounds
# =============================================================================================
def test_optional_libraries_that_fail_to_import_are_none(monkeypatch):
    monkeypatch.setitem(sys.modules, "sksundae", None)      # import raises ImportError
    monkeypatch.setitem(sys.modules, "CyRK", None)
    assert peers.sundials() is None and peers.cyrk() is None
    ok, notes = peers.available_peers(("ode-dop853", "cvode-bdf", "cyrk-nbsolve2-Vern8", "ida"))
    assert ok == ["ode-dop853"]
    assert len(notes) == 2 and "cvode-bdf, ida" in notes[0] and "cyrk-nbsolve2-Vern8" in notes[1]
    # control: present modules are returned as they are
    fake = types.ModuleType("sksundae")
    monkeypatch.setitem(sys.modules, "sksundae", fake)
    assert peers.sundials() is fake


def test_cpu_min_is_the_minimum_and_long_runs_are_not_repeated(clock):
    costs = iter([0.25, 0.125, 0.5])
    calls = []

    def fn():
        clock.now += next(costs)
        calls.append(1)
        return len(calls)
    best, out = peers._cpu_min(fn, repeats=3, short=1.0)
    assert best == 0.125 and len(calls) == 3 and out == 3
    # a run longer than ``short`` ends the repeats; one exactly ``short`` long does not
    costs, calls[:] = iter([2.0, 0.5]), []
    assert peers._cpu_min(fn, repeats=3, short=1.0) == (2.0, 1)
    costs, calls[:] = iter([1.0, 0.5, 4.0]), []
    assert peers._cpu_min(fn, repeats=3, short=1.0) == (0.5, 3)


def _fake_task(clock, log, name, costs, out=lambda name, c: (name, c)):
    """(label, go, finish) of run_interleaved whose runs cost ``costs`` in turn on the fake clock,
    logging each run."""
    it = iter(costs)

    def go():
        c = next(it)
        clock.now += c
        log.append(name)
        return out(name, c)
    return (name, go, lambda cpu, o: {"method": name, "cpu": cpu, "out": o})


def test_interleaved_rounds_keep_each_runs_cheapest_round(clock):
    log = []

    def task(name, costs):
        return _fake_task(clock, log, name, costs)
    tasks = [task("a", [1.0, 0.5, 0.75]), task("b", [2.0]), task("c", [1.5, 1.25, 1.0]), task("d", [0.5, 3.0, 0.25])]
    rows = peers.run_interleaved(tasks, rounds=3, short=1.5)
    # b (2.0 > short) is not repeated; c (exactly short) is; each round runs the tasks in turn
    assert log == ["a", "b", "c", "d", "a", "c", "d", "a", "c", "d"]
    got = {r["method"]: (r["cpu"], r["out"]) for r in rows}
    assert got == {"a": (0.5, ("a", 0.5)), "b": (2.0, ("b", 2.0)), "c": (1.0, ("c", 1.0)), "d": (0.25, ("d", 0.25))}
    # a task dropped after its first round has no row; LdasparkError is dropped like PeerFailure
    n = {"k": 0}

    def flaky():
        n["k"] += 1
        clock.now += 0.25
        if n["k"] == 2:
            raise two_line_error(LdasparkError, "no point", "second line")
        return n["k"]
    failed = []
    rows = peers.run_interleaved([("f", flaky, lambda c, o: o), task("g", [0.5, 0.5])], rounds=2, short=1.0,
                                 failed=failed)
    assert rows == [{"method": "g", "cpu": 0.5, "out": ("g", 0.5)}] and failed == ["f: LdasparkError: no point"]
    # without a list for the failures they are dropped all the same
    n["k"] = 1
    rows = peers.run_interleaved([("f", flaky, lambda c, o: o), task("h", [0.5])], rounds=1, short=1.0)
    assert rows == [{"method": "h", "cpu": 0.5, "out": ("h", 0.5)}]



def test_interleaved_min_cpu_repeats_short_runs_within_a_round(clock):
    """min_cpu: a task runs again in its round until its runs there add up to min_cpu (every run a
    sample of the minimum), at most max_repeats times; a run at or above min_cpu runs once; a
    failure in a repeat drops the task. Negative control: without min_cpu, one run per round."""
    log = []

    def task(name, costs):
        return _fake_task(clock, log, name, costs, out=lambda name, c: c)
    rows = peers.run_interleaved([task("a", [0.25, 0.5, 0.125, 0.5, 0.5, 0.5]), task("b", [2.0, 2.0])], rounds=2,
                                 short=10.0, min_cpu=0.75)
    # round 1: a 0.25 + 0.5 (0.75 reached), b once; round 2: a 0.125 + 0.5 + 0.5, b once
    assert log == ["a", "a", "b", "a", "a", "a", "b"]
    assert {r["method"]: r["cpu"] for r in rows} == {"a": 0.125, "b": 2.0}
    log.clear()
    rows = peers.run_interleaved([task("c", [0.25] * 10)], rounds=2, short=10.0, min_cpu=100.0, max_repeats=3)
    assert log == ["c"] * 6 and rows[0]["cpu"] == 0.25
    log.clear()
    peers.run_interleaved([task("d", [0.25, 0.125, 0.5])], rounds=3, short=10.0)
    assert log == ["d"] * 3                              # the control: one run per round
    n = {"k": 0}

    def flaky():
        n["k"] += 1
        clock.now += 0.25
        if n["k"] == 3:
            raise LdasparkError("gone")
        return n["k"]
    failed = []
    rows = peers.run_interleaved([("f", flaky, lambda c, o: o)], rounds=2, short=10.0, failed=failed, min_cpu=1.0)
    assert rows == [] and failed == ["f: LdasparkError: gone"] and n["k"] == 3
    with pytest.raises(InputError):
        peers.run_interleaved([], min_cpu=-1.0)
    with pytest.raises(InputError):
        peers.run_interleaved([], max_repeats=0)

# =============================================================================================
# peers: the solvers' wiring (libraries replaced by recorders)
# =============================================================================================
def test_solve_ivp_peer_reports_its_failure(osc, monkeypatch):
    import scipy.integrate
    seen = {}

    def fake(f, span, y0, method, rtol, atol, t_eval, args):
        seen.update(span=span, method=method, rtol=rtol, atol=atol)
        return SimpleNamespace(status=seen["status"], message="too many steps", y=np.ones((2, len(t_eval))), nfev=17)
    monkeypatch.setattr(scipy.integrate, "solve_ivp", fake)
    go = peers.peer_solver(osc, "solve_ivp-DOP853", 1e-6, 0.0, Y0, [0.5, 2.0], form="solve")
    seen["status"] = -1
    with pytest.raises(peers.PeerFailure, match="too many steps"):
        go()
    seen["status"] = 0
    y, nfev = go()
    assert y.shape == (2, 2) and nfev == 17
    assert seen["span"] == (0.0, 2.0) and seen["method"] == "DOP853"
    assert seen["atol"] == peers.ATOL_FACTOR * seen["rtol"] and seen["rtol"] == 1e-6 and peers.ATOL_FACTOR == 1e-3


def test_ode_peer_solves_and_reports_a_stop(osc, monkeypatch):
    t = np.array([0.5, 1.0, 2.0])
    go = peers.peer_solver(osc, "ode-dop853", 1e-10, 0.0, Y0, t, form="closed")
    y, nfev = go()
    # DOP853 at rtol 1e-10 on the oscillator: error a modest multiple of the tolerance
    assert nfev is None and np.max(np.abs(y[:, 0] - np.cos(t))) <= 1e-7
    assert np.max(np.abs(y[:, 1] + np.sin(t))) <= 1e-7
    import scipy.integrate

    class Stops:
        def __init__(self, f):
            self.t, self.k = 0.0, 0

        def set_integrator(self, name, **kw):
            assert name == "lsoda"
            return self

        def set_initial_value(self, y0, t0):
            return self

        def set_f_params(self, W):
            return self

        def integrate(self, t):
            self.t, self.k = t, self.k + 1
            return np.zeros(2)

        def successful(self):
            return self.k < 2
    monkeypatch.setattr(scipy.integrate, "ode", Stops)
    go = peers.peer_solver(osc, "ode-lsoda", 1e-6, 0.0, Y0, t, form="solve")
    with pytest.raises(peers.PeerFailure, match="ode-lsoda failed at t = 1 "):
        go()


def test_unknown_peer_is_refused(osc, monkeypatch):
    # as with the bench extra installed (without it, the SUNDIALS check speaks first)
    monkeypatch.setattr(peers, "sundials", lambda: object())
    with pytest.raises(ValueError, match="unknown peer"):
        peers.peer_solver(osc, "rk4-by-hand", 1e-6, 0.0, Y0, [1.0], form="solve")


def test_form_defaults_to_the_measured_choice(osc, monkeypatch):
    used = []
    monkeypatch.setattr(peers, "rhs_choice", lambda system, y0: {"form": "closed"})
    monkeypatch.setattr(_Mod, "rhs_closed", staticmethod(lambda t, y, W: used.append("closed") or _f(t, y, W)))
    peers.peer_solver(osc, "solve_ivp-DOP853", 1e-6, 0.0, Y0, [1.0])
    assert used == ["closed"]


def test_cyrk_compiled_loop_peer_checks_success_and_the_output_count(osc, monkeypatch):
    monkeypatch.setattr(peers, "cyrk", lambda: object())
    monkeypatch.setattr(peers, "_cyrk_funcs", lambda system, mod, form: (SimpleNamespace(address=4242), None))
    calls, answer = [], {}

    def run(addr, t0, t1, y0, teval, rtol, atol, W, method):
        calls.append((addr, t0, t1, method, rtol, atol))
        return answer.get("ok", True), answer.get("out", np.zeros((len(teval), 2)))
    monkeypatch.setattr(peers, "_cyrk_driver", lambda: run)
    times = [1.0, 3.0]
    go = peers.peer_solver(osc, "cyrk-nbsolve2-Vern8", 1e-8, 0.5, Y0, times, form="solve")
    assert calls == [(4242, 0.5, 3.0, "Vern8", 1e-8, peers.ATOL_FACTOR * 1e-8)]          # the compile call, untimed
    out, nfev = go()
    assert out.shape == (2, 2) and nfev is None
    answer.update(ok=False)
    with pytest.raises(peers.PeerFailure):
        go()
    answer.update(ok=True, out=np.zeros((1, 2)))                      # stopped early: fewer rows
    with pytest.raises(peers.PeerFailure):
        go()


def test_cyrk_numba_and_python_loop_peers_check_success_and_the_output_count(osc, monkeypatch):
    state = {"r": (True, np.zeros((2, 2)), "ok")}
    fake = _fake_cyrk(lambda: state["r"])
    monkeypatch.setitem(sys.modules, "CyRK", fake)
    monkeypatch.setattr(peers, "cyrk", lambda: fake)
    dy = []
    monkeypatch.setattr(peers, "_cyrk_funcs", lambda system, mod, form: (None, lambda *a: dy.append(a)))
    for peer in ("cyrk-nbsolve-DOP853", "cyrk-pysolve-DOP853"):
        fake.calls.clear()
        state["r"] = (True, np.zeros((2, 2)), "ok")
        go = peers.peer_solver(osc, peer, 1e-6, 0.0, Y0, [1.0, 2.0], form="solve")
        assert len(fake.calls) == 1                                  # the untimed first call
        name, span, kw = fake.calls[0]
        assert span == (0.0, 2.0) and kw["rtol"] == 1e-6 and kw["atol"] == peers.ATOL_FACTOR * 1e-6
        if name == "nb":
            assert kw["rk_method"] == 2                              # CyRK's DOP853
        else:
            assert kw["method"] == "DOP853" and kw["pass_dy_as_arg"] and len(dy) == 1
        y, nfev = go()
        assert y.shape == (2, 2) and nfev is None
        state["r"] = (False, np.zeros((2, 2)), "step size underflow")
        with pytest.raises(peers.PeerFailure, match="step size underflow"):
            go()
        state["r"] = (True, np.zeros((2, 1)), "short")
        with pytest.raises(peers.PeerFailure, match="short"):
            go()


def test_cvode_peers_drop_the_added_output_time_and_report_failure(osc, monkeypatch):
    state = {}
    sk = _fake_sundials(state)
    monkeypatch.setattr(peers, "sundials", lambda: sk)
    monkeypatch.setattr(peers, "_cvode_func", lambda system, fi: (lambda t, y, yp, ud: fi(t, y, yp, ud[0])))
    # one output time: a midpoint is added (scikit-sundae would return every step) and dropped
    go = peers.peer_solver(osc, "cvode-adams", 1e-6, 1.0, Y0, [3.0], form="solve")
    y, nfev = go()
    kind, kw = sk.made[-1]
    assert kw["method"] == "Adams" and kw["rtol"] == 1e-6 and kw["atol"] == peers.ATOL_FACTOR * 1e-6
    assert np.array_equal(sk.solved[-1][1], [1.0, 2.0, 3.0])
    assert y.tolist() == [[2.0, 20.0]] and nfev == 33
    # several output times: t0 and the times, only t0 dropped
    go = peers.peer_solver(osc, "cvode-bdf", 1e-6, 0.0, Y0, [1.0, 2.0], form="solve")
    y, _ = go()
    assert sk.made[-1][1]["method"] == "BDF" and np.array_equal(sk.solved[-1][1], [0.0, 1.0, 2.0])
    assert y.tolist() == [[1.0, 10.0], [2.0, 20.0]]
    state["complete"] = False
    with pytest.raises(peers.PeerFailure, match="cvode-bdf: gave up"):
        go()
    state.update(complete=True, success=False)
    with pytest.raises(peers.PeerFailure):
        go()


def test_ida_peer_excludes_psi_from_the_error_test_and_returns_q_v_only(osc, monkeypatch):
    state = {}
    sk = _fake_sundials(state)
    monkeypatch.setattr(peers, "sundials", lambda: sk)
    go = peers.peer_solver(osc, "ida", 1e-6, 0.0, Y0, [1.0, 2.0], form="solve")
    # the warm-up solve (compiles the residual's other layouts) runs inside (t0, t_end), untimed
    (_, warm_kw), = sk.made
    warm_t = sk.solved[0][1]
    assert warm_kw["rtol"] == 1e-3 and len(warm_t) == 3 and warm_t[0] == 0.0 and 0 < warm_t[1] < warm_t[2] < 2.0
    y, nfev = go()
    kind, kw = sk.made[-1]
    assert kw["rtol"] == 1e-6 and kw["algebraic_idx"] == [2]
    atol = np.asarray(kw["atol"])
    assert atol.tolist()[:2] == [peers.ATOL_FACTOR * 1e-6] * 2 and atol[2] >= 1e20         # psi: no error test
    z0, zp0, res = sk.solved[-1][2]
    assert z0.tolist() == [1.0, 0.0, 7.0] and zp0.tolist() == [0.0, -1.0, 0.0]
    assert np.max(np.abs(res)) == 0.0                                     # consistent start
    assert y.tolist() == [[1.0, 10.0], [2.0, 20.0]] and nfev == 33       # rows after t0, columns q, v
    state["success"] = False
    with pytest.raises(peers.PeerFailure, match="ida: gave up"):
        go()
    # the untimed warm-up integrates a short stretch of the run itself, never past its end
    sk.made.clear(), sk.solved.clear()
    peers.peer_solver(osc, "ida", 1e-6, 1.0, Y0, [1.01], form="solve")
    (_, tspan, _), = sk.solved
    assert tspan[0] == 1.0 and all(1.0 < x <= 1.01 for x in tspan[1:])


def test_peer_row_has_the_largest_energy_and_constraint_errors_over_the_output_times(monkeypatch, clock):
    seen = {}

    def solver(system, peer, rtol, t0, y0, times, form=None):
        seen.update(t0=t0, y0=y0, times=np.asarray(times), form=form)
        ys = np.array([[1.0, 0.5], [0.5, 1.0], [2.0, 0.25]])          # E - E0: 0.125, 0.125, 1.53125

        def go():
            clock.now += 0.5
            return ys, 9
        return go
    monkeypatch.setattr(peers, "peer_solver", solver)
    r = peers.run_peer(_Scene(t0=1.0), "ode-dop853", 1e-6, 4.0, n_out=3, repeats=2, form="closed")
    assert np.array_equal(seen["times"], [2.0, 3.0, 4.0]) and seen["t0"] == 1.0 and seen["form"] == "closed"
    assert seen["y0"].tolist() == [1.0, 0.0]
    assert r["cpu"] == 0.5 and r["nfev"] == 9 and r["q_final"] == [2.0] and r["param"] == 1e-6
    assert r["kind"] == "peer" and r["method"] == "ode-dop853"
    assert r["energy_error"] == 1.53125 and r["constraint"] == 0.75      # max |v - 1| over the times


def test_spark_runs_public_internal_and_comparator(monkeypatch, clock):
    import ldaspark.compiled.fast as fast
    import ldaspark.solve  # noqa: F401
    solve = sys.modules["ldaspark.solve"]
    calls = []

    def fast_integrate(scene, method, h, n_steps, every=None):
        calls.append(("fast", method, h, n_steps, every))
        return _spark_result([1.0, 1.5, 0.25], [[0.0], [3.0]], [-3.0, 1.0])

    def integrate(scene, method, h, n_steps, engine, save_every=None):
        assert engine == "compiled"
        calls.append(("public", method, h, n_steps, save_every))
        return _spark_result([2.0, 2.0], [[5.0]], [0.0])
    monkeypatch.setattr(fast, "fast_integrate", fast_integrate)
    monkeypatch.setattr(solve, "integrate", integrate)
    sc = _Scene(t0=0.5)
    # T from 0.5 to 2.5 with h = 0.25: 8 steps, sampled every 8 // 3 = 2
    go, fin = peers.prepare_spark(sc, "gauss-2", 0.25, 2.5, n_out=3)
    assert calls == [("fast", "gauss-2", 0.25, 2, None)]
    r = fin(1.5, go())
    assert calls[-1] == ("fast", "gauss-2", 0.25, 8, 2)
    assert r["kind"] == "spark-fast" and r["energy_error"] == 0.75 and r["constraint"] == 3.0
    assert r["q_final"] == [3.0] and r["param"] == 0.25 and r["cpu"] == 1.5 and r["nfev"] is None
    calls.clear()
    go, fin = peers.prepare_spark(sc, "gauss-2", 0.25, 2.5, n_out=100, public=True)
    assert fin(1.0, go())["kind"] == "spark" and calls == [("public", "gauss-2", 0.25, 2, None),
                                                            ("public", "gauss-2", 0.25, 8, 1)]
    go, fin = peers.prepare_spark(sc, peers.COMPARATORS[0], 0.25, 2.5, public=True)
    assert fin(1.0, go())["kind"] == "comparator"
    clock_costs = iter([0.5, 0.25, 2.0])

    def tick(*a, **k):
        clock.now += next(clock_costs)
        return _spark_result([1.0, 1.0], [[1.0]], [0.0])
    monkeypatch.setattr(fast, "fast_integrate", tick)
    monkeypatch.setattr(peers, "_cpu_min", lambda go, repeats: (repeats, go()))
    assert peers.run_spark(sc, "gauss-4", 0.25, 2.5, repeats=7)["cpu"] == 7.0


def test_reference_is_the_closed_form_or_gauss4_checked_by_dop853(monkeypatch):
    q, label, chk = peers.reference_final(_Scene(exact=object()), 2.0)
    assert np.allclose(q, [np.cos(2.0)], rtol=0, atol=0) and label == "closed-form solution" and chk is None
    import ldaspark.compiled.fast as fast
    seen = {}

    def fi(scene, method, h, n_steps, every):
        seen.update(method=method, h=h, n=n_steps)
        return SimpleNamespace(q=np.array([[0.0, 0.0], [1.0, -2.0]]))
    monkeypatch.setattr(fast, "fast_integrate", fi)
    monkeypatch.setattr(peers, "run_peer", lambda sc, p, tol, t_end, repeats: {"q_final": [1.25, -2.5]})
    q, label, chk = peers.reference_final(_Scene(t0=1.0), 3.0)
    assert seen == {"method": "gauss-4", "h": 0.005, "n": 400}
    assert q.tolist() == [1.0, -2.0] and "gauss-4" in label and chk == 0.5


def test_the_study_plan_is_the_one_the_section_describes():
    # section(): "final error ... at t = 100", "energy error ... over t in [0, 1e4]"
    P, Q = peers.plan(), peers.plan(quick=True)
    assert P["t_end"] == 100.0 and P["t_long"] == 1e4
    assert Q["t_end"] < P["t_end"] and Q["t_long"] < P["t_long"] and Q["n_out_long"] < P["n_out_long"]
    every = set(peers.SPARK_METHODS + peers.COMPARATORS)
    for p in (P, Q):
        assert set(p["hs"]) == every and set(p["hs_long"]) == every
        assert all(h > 0 for hs in p["hs"].values() for h in hs) and all(list(r) == sorted(r, reverse=True)
                                                                          for r in (p["rtols"], p["rtols_long"]))
        # every run is a whole number of steps
        assert all(abs(p["t_end"] / h - round(p["t_end"] / h)) <= 1e-9 for hs in p["hs"].values() for h in hs)
    assert P["hs"]["lobatto-iiia-iiib-2"] == peers.SEMI_HS and P["hs_long"][peers.COMPARATORS[0]] == peers.SEMI_HS_LONG


def test_scene_study_interleaves_spark_and_peers_and_compares_at_equal_error(study_env):
    ps = ("ode-dop853", "ode-lsoda", "cvode-bdf", "cyrk-nbsolve2-Vern8", "solve_ivp-DOP853")
    st = peers.scene_study("skate", peers=ps, progress=lambda s: None, rounds=3)
    (labels, rounds), (long_labels, long_rounds) = study_env.batches
    assert rounds == 3 and long_rounds == 2
    # SPARK and peer tasks alternate from the first
    assert all(("rtol" in lab) == (i % 2 == 1) for i, lab in enumerate(labels[:14]))
    assert len(labels) == 23 and all("rtol" not in lab for lab in labels[14:])    # the 7 peers ran out first
    # every SPARK method and step, public and internal (comparators internal only), minus the failure
    n_spark = len(peers.SPARK_METHODS) * 2 * 2 + len(peers.COMPARATORS) * 2 - 2
    assert sum("rtol" not in lab for lab in labels) == n_spark
    assert ["cvode-bdf" in lab for lab in labels].count(True) == 0 and st["peers"] == [p for p in ps if p != "cvode-bdf"]
    assert any("scikit-sundae" in n for n in st["notes"])
    assert any(x.startswith("gauss-3 (integrate) h = 0.25 (T = 1): LdasparkError") for x in st["failed"])
    assert any(x.startswith("ode-lsoda rtol 1e-06 (T = 1): lsoda refused") for x in st["failed"])
    assert any(x.startswith("cyrk-nbsolve2-Vern8 rtol 0.001 (T = 1): PeerFailure: stopped") for x in st["failed"])
    # the long runs: the long peers only, their tolerances and output times
    assert {p for p, tol, T, n in study_env.peer if T == 2.0} == {"ode-dop853", "ode-lsoda", "cyrk-nbsolve2-Vern8"}
    assert all(n == 3 for p, tol, T, n in study_env.peer if T == 2.0)
    assert all(n == 3 for *_, T, n, pub in study_env.spark if T == 2.0)
    # the final-error runs (T = 1 here) need q at t_end only: one output time
    assert all(n == 1 for p, tol, T, n in study_env.peer if T == 1.0)
    assert all(n == 1 for *_, T, n, pub in study_env.spark if T == 1.0)
    # the final error is max |q_final - q_ref| (q_ref = 1, q_final = 1 - err)
    for r in st["rows"]:
        assert "q_final" not in r and abs(r["error"] - r["energy_error"]) <= 1e-15
    assert all("q_final" not in r and "error" not in r for r in st["long_rows"]) and st["long_rows"]
    assert st["speedups"] == peers.speedups(st["rows"], peers.TARGETS)
    assert st["comparators"] == peers.speedups(st["rows"], peers.TARGETS, other="comparator", spark="spark-fast")
    assert st["long_speedups_fast"] == peers.speedups(st["long_rows"], peers.ENERGY_TARGETS, key="energy_error",
                                                      spark="spark-fast")
    assert "t_vlong" not in st and st["rhs"]["form"] == "solve" and st["reference"] == "ref"
    assert st["t_end"] == 1.0 and st["t_long"] == 2.0 and (st["n"], st["m"]) == (1, 1)


def test_scene_study_very_long_runs_the_strongest_only(study_env):
    st = peers.scene_study("skate", peers=("ode-dop853", "cyrk-nbsolve2-DOP853"), progress=lambda s: None,
                           rounds=1, very_long=True)
    assert [r for _, r in study_env.batches] == [1, 1, 1]
    assert st["t_vlong"] == 20.0
    vl = [(m, h) for m, h, T, n, pub in study_env.spark if T == 20.0]
    assert sorted(set(vl)) == sorted((m, h) for m, hs in peers.VLONG_METHODS.items() for h in hs)
    assert {(p, tol) for p, tol, T, n in study_env.peer if T == 20.0} == {("cyrk-nbsolve2-DOP853", t)
                                                                           for t in peers.VLONG_RTOLS}
    assert st["vlong_rows"] and all("q_final" not in r for r in st["vlong_rows"])
    assert st["vlong_speedups"] == peers.speedups(st["vlong_rows"], peers.ENERGY_TARGETS, key="energy_error")
    assert "vlong_speedups_fast" in st


def test_run_study_saves_each_scene_and_records_the_load(monkeypatch):
    loads = iter([1.234, 5.0, 6.0, 5.678])          # start, after each scene, end
    monkeypatch.setattr(os, "getloadavg", lambda: (next(loads), 0.0, 0.0))
    monkeypatch.setattr(peers, "scene_study", lambda s, quick, peers, progress, rounds, very_long:
                        {"scene": s, "very_long": very_long, "rounds": rounds})
    monkeypatch.setattr(peers, "sundials", lambda: SimpleNamespace(__version__="s"))
    monkeypatch.setattr(peers, "cyrk", lambda: SimpleNamespace(__version__="c"))
    saved = []
    d = peers.run_study(scenes=("a", "b"), quick=True, peers=("ode-dop853",), progress=lambda s: None,
                        on_scene=lambda x: saved.append([s["scene"] for s in x["studies"]]), rounds=2,
                        very_long=("b",))
    assert saved == [["a"], ["a", "b"]]
    assert [s["very_long"] for s in d["studies"]] == [False, True]
    assert d["load_average_1min_at_start"] == 1.23 and d["load_average_1min_at_end"] == 5.68
    assert d["command"] == "python benchmarks/peers.py --quick --rounds 2 --very-long b"
    assert d["peers"] == {"ode-dop853": peers.PEERS["ode-dop853"]} and d["rounds"] == 2
    monkeypatch.setattr(os, "getloadavg", lambda: (0.5, 0.0, 0.0))
    d2 = peers.run_study(scenes=("a", "b", "c"), progress=lambda s: None)       # no on_scene: only the end
    assert [s["scene"] for s in d2["studies"]] == ["a", "b", "c"] and d2["command"] == "python benchmarks/peers.py"
    d3 = peers._study_dict([], False, None, SimpleNamespace(cpu=1.26), rounds=3)
    assert d3["command"] == "python benchmarks/peers.py" and d3["peers"] == peers.PEERS and d3["cpu_seconds"] == 1.3
    assert d3["load_average_1min_at_start"] is None and d3["load_average_1min_at_end"] == 0.5


def test_recompute_speedups_from_the_stored_rows():
    e = [10.0 ** -k for k in range(1, 10)]
    rows = _law("spark", "gauss-2", 1e-3, e) + _law("peer", "p", 4e-3, e)
    st1 = {"rows": rows, "long_rows": rows, "speedups": None, "long_speedups": None}
    st2 = {"rows": rows + _law("spark-fast", "gauss-2", 2e-3, e), "long_rows": rows, "speedups": None,
           "long_speedups": None}
    d = {"targets": [1e-3], "energy_targets": [1e-6], "studies": [st1, st2]}
    assert "recomputed" not in peers.recompute_speedups(d)
    assert abs(st1["speedups"][0]["speedup"] - 4.0) <= 1e-12 and abs(st1["long_speedups"][0]["speedup"] - 4.0) <= 1e-12
    assert st1["long_speedups"][0]["target"] == 1e-6
    assert "speedups_fast" not in st1 and abs(st2["speedups_fast"][0]["speedup"] - 2.0) <= 1e-12
    assert st2["long_speedups_fast"][0]["spark"] is None                 # no spark-fast long rows
    assert peers.recompute_speedups(d, note="today")["recomputed"] == "today"


def test_section_load_and_recomputed_notes():
    assert "a loaded machine" not in _section_doc()                            # load == CPUs: not loaded
    assert "a loaded machine" in _section_doc(load_average_1min_at_end=2.01)
    assert "a loaded machine" in _section_doc(cpu_count=None, load_average_1min_at_end=1.5)
    assert "a loaded machine" not in _section_doc(cpu_count=None, load_average_1min_at_end=0.5)   # as 1 CPU
    assert "a loaded machine" not in _section_doc(load_average_1min_at_end=None)
    assert "Speed-ups recomputed from the stored runs: x." in _section_doc(recomputed="x")
    assert "recomputed" not in _section_doc()
    assert "0.5 at the start" in _section_doc(load_average_1min_at_start=0.5)
    assert peers._x(10.0) == "10x" and peers._x(9.5) == "9.50x" and peers._x(None, at_most=2.0) == "<= 2.00x"
    assert peers._s(0.0123) == "12.3 ms" and peers._s(None) == "-"


def test_section_renders_every_part_of_a_study():
    sp = {"target": 1e-3, "spark": "gauss-2", "spark_cpu": 0.004, "peer": "ode-dop853", "peer_cpu": 0.008,
          "speedup": 2.0}
    fast = dict(sp, spark="gauss-4", spark_cpu=0.002, speedup=None, speedup_at_least=4.0)
    row = {"kind": "peer", "method": "ode-dop853", "param": 1e-6, "cpu": 0.5, "error": 1e-7, "energy_error": 1e-8,
           "constraint": 1e-15, "nfev": 120}
    lrow = dict(row, kind="spark-fast", method="gauss-4", nfev=None)
    st = {"scene": "skate", "n": 3, "t_end": 100.0, "t_long": 1e4, "t_vlong": 1e5, "reference": "gauss-4",
          "reference_check": 2.5e-12, "notes": ["a note"], "failed": ["x failed"], "rows": [row], "long_rows": [lrow],
          "vlong_rows": [lrow], "speedups": [sp], "speedups_fast": [fast], "long_speedups": [sp],
          "vlong_speedups": [dict(sp, speedup=30.0)], "vlong_speedups_fast": None,
          "rhs": {"form": "closed", "ns_per_call": {"solve": 80.0, "closed": 45.5}},
          "comparators": [dict(sp, peer="mp-lobatto-iiib-a-2", speedup=0.5), dict(sp, peer=None)],
          "long_comparators": None}
    text = _section_doc(studies=[st], peers={"ode-dop853": "Fortran"})
    assert "| skate (n = 3) | final error, T = 100 | 1e-03 | gauss-2 4 ms | ode-dop853 8 ms | 2.00x | gauss-4 2 ms: >= 4.00x |" in text
    assert "| skate (n = 3) | energy error, T = 100000 | 1e-03 | gauss-2 4 ms | ode-dop853 8 ms | 30x | - |" in text
    assert "skate: closed (solve 80 ns, closed 45.5 ns per call)" in text and "(the faster, measured per scene" in text
    assert "| skate (n = 3) | final error, T = 100 | 1e-03 | gauss-2 4 ms | mp-lobatto-iiib-a-2 8 ms | 0.50x |" in text
    assert text.count("mp-lobatto-iiib-a-2") == 1                         # the comparator row without a peer is left out
    assert "differs from ode('dop853') rtol 1e-13 by 2.5e-12" in text and "- a note\n- x failed" in text
    assert "| T = 100 | ode-dop853 | 1e-06 | 0.5 | 1.00e-07 | 1.00e-08 | 1.0e-15 | 120 |" in text
    assert "| T = 100000 | gauss-4 (fast path) | 1e-06 | 0.5 | - | 1.00e-08 | 1.0e-15 | - |" in text
    assert "- `ode-dop853`: Fortran" in text
    bare = _section_doc(studies=[dict(st, rhs=None, comparators=None, t_vlong=None, vlong_rows=[], reference_check=None)])
    assert "per call" not in bare and "McLachlan" not in bare and "differs from" not in bare and "T = 100000" not in bare
    assert "(the faster, measured per scene" in bare                     # the key is there, empty


ROOT = pathlib.Path(__file__).resolve().parents[3]


class _Clock_2:
    """time.process_time stand-in: returns the given instants in turn."""

    def __init__(self, instants):
        self.instants = list(instants)

    def process_time(self):
        return self.instants.pop(0)


def test_cpu_min_takes_the_fastest_repeat(monkeypatch):
    # repeats of 0.3, 0.1, 0.2 s
    monkeypatch.setattr(P, "time", _Clock_2([0.0, 0.3, 1.0, 1.1, 2.0, 2.2]))
    best, out = P._cpu_min(lambda: "r", repeats=3, short=0.5)
    assert best == pytest.approx(0.1)
    assert out == "r"


def test_time_rhs_takes_the_fastest_repeat(monkeypatch):
    pytest.importorskip("numba")
    import numba

    @numba.njit
    def g(t, y, yp, W):
        yp[-1] = t

    monkeypatch.setattr(P, "time", _Clock_2([0.0, 3.0, 10.0, 11.0, 20.0, 22.0]))
    ns = P._time_rhs(g, np.zeros(2), np.zeros(1), calls=1000, repeats=3)
    assert ns == pytest.approx(1.0 / 1000 * 1e9)


def test_rhs_choice_takes_the_faster_form(monkeypatch):
    system = types.SimpleNamespace(name="kills-a-fake", n=1, m=1)
    mod = types.SimpleNamespace(HAS_CLOSED=True, CLOSED_INFO={}, rhs_into_solve="solve", rhs_into_closed="closed")
    monkeypatch.setattr(P, "_module", lambda s: mod)
    monkeypatch.setattr(P, "_RHS_CHOICE", {})
    monkeypatch.setattr(P, "_time_rhs", lambda g, y, W: {"solve": 80.0, "closed": 30.0}[g])
    out = P.rhs_choice(system, [0.0, 0.0])
    assert out["form"] == "closed"
    assert out["ns_per_call"] == {"solve": 80.0, "closed": 30.0}


def test_peer_section_names_the_rhs_choice_when_any_study_measured_it():
    d = json.loads((ROOT / "reports" / "peers.json").read_text())
    with_rhs = [i for i, st in enumerate(d["studies"]) if "rhs" in st]
    assert len(d["studies"]) >= 2 and with_rhs
    for i, st in enumerate(d["studies"]):
        if i != with_rhs[0]:
            st.pop("rhs", None)                 # one study measured the choice, the others not
    text = "\n".join(P.section(d))
    assert "the faster, measured per scene, of the closed form" in text
    for st in d["studies"]:
        st.pop("rhs", None)
    assert "the faster, measured per scene, of the closed form" not in "\n".join(P.section(d))


def _close(x, rel=1e-9, abs=0.0):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny residuals."""
    return pytest.approx(x, rel=rel, abs=abs)


def _cost_rows(kind, method, pairs):
    return [{"kind": kind, "method": method, "error": e, "cpu": c} for e, c in pairs]


def test_the_speedup_is_peer_cost_over_spark_cost():
    from ldaspark.lab.reports import peers
    # SPARK reaches 1e-6 at 1 s, the peer at 4 s (both bracket the target, log-interpolated on the envelope)
    rows = (_cost_rows("spark", "s1", [(1e-4, 0.5), (1e-8, 2.0)]) + _cost_rows("spark", "s2", [(1e-4, 3.0), (1e-8, 9.0)])
            + _cost_rows("peer", "p1", [(1e-4, 2.0), (1e-8, 8.0)]) + _cost_rows("peer", "p2", [(1e-4, 7.0), (1e-8, 30.0)]))
    (r,) = peers.speedups(rows, [1e-6])
    assert r["spark"] == "s1" and r["peer"] == "p1"                   # the cheapest of each side
    assert r["speedup"] == _close(r["peer_cpu"] / r["spark_cpu"]) and r["speedup"] > 1
    assert r["speedup"] == _close(4.0, rel=1e-9)
    # the sides swapped: the reciprocal
    sw = [dict(x, kind={"spark": "peer", "peer": "spark"}[x["kind"]]) for x in rows]
    assert peers.speedups(sw, [1e-6])[0]["speedup"] == _close(0.25, rel=1e-9)
