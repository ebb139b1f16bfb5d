"""A member of an ensemble keeps the promises of its single run (probe t16): the same warnings on
every executor, the same stats keys, the same refusals."""
import concurrent.futures as cf
import multiprocessing
import warnings

import numpy as np
import pytest
import sympy as sp

import ldaspark
import ldaspark.executors
from ldaspark.core.errors import LdasparkWarning


def _singular_mass():
    # M = [[1, 1], [1, 1]] (rank 1), K = [1, -1] covers its null vector: (4) regular, (5) fails
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = (vx + vy) ** 2 / 2 - (x ** 2 + 2 * y ** 2) / 2
    return ldaspark.LagrangianSystem(L, [vx - vy], [x, y], [vx, vy], name="singular-M")


def _regular():
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = (vx ** 2 + vy ** 2) / 2 - (x ** 2 + 2 * y ** 2) / 2
    return ldaspark.LagrangianSystem(L, [vx - vy], [x, y], [vx, vy], name="regular-M")


def _said(call):
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        res = call()
    return res, [(w.category, str(w.message)) for w in rec if issubclass(w.category, LdasparkWarning)]


def test_a_process_pool_says_the_warnings_of_the_run_in_this_process():
    """A member (or a single run) on a process pool warned in the worker, where the caller never
    saw it: project=True's change of v0 and the singular L_vv of (5) were 0 warnings through a
    ProcessPoolExecutor against 3 (one projection, one (5) per member) without an executor. Now
    the tasks hand their warnings back and they are said here, in member order, the same list.
    Control: a regular L with consistent v0 says nothing on either path."""
    kw = dict(q0=[[1.0, 0.5], [0.9, 0.4]], v0=[[0.3, 0.2], [0.2, 0.2]], h=0.05, n_steps=2, project=True,
              engine="generic")
    with cf.ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("fork")) as ex:
        for system, expect in ((_singular_mass(), 3), (_regular(), 0)):
            kw_sys = dict(kw, v0=[[0.3, 0.3], [0.2, 0.2]]) if expect == 0 else kw
            here, said_here = _said(lambda: ldaspark.integrate(system, "gauss-2", **kw_sys))
            there, said_there = _said(lambda: ldaspark.integrate(system, "gauss-2", executor=ex, **kw_sys))
            assert len(said_here) == expect and said_there == said_here
            assert np.array_equal(there.q, here.q)
            one = dict(kw_sys, q0=kw_sys["q0"][0], v0=kw_sys["v0"][0])
            assert _said(lambda: ldaspark.integrate(system, "gauss-2", executor=ex, **one))[1] == \
                _said(lambda: ldaspark.integrate(system, "gauss-2", **one))[1]


def test_member_0_failing_its_first_kernel_step_is_reported_as_any_member():
    """run_many warmed the kernels on member 0's first step in this process and let its failure
    escape: a bare NewtonError naming no member (member 1 failing is UnitsFailed), and
    integrate(q0=(B, n), executor=..., guard=False) raised it where the same call without an
    executor returns status 0 for both members (2 steps rescued by the generic step each, singular
    L_vv of (5), gauss-2). Now it is UnitsFailed naming the unit, and integrate falls back to the
    loop of single runs: the same numbers bit for bit. Control: a regular L runs on the kernels."""
    from ldaspark.ensemble import RunSpec, run_many
    from ldaspark.executors import UnitsFailed
    Q, V = [[1.0, 0.5], [0.9, 0.4]], [[0.3, 0.3], [0.2, 0.2]]
    kw = dict(q0=Q, v0=V, h=0.05, n_steps=2, guard=False)
    S = _singular_mass()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LdasparkWarning)
        loop = ldaspark.integrate(S, "gauss-2", **kw)
        with cf.ThreadPoolExecutor(2) as ex:
            with pytest.raises(UnitsFailed, match=r"^2 work unit\(s\) failed \(0 finished\): spec 0, member 0: NewtonError"):
                run_many([RunSpec(S, "gauss-2", 0.0, Q, V, 0.05, 2)], where=ex)
            there = ldaspark.integrate(S, "gauss-2", executor=ex, **kw)
            ok = run_many([RunSpec(_regular(), "gauss-2", 0.0, Q, V, 0.05, 2)], where=ex)[0]
    assert list(loop.status) == [0, 0] and [m.stats["rescued_steps"] for m in loop.members] == [2, 2]
    assert list(there.status) == [0, 0] and np.array_equal(there.q, loop.q) and np.array_equal(there.v, loop.v)
    assert ok.q.shape == (2, 3, 2)


