"""The engine protocol (``ldaspark.engines``): ``ldaspark.integrate`` reaches every engine only
through ``ENGINES`` and the ``Engine`` interface, and the driver (``ldaspark.solve``), not the
engine, applies save_every, chunking, events, dense output, the energy monitor and the
step-acceptance guard. A fake engine registered here is driven like the real ones; a misbehaving
one (a wrong root at one step) is caught by the driver."""
import numpy as np
import pytest

import ldaspark
from ldaspark.core.errors import InputError
from ldaspark.engines import ENGINES, Engine, get_engine, register
from ldaspark.engines.generic import GenericEngine

RUN = dict(t_span=(0, 1.2), h=0.1)          # 12 steps of the skate


class StepsAsBlocks(GenericEngine):
    """A block engine built on the generic engine's steps: returns every step (``samples`` False),
    or keeps every ``every``-th sample itself (``samples`` True); records the blocks asked for.
    ``corrupt``: the step whose end state it replaces by a wrong root (v1 scaled)."""

    name = "fake"
    mode = "block"

    def __init__(self, samples=False, chunked=False, corrupt=None):
        self.samples, self.chunked, self.corrupt = samples, chunked, corrupt
        self.blocks = []

    def run(self, prep, start, n_steps, every):
        from ldaspark.core.backend import Backend
        from ldaspark.core.result import Result, save_indices
        self.blocks.append((n_steps, every))
        before = GenericEngine.stats(self, prep)
        t0, q, v = start
        bk, system, h = Backend(None), prep.system, float(prep.prob.h)
        T, Q, V = [float(t0)], [np.asarray(q, float)], [np.asarray(v, float)]
        for st in GenericEngine.steps(self, prep, start, n_steps):
            q1, v1 = np.asarray(st.q1, float), np.asarray(st.v1, float)
            if st.index == self.corrupt:
                v1 = 3.0 * v1             # another "root" (k is linear in v: still k = 0), energy x 9
            T.append(float(t0) + (st.index + 1) * h)
            Q.append(q1)
            V.append(v1)
        idx = save_indices(len(T) - 1, every) if self.samples else np.arange(len(T))
        T, Q, V = np.array(T)[idx], np.array(Q)[idx], np.array(V)[idx]
        E = np.array([float(system.energy(bk, t, a, b)) for t, a, b in zip(T, Q, V)])
        K = np.array([system.constraint(bk, t, a, b) for t, a, b in zip(T, Q, V)], float).reshape(len(T), system.m)
        # this block's counters (the method object's are cumulative over the blocks)
        after = GenericEngine.stats(self, prep)
        st = {c: after[c] - before.get(c, 0) for c in ("steps", "nfev", "njev", "nlu", "newton_iterations")}
        st["path"] = "fake"
        return Result(T, Q, V, E, K, None, 0, "done", st["nfev"], st["njev"], st["nlu"], st["newton_iterations"],
                      engine=self.label, stats=st)


def _with(monkeypatch, engine):
    monkeypatch.setitem(ENGINES, "generic", engine)      # what integrate(engine="generic") runs
    return engine


def test_every_registered_engine_is_an_engine_and_the_registry_refuses_others():
    assert {"generic", "compiled", "comparator"} <= set(ENGINES)
    for name, eng in ENGINES.items():
        assert isinstance(eng, Engine) and eng.name == name and eng.mode in ("steps", "block")
        assert get_engine(name) is eng
    with pytest.raises(TypeError):
        register(object())               # negative control: not an Engine
    with pytest.raises(InputError, match="unknown engine"):
        get_engine("warp")


