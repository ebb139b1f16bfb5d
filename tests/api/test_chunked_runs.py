"""A run cut into blocks (``chunks.run_in_blocks``, runs longer than COMPILED_CHUNK steps; made small
here) is the run of one call to what it reports: the saved times t0 + i h as one call computes
them, the counters' maximum over the blocks, a failure's step number in its message, and the
guard's rerun of the first steps with the blocks of the run it judges. Each check has the
unchunked run (or the generic engine) as its control."""
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark import solve
from ldaspark.core import chunks

x, y, th, vx, vy, vth = sympy.symbols("x y th vx vy vth")
# a stiff quartic spring with a nonholonomic constraint: gauss-3 at h = 0.2 takes up to ~70
# full-Newton iterations a step, gauss-2 at h = 0.7 fails after a few steps
QUARTIC = ldaspark.LagrangianSystem((vx**2 + vy**2) / 2 + vth**2 / 2 - 1e4 * (x**4 / 4 + x**2 * y**2 / 2)
                                    - 3 * sympy.cos(th), [vy - 3 * x * vth], [x, y, th], [vx, vy, vth], name="quartic")
IC = dict(q0=[0.5, 0.1, 0.3], v0=[1.0, 0.75, 0.5], engine="compiled")


def _run(chunk, monkeypatch, method="gauss-2", **kw):
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", chunk)
    return ldaspark.integrate(QUARTIC, method, **dict(IC, **kw))


def test_max_iterations_is_the_maximum_over_the_blocks(monkeypatch):
    kw = dict(h=0.2, n_steps=50, newton="full")
    one = _run(2**18, monkeypatch, "gauss-3", **kw).stats["max_iterations"]
    blocks = _run(10, monkeypatch, "gauss-3", **kw).stats["max_iterations"]
    assert blocks == one and one > 30          # was the first block's (36 against 69)


def test_the_counters_add_up_over_the_blocks(monkeypatch):
    """steps, nfev, njev, nlu, newton_iterations and full_newton_steps of a run in blocks are the
    sums of its blocks' (each block's run recorded as the engine returns it), in ``stats`` and in
    the Result's nfev, njev, nlu; with full Newton every Jacobian is factored once, so nlu = njev
    over the run as within a block. Control: the run has more than one block."""
    from ldaspark.engines import ENGINES
    seen = []
    real = ENGINES["compiled"].run

    def recording(prepared, start, n_steps, every):
        res = real(prepared, start, n_steps, every)
        seen.append(dict(res.stats))
        return res
    monkeypatch.setitem(vars(ENGINES["compiled"]), "run", recording)    # the registered instance's
    r = _run(10, monkeypatch, "gauss-3", h=0.2, n_steps=50, newton="full")
    assert len(seen) == 5 and r.stats["steps"] == 50
    for key in ("steps", "nfev", "njev", "nlu", "newton_iterations", "full_newton_steps"):
        assert r.stats[key] == sum(st[key] for st in seen), (key, r.stats[key], [st[key] for st in seen])
    assert (r.nfev, r.njev, r.nlu) == (r.stats["nfev"], r.stats["njev"], r.stats["nlu"])
    assert r.nlu == r.njev >= 50


@pytest.mark.parametrize("every", [1, 3])
def test_the_saved_times_are_those_of_one_call(monkeypatch, every):
    """Each block started at t0 + done h and added j h: 10 of 41 times were an ulp off the generic
    engine's and the unchunked run's t0 + i h."""
    kw = dict(h=0.1, t0=0.3, n_steps=40, save_every=every)
    gen = ldaspark.integrate(QUARTIC, "gauss-2", q0=IC["q0"], v0=IC["v0"], h=0.1, t0=0.3, n_steps=40,
                             save_every=every, engine="generic")
    one = _run(2**18, monkeypatch, **kw)
    blocks = _run(8, monkeypatch, **kw)
    np.testing.assert_array_equal(one.t, np.asarray(gen.t, float))
    np.testing.assert_array_equal(blocks.t, one.t)


def test_a_later_block_s_failure_names_the_run_s_step_in_its_message(monkeypatch):
    """The kernel's message counted the block's steps ("step 3") where error.step said 7."""
    one = _run(2**18, monkeypatch, h=0.7, n_steps=30, newton="full")
    blocks = _run(4, monkeypatch, h=0.7, n_steps=30, newton="full")
    assert blocks.status == one.status < 0 and blocks.error.step == one.error.step >= 4
    k = blocks.error.step
    import re
    steps = {int(m) for m in re.findall(r"\bstep (\d+)\b", blocks.message)}
    assert steps == {k} and blocks.message.count(f"step {k}") >= 2