@pytest.mark.parametrize("method", ["gauss-2", "lobatto-iiia-iiib-2", "mp-lobatto-iiib-a-2"])
def test_run_many_members_have_the_stats_of_their_single_runs(method):
    """run_many's members lacked ``rescued_steps``, had ``root_finder`` as the kernel's bare kind
    ("quasi", or none for the semi-implicit kernel) and said ``engine`` "compiled" where the single
    run of lobatto-iiia-iiib-2 and of a comparator says "compiled-lf2" (3 of 3 methods differed;
    only integrate's executor path patched them). Now keys and values equal (no timing is kept in
    these stats: the whole dicts compare), the numbers bit for bit, with t0 != 0, h < 0,
    save_every and tol. Control: the numbers of another initial point differ."""
    from ldaspark.core.result import from_ensemble
    from ldaspark.ensemble import RunSpec, run_many
    sc = ldaspark.get_scene("skate")
    q0, v0 = np.asarray(sc.q0, float), np.asarray(sc.v0, float)
    Q, V = np.array([q0, q0 + [0.1, 0, 0]]), np.array([v0, v0])
    kw = dict(t0=0.3, h=-0.05, n_steps=17, save_every=3, tol=1e-12)
    with cf.ThreadPoolExecutor(2) as ex:
        ens = run_many([RunSpec(sc.system, method, 0.3, Q, V, -0.05, 17, 3, tol=1e-12)], where=ex)[0]
    res = from_ensemble(ens, method=method, h=-0.05, save_every=3)
    for j in range(2):
        one = ldaspark.integrate(sc.system, method, q0=Q[j], v0=V[j], **kw)
        assert res.members[j].stats == one.stats
        assert np.array_equal(res.q[j], one.q) and np.array_equal(res.v[j], one.v)
        assert np.array_equal(res.energy[j], one.energy)
    assert not np.array_equal(res.q[0], res.q[1])


def test_run_many_says_the_singular_L_vv_warning_of_the_single_run():
    """The single run from a point where L_vv is singular while (4) holds says one LdasparkWarning
    ((5) fails); run_many's members said nothing (the open item of the earlier probes). Now each
    such member says the single run's text, once every member ended well. gauss-1 converges on
    the kernels there (gauss-2 and -3, the Lobatto and Euler methods do not: the warm-up test
    above). Control: a regular L says nothing."""
    from ldaspark.ensemble import RunSpec, run_many
    Q, V = [[1.0, 0.5], [0.9, 0.4]], [[0.3, 0.3], [0.2, 0.2]]
    with cf.ThreadPoolExecutor(2) as ex:
        for system, expect in ((_singular_mass(), 2), (_regular(), 0)):
            singles = [_said(lambda: ldaspark.integrate(system, "gauss-1", q0=q, v0=v, h=0.05,
                                                        n_steps=2))[1] for q, v in zip(Q, V)]
            ens, said = _said(lambda: run_many([RunSpec(system, "gauss-1", 0.0, Q, V, 0.05, 2)],
                                               where=ex)[0])
            assert len(said) == expect and said == [w for ws in singles for w in ws]
            assert ens.q.shape == (2, 3, 2)


@pytest.mark.parametrize("key, match", [
    ("project", r"RunSpec does not take integrate's option 'project'; ldaspark.integrate\(system, method, "
                r"q0=Q0, v0=V0, executor=\.\.\.\) runs an ensemble with it"),
    ("dense_output", r"does not take integrate's option 'dense_output'"),
    ("save_every", r"does not take integrate's option 'save_every' \(a RunSpec calls it every\)"),
    ("evry", r"RunSpec: unknown option 'evry' \(did you mean every\?\)")])