def test_the_driver_slices_save_every_for_an_engine_that_returns_every_step(monkeypatch):
    ref = ldaspark.integrate("skate", "gauss-2", engine="generic", save_every=5, **RUN)
    fake = _with(monkeypatch, StepsAsBlocks())
    res = ldaspark.integrate("skate", "gauss-2", engine="generic", save_every=5, **RUN)
    assert fake.blocks == [(12, 1)]                          # asked for every step ...
    assert list(np.round(res.t / 0.1).astype(int)) == [0, 5, 10, 12]    # ... and sliced by the driver
    # the same steps (the generic engine's, same predictor): the same numbers, bit for bit
    assert np.array_equal(res.q, ref.q) and np.array_equal(res.v, ref.v)
    assert res.stats["path"] == "fake" and res.stats["guard"] is True


def test_the_driver_chunks_a_chunked_engine_and_keeps_the_samples(monkeypatch):
    whole = _with(monkeypatch, StepsAsBlocks(samples=True, chunked=True))
    one = ldaspark.integrate("skate", "gauss-2", engine="generic", save_every=3, **RUN)
    # negative control: a short run is one block; then the driver's guard judges the first saved
    # interval on a rerun of its 3 steps with every step kept (the guard is the driver's)
    assert whole.blocks == [(12, 3), (3, 1)]
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", 4)
    cut = _with(monkeypatch, StepsAsBlocks(samples=True, chunked=True))
    res = ldaspark.integrate("skate", "gauss-2", engine="generic", save_every=3, guard=False, **RUN)
    assert len(cut.blocks) == 4 and all(n <= 4 for n, _ in cut.blocks), cut.blocks
    assert list(np.round(res.t / 0.1).astype(int)) == list(np.round(one.t / 0.1).astype(int)) == [0, 3, 6, 9, 12]
    # the predictor restarts at a block boundary: agreement to the Newton tolerance (10 eps
    # relative per step, 12 steps of an O(1) solution)
    np.testing.assert_allclose(res.q, one.q, rtol=0, atol=1e-12)
    assert res.stats["steps"] == one.stats["steps"] == 12


def test_the_driver_locates_events_and_builds_dense_output_for_a_block_engine(monkeypatch):
    _with(monkeypatch, StepsAsBlocks())
    x_end = ldaspark.integrate("skate", "gauss-2", engine="generic", **RUN).q[-1, 0]
    g = lambda t, q, v: q[0] - 0.5 * x_end              # noqa: E731  (crossed once on the way)
    g.terminal = True
    res = ldaspark.integrate("skate", "gauss-2", engine="generic", events=g, dense_output=True, **RUN)
    assert res.status == 1 and len(res.t_events[0]) == 1
    te = res.t_events[0][0]
    assert 0 < te < res.t[-1] <= 1.2
    q_e, _ = res.sol(te)
    assert abs(g(te, q_e, None)) < 1e-9                 # the zero of g on the driver's dense output
    q_grid, _ = res.sol(res.t[1])
    np.testing.assert_allclose(q_grid, res.q[1], rtol=0, atol=1e-14)   # Hermite: exact at the nodes


def test_a_misbehaving_engine_is_caught_by_the_drivers_guard(monkeypatch):
    """Negative control: a block engine that hands back another root at step 7 (v1 tripled, so the
    energy jumps) is stopped by the driver's guard with status -4 naming step 7; with the guard
    off the driver's energy monitor catches it (status -3); with both off the wrong step passes
    (what the monitors prevent)."""
    _with(monkeypatch, StepsAsBlocks(corrupt=7))
    res = ldaspark.integrate("skate", "gauss-2", engine="generic", **RUN)
    assert res.status == -4 and "step 7" in res.message and len(res.t) == 8
    assert res.stats["guard_flagged"] >= 1
    jump = ldaspark.integrate("skate", "gauss-2", engine="generic", guard=False, energy_jump=0.5, **RUN)
    assert jump.status == -3 and "step 7" in jump.message and len(jump.t) == 8
    blind = ldaspark.integrate("skate", "gauss-2", engine="generic", guard=False, **RUN)
    assert blind.status == 0 and len(blind.t) == 13      # without the monitors the wrong step passes