def test_the_guard_reruns_the_blocks_of_the_run_it_judges(monkeypatch):
    """With save_every = 3 the run's blocks were 3 steps long (COMPILED_CHUNK = 4) and the guard's
    every-step rerun's 4: the predictor restarted at other steps, the rerun was another trajectory
    (it failed at another step than the run near the Newton limit). With the run's block ends
    (``boundaries``) the rerun's every third step is the run's sample, bit for bit; control: with
    its own blocks it is not."""
    from ldaspark.engines import ENGINES
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", 4)
    opts = solve.IntegrationOptions.checked(engine="compiled", save_every=3)
    prob = solve._Problem("spark", solve.resolve_method("gauss-2")[1], "gauss-2", 0.0, 0.05, 30, None)
    eng = ENGINES["compiled"]
    prep = eng.prepare(QUARTIC, prob, opts)
    start = (0.0, np.array(IC["q0"]), np.array(IC["v0"]))
    run = chunks.run_in_blocks(eng, prep, start, 30, 3)
    rerun = chunks.run_in_blocks(eng, prep, start, 30, 1, boundaries=3)
    own = chunks.run_in_blocks(eng, prep, start, 30, 1)
    np.testing.assert_array_equal(np.asarray(rerun.q)[::3], np.asarray(run.q))
    assert not np.array_equal(np.asarray(own.q)[::3], np.asarray(run.q))


@pytest.mark.parametrize("every", [1, 3, 11])
def test_an_ensemble_through_an_executor_is_cut_into_the_blocks_of_its_single_runs(monkeypatch, every):
    """The kernel tasks of ``run_many`` (guard=False with an executor) ran each member in one kernel
    call while the loop of single runs cut it into blocks (the predictor restarting at each): past
    COMPILED_CHUNK steps the members differed from their single runs (4.4e-16 on the skate);
    now bit for bit, counters too, and the guard's rerun of ``run_many`` likewise."""
    from concurrent.futures import ThreadPoolExecutor
    from ldaspark.ensemble import RunSpec, run_many
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", 8)
    Q0, V0 = [IC["q0"], [0.45, 0.1, 0.2]], [IC["v0"], [1.0, 0.27, 0.2]]
    kw = dict(q0=Q0, v0=V0, h=0.05, n_steps=50, save_every=every, engine="compiled", guard=False)
    loop = ldaspark.integrate(QUARTIC, "gauss-2", **kw)
    with ThreadPoolExecutor(1) as ex:
        par = ldaspark.integrate(QUARTIC, "gauss-2", executor=ex, **kw)
    assert [m["guard"] for m in par.stats["members"]] == [False, False]    # the kernel tasks ran
    for name in ("t", "q", "v", "energy", "constraint", "psi", "nfev", "njev", "nlu", "newton_iterations"):
        np.testing.assert_array_equal(getattr(par, name), getattr(loop, name), err_msg=name)
    for a, b in zip(par.stats["members"], loop.stats["members"]):
        assert a["steps"] == b["steps"] == 50 and a["max_iterations"] == b["max_iterations"]
    # run_many's guard (on by default) judges the members it ran, with the same blocks
    with ThreadPoolExecutor(1) as ex:
        (ens,) = run_many([RunSpec(QUARTIC, "gauss-2", 0.0, Q0, V0, 0.05, 50, every)], where=ex)
    np.testing.assert_array_equal(ens.q, loop.q)
    assert [st["guard"] for st in ens.stats] == [True, True]



@pytest.mark.parametrize("chunk, every, calls", [(None, 1, [(300, 1)]), (128, 1, [(128, 1), (128, 1), (44, 1)]),
                                                 (None, 7, [(300, 7)])])
def test_a_run_shorter_than_the_chunk_is_one_kernel_call_keeping_its_samples(monkeypatch, chunk, every, calls):
    """``COMPILED_CHUNK`` promises that runs up to 2**18 steps are one kernel call (bit for bit the
    unchunked run: the predictor never restarts); every other test lowers the chunk, so a block
    of 2*18 = 36 steps went unseen (300 steps became 9 calls). The kernel keeps every
    ``save_every``-th sample itself (``CompiledEngine.samples``): with samples = False it stored
    every step for the driver to slice, the same numbers (which every other test compares) at
    save_every times the memory. Control: a chunk of 128 cuts the same run into 128 + 128 + 44.
    guard=False: the guard's rerun of the first steps (every step kept) is another call."""
    from ldaspark.engines import ENGINES
    seen = []
    real = ENGINES["compiled"].run

    def recording(prepared, start, n_steps, every):
        seen.append((n_steps, every))
        return real(prepared, start, n_steps, every)
    monkeypatch.setitem(vars(ENGINES["compiled"]), "run", recording)
    if chunk is not None:
        monkeypatch.setattr(chunks, "COMPILED_CHUNK", chunk)
    r = ldaspark.integrate(QUARTIC, "gauss-2", **dict(IC, h=0.01, n_steps=300, save_every=every, guard=False))
    assert r.status == 0 and len(r.t) == len(range(0, 300, every)) + 1 and seen == calls