def test_an_option_runspec_does_not_take_is_one_input_error(key, match):
    """RunSpec(..., project=True) and a misspelt option were a raw TypeError ("unexpected keyword
    argument"), where integrate refuses an unknown option with an InputError naming the closest
    one; an option of integrate that a RunSpec does not take now says where it is taken.
    run_many's own keywords likewise. Control: the same RunSpec without it is made."""
    from ldaspark.core.errors import InputError
    from ldaspark.ensemble import RunSpec, run_many
    sc = ldaspark.get_scene("skate")
    args = (sc.system, "gauss-2", 0.0, [sc.q0], [sc.v0], 0.1, 3)
    with pytest.raises(InputError, match=match):
        RunSpec(*args, **{key: 2})
    with pytest.raises(InputError, match=r"run_many: unknown option 'gaurd' \(did you mean guard\?\)"):
        run_many([RunSpec(*args)], gaurd=False)
    assert RunSpec(*args).n_steps == 3


def test_from_ensemble_of_run_many_keeps_the_coordinate_names_through_a_file(tmp_path):
    """``from_ensemble`` of run_many's result had coordinate_names None (its file none), where the
    single runs, their ``stack`` and integrate's executor ensemble have the names (['q1', 'q2',
    'q3'] on the skate). EnsembleResult now carries them. The .npz round trip of both ensembles
    gives the same arrays and names. Control: names given to from_ensemble are kept."""
    from ldaspark import load_result, save_result
    from ldaspark.core.result import from_ensemble, stack
    from ldaspark.ensemble import RunSpec, run_many
    sc = ldaspark.get_scene("skate")
    q0, v0 = np.asarray(sc.q0, float), np.asarray(sc.v0, float)
    Q, V = np.array([q0, q0 + [0.01, 0, 0]]), np.array([v0, v0])
    with cf.ThreadPoolExecutor(1) as ex:
        ens = run_many([RunSpec(sc.system, "lobatto-iiia-iiib-2", 0.3, Q, V, -0.1, 7, 2)], where=ex)[0]
    meta = dict(method="lobatto-iiia-iiib-2", h=-0.1, save_every=2, system=sc.system.name, scene="skate")
    R = from_ensemble(ens, **meta)
    S = stack([ldaspark.integrate("skate", "lobatto-iiia-iiib-2", q0=Q[j], v0=V[j], t0=0.3, h=-0.1, n_steps=7,
                                  save_every=2) for j in range(2)])
    assert R.coordinate_names == S.coordinate_names == ["q1", "q2", "q3"]
    assert [m.coordinate_names for m in R.members] == [["q1", "q2", "q3"]] * 2
    save_result(R, tmp_path / "r.npz")
    save_result(S, tmp_path / "s.npz")
    r, s = load_result(tmp_path / "r.npz"), load_result(tmp_path / "s.npz")
    assert r.coordinate_names == s.coordinate_names == ["q1", "q2", "q3"]
    for a in ("t", "q", "v", "energy", "constraint", "psi"):
        assert np.array_equal(getattr(r, a), getattr(s, a))
    assert from_ensemble(ens, coordinate_names=["x", "y", "th"], **meta).coordinate_names == ["x", "y", "th"]


class _InterruptedAtSecond(cf.Executor):
    """Runs the first task at once; the second future holds a KeyboardInterrupt (Ctrl-C while
    waiting for it); the later ones stay queued, never started."""

    def __init__(self, interrupt=True):
        self.futures, self.interrupt = [], interrupt

    def submit(self, fn, /, *args, **kwargs):
        f = cf.Future()
        if not self.futures:
            f.set_result(fn(*args, **kwargs))
        elif len(self.futures) == 1:
            if self.interrupt:
                f.set_exception(KeyboardInterrupt())
            else:
                f.set_result(fn(*args, **kwargs))
        self.futures.append(f)
        return f


def test_ctrl_c_in_integrates_executor_ensemble_cancels_the_queued_members():
    """docs/reliability.md "Interrupting ensembles" for integrate's loop of members on an executor
    (each member submitted and checked since probe t16, no longer through ``map``): the
    KeyboardInterrupt reaches the caller as it is (not an LdasparkError) and the members still
    queued are cancelled. Control: the same executor without the interrupt leaves its third
    future queued (the call then waits for it: not run here), so the cancellation is the
    interrupt's doing; the first member's future is done, not cancelled."""
    sc = ldaspark.get_scene("skate")
    kw = dict(q0=[sc.q0] * 3, v0=[sc.v0] * 3, h=0.1, n_steps=2, engine="generic")
    ex = _InterruptedAtSecond()
    with pytest.raises(KeyboardInterrupt):
        ldaspark.integrate("skate", "gauss-2", executor=ex, **kw)
    assert [f.cancelled() for f in ex.futures] == [False, False, True]
    calm = _InterruptedAtSecond(interrupt=False)
    for j in range(3):
        calm.submit(abs, -j)
    assert [f.done() for f in calm.futures] == [True, True, False]