def test_the_real_engines_are_reached_through_the_protocol(monkeypatch):
    """integrate -> the driver -> Engine.prepare and Engine.steps / Engine.run of the registered
    engine of each path (generic, mpmath generic, comparator, compiled)."""
    calls = []
    for name in ("generic", "comparator", "compiled"):
        eng = ENGINES[name]
        for meth in ("prepare", "steps", "run"):
            real = getattr(eng, meth)

            def spy(*a, _n=name, _m=meth, _r=real, **k):
                calls.append((_n, _m))
                return _r(*a, **k)
            # in the instance's __dict__, removed at teardown (setattr's undo would leave the old bound
            # method there, hiding a later class-level patch of the engine from every later test)
            monkeypatch.setitem(vars(eng), meth, spy)
    cases = [(dict(method="gauss-2", engine="generic"), ("generic", "steps")),
             (dict(method="gauss-2", engine="generic", dps=20), ("generic", "steps")),
             (dict(method="gauss-irk-2", engine="generic"), ("comparator", "run")),
             (dict(method="gauss-2", engine="compiled"), ("compiled", "run"))]
    for kw, want in cases:
        calls.clear()
        res = ldaspark.integrate("skate", t_span=(0, 0.3), h=0.1, **kw)
        assert res.status == 0
        assert calls[0] == (want[0], "prepare") and want in calls, (kw, calls)
        assert {c[0] for c in calls} == {want[0]}


def test_a_failure_in_a_later_block_names_the_step_and_time_of_the_whole_run(monkeypatch):
    # the semi-implicit kernel (a comparator: its error is returned as it is, not re-examined)
    # with 4 iterations fails at step 1 of the pendulum at h = 1 from t0 = 5; cut into blocks of
    # one step, the failure is in the second block: the same step and time (t0 + k h) as one call
    kw = dict(engine="compiled", t0=5.0, n_steps=6, h=1.0, newton=ldaspark.Newton(max_iter=4), guard=False)
    one = ldaspark.integrate("pendulum", "lobatto-iiia-iiib-2-leapfrog", **kw)
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", 1)
    cut = ldaspark.integrate("pendulum", "lobatto-iiia-iiib-2-leapfrog", **kw)
    assert one.status == cut.status < 0 and one.error.step == cut.error.step == 1
    assert cut.error.time == one.error.time == 6.0 == float(cut.t[-1])


def test_a_comparator_the_compiled_kernel_cannot_run_is_decided_before_the_run(capsys):
    """lobatto-iiia-iiib-2-modified on a system not in mechanical form: "auto" runs the generic
    comparator engine with the root finder's fields (max_iter = 2 fails there, as on the generic
    engine) and says so; "compiled" is refused in one line. Before, the compiled engine fell back to
    the generic path inside its run, dropped max_iter (status 0, 40 iterations) and reported the
    fields it had ignored. Control: the same comparator on a mechanical system runs compiled."""
    nw = ldaspark.Newton(max_iter=2)
    gen = ldaspark.integrate("relativistic", "lobatto-iiia-iiib-2-modified", n_steps=10, h=0.05,
                             engine="generic", newton=nw)
    auto = ldaspark.integrate("relativistic", "lobatto-iiia-iiib-2-modified", n_steps=10, h=0.05, newton=nw)
    assert gen.status == auto.status == -1 and auto.engine == "generic"
    assert "needs a system in mechanical form" in capsys.readouterr().err
    with pytest.raises(InputError, match="engine 'compiled' cannot run this: .*mechanical form"):
        ldaspark.integrate("relativistic", "lobatto-iiia-iiib-2-modified", n_steps=10, h=0.05, engine="compiled",
                           newton=nw)
    ok = ldaspark.integrate("skate", "lobatto-iiia-iiib-2-modified", n_steps=10, h=0.05, engine="compiled")
    assert ok.status == 0 and ok.engine == "compiled"


@pytest.mark.parametrize("method", ["lobatto-iiia-iiib-2-leapfrog", "lobatto-iiia-iiib-2-modified-leapfrog",
                                    "mp-lobatto-iiib-a-2"])