def test_a_failed_task_of_run_many_names_its_spec_and_members():
    """A task that failed was named by its position in the plan: two specs of 3 members with
    chunk=2 failing in spec 1 said "2: NewtonError ...; 3: NewtonError ..." (read as members 2 and
    3 of spec 0, which ran well), where the guard and the det (4) monitor name "spec k, member r".
    Now "spec 1, members 0-1" and "spec 1, member 2". Control: spec 0 (a regular L) finished."""
    from ldaspark.ensemble import RunSpec, run_many
    from ldaspark.executors import UnitsFailed
    Q, V = [[1.0, 0.5], [0.9, 0.4], [0.8, 0.4]], [[0.3, 0.3], [0.2, 0.2], [0.1, 0.1]]
    specs = [RunSpec(_regular(), "gauss-2", 0.0, Q, V, 0.05, 2), RunSpec(_singular_mass(), "gauss-2", 0.0, Q, V, 0.05, 2)]
    with cf.ThreadPoolExecutor(2) as ex:
        with pytest.raises(UnitsFailed) as err:
            run_many(specs, where=ex, chunk=2)
    assert list(err.value.failed) == ["spec 1, members 0-1", "spec 1, member 2"]
    assert sorted(err.value.results) == ["spec 0, member 2", "spec 0, members 0-1"]
    assert str(err.value).startswith("2 work unit(s) failed (2 finished): spec 1, members 0-1: NewtonError")


def test_run_many_members_on_the_generic_path_have_the_stats_of_their_single_runs(monkeypatch):
    """A system the kernels cannot run goes to the generic path in run_many's tasks and to the
    generic engine in integrate: the numbers agreed bit for bit but the members lacked the single
    run's ``root_finder`` (the Newton asked for, as the generic engine honours it). Now the stats
    dicts are equal (t0 = 0.2, h = -0.1, save_every 3, tol 1e-10). Control: the numbers of the two
    members differ."""
    from ldaspark.compiled import runner
    from ldaspark.compiled.codegen import NotCompilableError
    from ldaspark.core.result import from_ensemble
    from ldaspark.ensemble import RunSpec, run_many
    q, v = list(sp.symbols("q1:4")), list(sp.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 + v[0] ** 4 / 12 - (q[0] ** 2 + q[1] ** 2)
    S = ldaspark.LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="quartic", nonideal=[q[1] * v[0], 0, 0])

    def refuse(system):      # as an expression without a numba translation (test_ensemble)
        raise NotCompilableError(f"{system.name}: an expression has no numba translation (refused here)")
    monkeypatch.setattr(runner, "general_source", refuse)
    Q, V = [[1.0, 0.0, 0.0], [0.5, 0.0, 0.0]], [[0.0, 1.0, 0.0], [0.0, 0.5, 0.0]]
    with cf.ThreadPoolExecutor(1) as ex:
        ens = run_many([RunSpec(S, "gauss-2", 0.2, Q, V, -0.1, 10, 3, tol=1e-10)], where=ex)[0]
    res = from_ensemble(ens, method="gauss-2", h=-0.1, save_every=3)
    for j in range(2):
        one = ldaspark.integrate(S, "gauss-2", q0=Q[j], v0=V[j], t0=0.2, h=-0.1, n_steps=10, save_every=3, tol=1e-10)
        assert one.stats["path"] == "generic" and res.members[j].stats == one.stats
        assert np.array_equal(res.q[j], one.q) and np.array_equal(res.psi[j], one.psi)
    assert not np.array_equal(res.q[0], res.q[1])