@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_every_engine_counts_its_work(method, engine):
    """The semi-implicit comparators on the generic engine reported nfev = njev = nlu = 0 (and no
    such keys in stats) for a run of 29 Newton iterations; the compiled kernels of the same methods
    count 40, 10, 10. Every engine's Result carries the four counters, in ``stats`` too, and a run
    that iterated has evaluated residuals and factorised a matrix."""
    r = ldaspark.integrate("particle", method, t_span=(0, 1), h=0.1, engine=engine)
    assert r.success and r.newton_iterations >= 10
    for c in ("nfev", "njev", "nlu", "newton_iterations"):
        assert c in r.stats and r.stats[c] == getattr(r, c), c
    assert r.nfev >= r.newton_iterations and r.njev >= 1 and r.nlu >= 1



# --- counters on failure: one meaning on every path (``ldaspark.core.result``) -----------------
def _accepted_steps(r) -> int:
    return int(round((float(r.t[-1]) - float(r.t[0])) / float(r.h)))


def _check_counters(r, kind, what):
    """The counters' invariants of one run that worked on at least one step (``Result``): every
    counter in ``stats`` too, nonzero once an iteration ran, a residual per iteration, a matrix
    factorised, ``steps`` the accepted steps; full Newton: one LU per Jacobian (one less for each
    attempt that met a singular or non-finite matrix: at most 3 attempts of a step on the
    compiled chain, the kernel's two and the rescuing generic step)."""
    for c in ("nfev", "njev", "nlu", "newton_iterations"):
        assert r.stats[c] == getattr(r, c), (what, c, r.stats[c], getattr(r, c))
    assert r.stats["steps"] == _accepted_steps(r), (what, r.stats["steps"], _accepted_steps(r))
    assert r.newton_iterations > 0 and r.nfev >= r.newton_iterations and r.nlu > 0, (what, r.nfev, r.nlu)
    if kind == "full":
        assert 0 <= r.njev - r.nlu <= 3 and r.njev > 0, (what, r.njev, r.nlu)


FAILING = {   # scene, method, run, newton fields: a failure at step 0 and at step 1
    "max_iter=2, step 0": ("pendulum", "gauss-2", dict(h=0.1, n_steps=8), dict(max_iter=2)),
    "huge h, step 1": ("pendulum", "gauss-2", dict(h=5.0, n_steps=3), {}),
}


@pytest.mark.parametrize("case", sorted(FAILING))
@pytest.mark.parametrize("dense", [False, True])
def test_a_failed_run_counts_its_failed_step_on_every_engine_and_kind(case, dense):
    """A failed run's counters include the work of the failed step (its retries and rescues too),
    with one meaning on every engine: the compiled engine reported nfev = njev = nlu =
    newton_iterations = 0 for a failure at step 0 (3/1/1 on the generic engine) and only its rerun
    prefix for a failure at step k; the generic engine counted the failed step's residuals but not
    its iterations (newton_iterations 23 of 53 on the pendulum at h = 5); the rescue counted the
    generic steps' iterations but not their residuals and matrices. The failure's status class
    is the same on every path (the compiled chain may fail a step later: its rescue)."""
    scene, method, run, fields = FAILING[case]
    runs = {}
    for engine, kinds in (("generic", ("auto", "full", "simplified")),
                          ("compiled", ("auto", "full", "simplified", "quasi"))):
        for kind in kinds:
            r = ldaspark.integrate(scene, method, engine=engine, newton=ldaspark.Newton(kind=kind, **fields),
                                   dense_output=dense, **run)
            assert r.status < 0, (engine, kind, r.message)
            _check_counters(r, kind, (engine, kind))
            runs[engine, kind] = r
    assert {r.status for (_, kind), r in runs.items() if kind != "simplified"} == {-1}
    assert runs["generic", "full"].stats["steps"] == runs["compiled", "full"].stats["steps"]


def test_a_failed_chunked_run_counts_the_blocks_before_its_failure(monkeypatch):
    """Cut into blocks of one step, the pendulum at h = 5 fails at step 1, in the second block:
    its counters are the first block's work plus the failed block's (its failed step's whole
    chain), not the rerun prefix's alone."""
    kw = dict(engine="compiled", h=5.0, n_steps=3, newton=ldaspark.Newton(kind="full"))
    one = ldaspark.integrate("pendulum", "gauss-2", **kw)
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", 1)
    cut = ldaspark.integrate("pendulum", "gauss-2", **kw)
    assert one.status == cut.status == -1 and cut.error.step == one.error.step == 1
    _check_counters(cut, "full", "chunked")
    # the blocks: step 0, then step 1 from its end (the predictor restarts there, so the numbers
    # are not one call's): the sum of the two runs' counters, the failed one's whole
    prefix = ldaspark.integrate("pendulum", "gauss-2", **dict(kw, n_steps=1))
    rest = ldaspark.integrate("pendulum", "gauss-2", **dict(kw, n_steps=2, t0=5.0, q0=prefix.q[-1], v0=prefix.v[-1]))
    assert prefix.status == 0 and rest.status == -1 and rest.error.step == 0
    for c in ("nfev", "njev", "nlu", "newton_iterations"):
        assert getattr(cut, c) == getattr(prefix, c) + getattr(rest, c) > getattr(prefix, c), c


@pytest.mark.parametrize("engine, dps", [("generic", None), ("generic", 30), ("compiled", None)])
def test_failed_ensemble_members_count_as_their_single_runs(engine, dps):
    """Each member of an ensemble (one failing at step 0 with max_iter = 2, one at h = 5) counts
    as its single run, failed step included; dps runs too."""
    nw = ldaspark.Newton(max_iter=2)
    kw = dict(engine=engine, dps=dps, h=0.1, n_steps=4, newton=nw)
    q0, v0 = [[1.0, 0.0], [0.0, -1.0]], [[0.0, 0.5], [0.5, 0.0]]
    ens = ldaspark.integrate("pendulum", "gauss-2", q0=q0, v0=v0, **kw)
    for j in range(2):
        one = ldaspark.integrate("pendulum", "gauss-2", q0=q0[j], v0=v0[j], **kw)
        assert one.status == int(ens.status[j]) == -1
        _check_counters(one, "auto", (engine, dps, j))
        assert [int(getattr(ens, c)[j]) for c in ("nfev", "njev", "nlu", "newton_iterations")] == \
            [getattr(one, c) for c in ("nfev", "njev", "nlu", "newton_iterations")]


def test_a_crossing_of_4_and_a_second_root_count_the_accepted_steps():
    """A step the saddle monitor or the guard refuses was worked on (counted) but not accepted:
    ``steps`` is the rows of the trajectory on every engine (the generic engine counted the refused
    step as a step)."""
    from tests.core.test_guard import WELL, START
    import sympy
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    L = (1 - q[0] ** 2) * v[0] ** 2 / 2 + (v[1] ** 2 + v[2] ** 2) / 2
    mass = ldaspark.LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="mass-vanishing")
    for engine in ("generic", "compiled"):
        r = ldaspark.integrate(mass, "gauss-2", q0=[0.9, 0.3, 0.0], v0=[1.0, 0.1, 0.3], t_span=(0, 2), h=0.02,
                               engine=engine)
        assert r.status == -2
        _check_counters(r, "auto", (engine, "saddle"))
        g = ldaspark.integrate(WELL, "gauss-1", engine=engine, newton=ldaspark.Newton(predictor="zero"), **START)
        assert g.status == -4
        _check_counters(g, "auto", (engine, "guard"))