class _TwoThreads(cf.Executor):
    """Not a ThreadPoolExecutor (so integrate treats it as a cluster's executor, whose tasks may
    run elsewhere), but its tasks run on two threads of this process, as a Dask cluster with
    processes=False does."""

    def __init__(self):
        self.pool = cf.ThreadPoolExecutor(2)

    def submit(self, fn, /, *args, **kwargs):
        return self.pool.submit(fn, *args, **kwargs)

    def shutdown(self, wait=True, **kw):
        self.pool.shutdown(wait)


def test_members_on_threads_of_a_foreign_executor_keep_every_warning(monkeypatch):
    """Two members on threads of an executor that is not a ThreadPoolExecutor (Dask with
    processes=False): with the members' warnings recorded by ``warnings.catch_warnings`` in each
    task (the first fix for process pools), member 1 leaving its context after member 0 restored
    member 0's recorder as the process's: the caller then got 1 of the 3 warnings (Dask with
    threads: 3 and then 0 of 5, in two calls). The runs now hand their warnings over without touching
    the warning state. The order is forced: both members inside their run, member 0 finishes,
    then member 1 (no timing). Also a params key that is no parameter, through a params ensemble.
    Control: the same calls without an executor say the same list."""
    from ldaspark import solve
    single, barrier, first = solve._single, __import__("threading").Barrier(2), []

    def forced(*args, **kwargs):
        barrier.wait()                        # both members inside their task
        member = args[1]
        if member[1] != [1.0, 0.5]:           # member 1 ends after member 0's task returned
            first[0].result()
        return single(*args, **kwargs)
    kw = dict(q0=[[1.0, 0.5], [0.9, 0.4]], v0=[[0.3, 0.2], [0.2, 0.2]], h=0.05, n_steps=2, project=True,
              engine="generic")
    S = _singular_mass()
    expected = _said(lambda: ldaspark.integrate(S, "gauss-2", **kw))[1]
    assert len(expected) == 3
    ex = _TwoThreads()
    monkeypatch.setattr(solve, "_single", forced)
    real_submit = ex.pool.submit

    def submit(fn, *args, **kwargs):
        f = real_submit(fn, *args, **kwargs)
        first.append(f)
        return f
    monkeypatch.setattr(ex.pool, "submit", submit)
    with ex:
        got = _said(lambda: ldaspark.integrate(S, "gauss-2", executor=ex, **kw))[1]
    monkeypatch.setattr(solve, "_single", single)
    assert got == expected
    pkw = dict(q0=[1.0, 0.5], v0=[0.3, 0.3], h=0.05, n_steps=2, engine="generic", params=[{"nope": 1.0}] * 2)
    with cf.ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("fork")) as pool:
        there = _said(lambda: ldaspark.integrate(S, "gauss-2", executor=pool, **pkw))[1]
    here = _said(lambda: ldaspark.integrate(S, "gauss-2", **pkw))[1]
    assert len(here) == 4 and there == here      # (5) and the key's note, for each member


def test_a_thread_pools_members_say_their_warnings_in_member_order(monkeypatch):
    """On a ThreadPoolExecutor the members warned from their threads, in the order they ran: with
    member 1 ending first the caller saw member 1's (5) warning before member 0's projection and
    (5) warnings, another list than the run without an executor (and on Python 3.14 a thread's
    warning need not reach the caller's catch_warnings at all). Now said here in member order.
    The order is forced (member 0 ends after member 1's task returned; no timing). Control: the
    run without an executor."""
    import threading
    from ldaspark import solve
    single, barrier, futs = solve._single, threading.Barrier(2), []
    # both members run once the caller holds both futures: the barrier alone let member 0 ask for
    # futs[1] before the caller's submit had appended it (IndexError on a fresh clone)
    both = threading.Event()

    def forced(*args, **kwargs):
        barrier.wait()
        if args[1][1] == [1.0, 0.5]:          # member 0 ends after member 1
            assert both.wait(60)
            futs[1].result()
        return single(*args, **kwargs)

    def submit(real_submit, fn, *a, **k):
        futs.append(real_submit(fn, *a, **k))
        if len(futs) == 2:
            both.set()
        return futs[-1]
    kw = dict(q0=[[1.0, 0.5], [0.9, 0.4]], v0=[[0.3, 0.2], [0.2, 0.2]], h=0.05, n_steps=2, project=True,
              engine="generic")
    S = _singular_mass()
    expected = _said(lambda: ldaspark.integrate(S, "gauss-2", **kw))[1]
    monkeypatch.setattr(solve, "_single", forced)
    with cf.ThreadPoolExecutor(2) as ex:
        real_submit = ex.submit
        monkeypatch.setattr(ex, "submit", lambda fn, *a, **k: submit(real_submit, fn, *a, **k))
        got = _said(lambda: ldaspark.integrate(S, "gauss-2", executor=ex, **kw))[1]
    assert len(expected) == 3 and got == expected