@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_a_failure_at_the_first_step_has_the_stats_keys_of_every_other_run(engine):
    """``Result.stats`` carries the same keys whether the run succeeded, failed at step k or at step
    0: a compiled run that failed at its first step lacked ``path``, ``mean_iterations`` and the
    guard's counters (``guard_flagged``, ``guard_confirmed``, ``guard_unverified``), which its run
    failing at step 1 and the generic engine's failure at step 0 have. Keys every engine reports:
    the generic engine's, but for its own ``max_residual``."""
    nw = ldaspark.Newton(max_iter=2)
    ok = ldaspark.integrate("pendulum", "gauss-2", engine=engine, h=0.1, n_steps=3)
    first = ldaspark.integrate("pendulum", "gauss-2", engine=engine, h=0.1, n_steps=3, newton=nw)
    later = ldaspark.integrate("pendulum", "gauss-2", engine=engine, h=5.0, n_steps=3)
    assert ok.status == 0 and first.status == later.status == -1
    assert first.stats["steps"] == 0 and later.stats["steps"] == 1
    common = set(ldaspark.integrate("pendulum", "gauss-2", engine="generic", h=0.1, n_steps=3).stats) - {"max_residual"}
    for r in (ok, first, later):
        assert common <= set(r.stats), sorted(common - set(r.stats))
    assert first.stats["path"] == ok.stats["path"] and first.stats["guard_flagged"] == 0
    assert first.stats["mean_iterations"] == first.newton_iterations    # one step worked on, none accepted


@pytest.mark.parametrize("method, engine", [
    (mth, eng) for mth in ("gauss-irk-2", "lobatto-iiia-iiib-2-modified", "lobatto-iiia-iiib-2-leapfrog",
                           "mp-lobatto-iiib-a-2")
    for eng in ("generic", "compiled") if (mth, eng) != ("gauss-irk-2", "compiled")])
def test_a_failed_comparator_run_counts_its_failed_step(method, engine):
    """The comparators fail on the pendulum at h = 5: on the generic engine their counters were
    those of the rerun prefix only (0/0/0/0 for a failure at step 0: the semi-implicit
    comparators; gauss-irk-2 dropped its failed step 2); now the failed step's work is counted on
    both engines (gauss-irk-2 has no compiled kernel)."""
    r = ldaspark.integrate("pendulum", method, h=5.0, n_steps=10, engine=engine)
    assert r.status < 0, r.message
    _check_counters(r, "auto", (engine, method))
    if r.stats["steps"]:          # a failure after accepted steps: more than their work
        ok = ldaspark.integrate("pendulum", method, h=5.0, n_steps=r.stats["steps"], engine=engine)
        assert ok.status == 0 and r.newton_iterations > ok.newton_iterations and r.nfev > ok.nfev


def test_a_rescued_run_counts_the_generic_steps_work():
    """mp-particles, gauss-2 at h = 32: the kernels' Newton fails at two steps which the generic
    full-Newton step takes (``compiled.rescue``). Full Newton assembles a Jacobian and evaluates
    the residual at the s + 1 = 3 points at every iteration; the rescue counted the generic
    steps' iterations but not their residuals, Jacobians and LUs (njev < newton_iterations)."""
    r = ldaspark.integrate("mp-particles", "gauss-2", h=32.0, n_steps=3, engine="compiled", newton="full")
    assert r.status == 0 and r.stats["rescued_steps"] >= 1
    _check_counters(r, "full", "rescued")
    assert r.njev >= r.newton_iterations and r.nfev >= 3 * r.newton_iterations, (r.njev, r.nfev, r.newton_iterations)


@pytest.mark.parametrize("s", [1, 2, 3])
def test_gauss_irk_counts_its_residuals_stage_points_once(s):
    """The standard Gauss IRK (7.3-7.4) imposes k = 0 at its s stages instead of (21e-f): its
    residual evaluates the model at the same s + 1 points as (21) (the stages and the end point
    of (21d)), and it counted the s stages a second time for its k rows (2 s + 1 per residual:
    gauss-irk-3 on the skate, nfev 42 for 6 iterations; now 24). One residual per iteration
    (``SparkMethod.step``); control: the SPARK method of s stages on the same engine, s + 1."""
    for method in (f"gauss-irk-{s}", f"gauss-{s}"):
        r = ldaspark.integrate("skate", method, h=0.1, n_steps=3, engine="generic")
        assert r.status == 0 and r.newton_iterations > 0, (method, r.message)
        assert r.nfev == (s + 1) * r.newton_iterations, (method, r.nfev, r.newton_iterations)


@pytest.mark.parametrize("scene", ["skate", "relativistic"])
def test_nfev_counts_the_residuals_stage_points_on_every_engine(scene):
    """``nfev`` is the stage points of the residual evaluations (s + 1 each) on every engine; the
    Jacobians are ``njev``. The compiled kernels counted a Jacobian's evaluations in ``nfev`` too
    (2 s + 1 per residual with Jacobian on the mechanical kernel, 2 s + 3 on the general one):
    skate gauss-2 full Newton, 20/20/20 iterations/njev/nlu on both engines, nfev 60 generic and
    100 compiled. Full Newton evaluates one residual per iteration, so nfev = (s + 1) iterations
    on both engines (skate: the mechanical kernel; relativistic: the general one)."""
    s = 2
    runs = {eng: ldaspark.integrate(scene, f"gauss-{s}", h=0.1, n_steps=10, engine=eng,
                                    newton=ldaspark.Newton(kind="full"))
            for eng in ("generic", "compiled")}
    assert runs["compiled"].stats["path"] != "generic"
    for eng, r in runs.items():
        assert r.status == 0 and r.newton_iterations > 0, (eng, r.message)
        assert r.nfev == (s + 1) * r.newton_iterations, (eng, r.nfev, r.newton_iterations)
        assert r.njev == r.nlu == r.newton_iterations, (eng, r.njev, r.nlu)
    # the quasi-Newton kernels (mechanical and general form): one residual per increment, the
    # frozen multiplier matrix not counted as residual points (the general one added s + 1 a step)
    r = ldaspark.integrate(scene, f"gauss-{s}", h=0.1, n_steps=10, engine="compiled", newton="quasi")
    assert r.status == 0 and r.stats["kernel"] == "quasi" and r.stats["quasi_fallbacks"] == 0, r.stats
    assert r.nfev == (s + 1) * r.newton_iterations, (r.nfev, r.newton_iterations)


def test_the_comparator_engine_bounds_the_steps_it_stores_not_the_samples_kept(monkeypatch):
    """The comparator engine returns every step (``samples`` False) and the driver slices
    save_every: its ``check_block`` bounds (n + 1) points x (2 + 2n + m) numbers (mpmath: 3 x
    the bytes) where the driver's check saw only the samples kept. Memory set to hold 1.5 x the
    101 float64 points of gauss-irk-2 on the skate (n = 3, m = 1: 9 numbers a point, 40 bytes
    each): 100 steps run (control); 200 steps kept every 100th are refused naming the 201 steps,
    as are 101 points at 20 digits; a SPARK method on the compiled kernel, which keeps its
    samples, runs those 200 steps."""
    from ldaspark.core import validate
    one = 101 * 9 * 40
    monkeypatch.setattr(validate, "physical_memory", lambda: int(1.5 * one / validate.MEMORY_FRACTION))
    kw = dict(h=0.01, engine="generic")
    assert ldaspark.integrate("skate", "gauss-irk-2", n_steps=100, **kw).status == 0
    with pytest.raises(InputError, match=r"storing the comparator's steps \(201 points x 9 numbers\)"):
        ldaspark.integrate("skate", "gauss-irk-2", n_steps=200, save_every=100, **kw)
    with pytest.raises(InputError, match=r"storing the comparator's steps \(101 points x 9 numbers\)"):
        ldaspark.integrate("skate", "gauss-irk-2", n_steps=100, dps=20, **kw)
    r = ldaspark.integrate("skate", "gauss-2", n_steps=200, save_every=100, h=0.01, engine="compiled")
    assert r.status == 0 and len(r.t) == 3