def test_a_comparator_member_on_the_generic_path_says_the_comparator_engine():
    """The modified method of 8.4 on a system not of the mechanical form runs the generic
    comparator in run_many's tasks and in integrate: the numbers agreed bit for bit, but the
    members' stats said engine "generic" where the single run says "comparator". Control: the
    whole stats dicts equal after, and the members differ."""
    from ldaspark.core.result import from_ensemble
    from ldaspark.ensemble import RunSpec, run_many
    x, y, vx, vy = sp.symbols("x y vx vy")
    S = ldaspark.LagrangianSystem(vx ** 4 / 12 + (vx ** 2 + vy ** 2) / 2 - (x ** 2 + y ** 2) / 2, [vy - x * vx],
                                  [x, y], [vx, vy], name="quartic")
    Q, V, m = [[0.5, 0.1], [0.4, 0.1]], [[1.3, 0.65], [1.0, 0.4]], "lobatto-iiia-iiib-2-modified"
    with cf.ThreadPoolExecutor(1) as ex:
        ens = run_many([RunSpec(S, m, 0.0, Q, V, 0.05, 5)], where=ex)[0]
    res = from_ensemble(ens, method=m, h=0.05)
    for j in range(2):
        one = ldaspark.integrate(S, m, q0=Q[j], v0=V[j], h=0.05, n_steps=5)
        assert one.stats["engine"] == "comparator" and res.members[j].stats == one.stats
        assert np.array_equal(res.q[j], one.q)
    assert not np.array_equal(res.q[0], res.q[1])


class _Reversed(cf.Executor):
    """Holds every task until the n-th is submitted, then runs them on one thread last first:
    the futures complete in reverse order (no timing)."""

    def __init__(self, n):
        self.n, self.calls, self.order = n, [], []

    def submit(self, fn, /, *args, **kwargs):
        f = cf.Future()
        self.calls.append((f, fn, args, kwargs))
        if len(self.calls) == self.n:
            import threading

            def run():
                for i, (g, fn2, a2, k2) in reversed(list(enumerate(self.calls))):
                    g.set_running_or_notify_cancel()
                    g.set_result(fn2(*a2, **k2))
                    self.order.append(i)
            threading.Thread(target=run, daemon=True).start()
        return f


def test_members_completed_in_reverse_order_are_assembled_in_member_order():
    """run_many (3 tasks) and integrate's members (3) on an executor that completes the last task
    first: the results equal the serial run's bit for bit, in member order. Control: the executor
    did complete them in reverse order."""
    from ldaspark.ensemble import RunSpec, run_many
    sc = ldaspark.get_scene("skate")
    q0, v0 = np.asarray(sc.q0, float), np.asarray(sc.v0, float)
    Q, V = np.array([q0 + [0.01 * j, 0, 0] for j in range(3)]), np.array([v0] * 3)
    spec = lambda: [RunSpec(sc.system, "gauss-2", 0.0, Q, V, 0.1, 10)]       # noqa: E731
    serial = run_many(spec(), where=ldaspark.executors.InlineExecutor())[0]
    ex = _Reversed(3)
    out = run_many(spec(), where=ex)[0]
    assert ex.order == [2, 1, 0]
    assert np.array_equal(out.q, serial.q) and out.stats == serial.stats
    loop = ldaspark.integrate(sc.system, "gauss-2", q0=Q, v0=V, h=0.1, n_steps=10)
    ex = _Reversed(3)
    there = ldaspark.integrate(sc.system, "gauss-2", q0=Q, v0=V, h=0.1, n_steps=10, executor=ex)
    assert ex.order == [2, 1, 0]
    assert np.array_equal(there.q, loop.q) and [m.stats for m in there.members] == [m.stats for m in loop.members]
    assert not np.array_equal(out.q[0], out.q[2])
