"""Ensembles over concurrent.futures executors: the process pool (default and passed in), any
Executor subclass (the hook Dask's client.get_executor() uses), the generic fallback in
workers, and the Fig. 4 data contract on a short run."""
import concurrent.futures

import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.ensemble import ensemble_integrate
from ldaspark.core.errors import InputError
from ldaspark.compiled.fast import fast_integrate, precompile
from ldaspark.lab.reports.fig4 import FIG4_METHODS, figure4_data, fit_growth
from ldaspark.models.scenes import mp_particles
from ldaspark.core.system import LagrangianSystem

N_STEPS = 2000


@pytest.fixture(scope="module", autouse=True)
def compiled():
    """Compile in parallel processes first; the same list as test_fast_path.WARM, so whichever
    file runs first compiles for all three (test_kahan uses linear-3)."""
    return precompile([("particle", "gauss-2", "spark"), ("rolling-disk", "mp-lobatto-iiib-a-2", "auto"),
                       ("mp-particles", "mp-lobatto-iiib-a-2", "auto"),
                       ("linear-3", "lobatto-iiia-iiib-2", "auto")])


@pytest.fixture(scope="module")
def ics():
    scenes = [mp_particles(j=j) for j in (0, 4, 9)]
    Q0 = np.array([sc.initial()[1] for sc in scenes])
    V0 = np.array([sc.initial()[2] for sc in scenes])
    return scenes, Q0, V0


@pytest.fixture(scope="module")
def serial(ics):
    scenes, _, _ = ics
    return [fast_integrate(sc, "mp-lobatto-iiib-a-2", h=0.05, n_steps=N_STEPS, every=100) for sc in scenes]


class InlineExecutor(concurrent.futures.Executor):
    """Minimal third-party Executor (stands in for a cluster's executor): runs at submit."""

    def __init__(self):
        self.calls = 0

    def submit(self, fn, *args, **kwargs):
        self.calls += 1
        f = concurrent.futures.Future()
        f.set_result(fn(*args, **kwargs))
        return f


def check_same(res, serial):
    assert res.q.shape == (3, N_STEPS // 100 + 1, 7) and res.energy.shape == (3, N_STEPS // 100 + 1)
    for j, s in enumerate(serial):        # row order = order of the initial data
        assert np.array_equal(res.q[j], s.q) and np.array_equal(res.energy[j], s.energy)
    assert np.array_equal(res.t, serial[0].t)


def test_process_pool_matches_serial(ics, serial):
    scenes, Q0, V0 = ics
    with concurrent.futures.ProcessPoolExecutor(max_workers=2) as ex:
        res = ensemble_integrate(scenes[0].system, "mp-lobatto-iiib-a-2", 0.0, Q0, V0, 0.05, N_STEPS,
                                 every=100, executor=ex)
    check_same(res, serial)
    assert all(s["path"] == "fast" for s in res.stats)
    # negative control: the runs really differ from one another (no row duplicated)
    assert np.max(np.abs(res.q[0] - res.q[1])) > 1e-3


def test_default_executor_and_any_executor(ics, serial):
    scenes, Q0, V0 = ics
    res = ensemble_integrate(scenes[0].system, "mp-lobatto-iiib-a-2", 0.0, Q0, V0, 0.05, N_STEPS,
                             every=100, max_workers=2, chunk=2)
    check_same(res, serial)
    ex = InlineExecutor()
    res = ensemble_integrate(scenes[0].system, "mp-lobatto-iiib-a-2", 0.0, Q0, V0, 0.05, N_STEPS,
                             every=100, executor=ex)
    check_same(res, serial)
    assert ex.calls == 3


def test_generic_fallback_in_workers(capsys, monkeypatch):
    q = list(sympy.symbols("q1:4"))
    v = list(sympy.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 + v[0] ** 4 / 12 - (q[0] ** 2 + q[1] ** 2)
    # a system the code generator refuses (as it does an expression without numba translation):
    # the workers run the generic path
    sysm = LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="quartic", nonideal=[q[1] * v[0], 0, 0])
    import ldaspark.compiled.runner as runner     # compile_system looks general_source up there
    from ldaspark.compiled.codegen import NotCompilableError

    def refuse(system):
        raise NotCompilableError(f"{system.name}: an expression has no numba translation (refused here)")
    monkeypatch.setattr(runner, "general_source", refuse)
    Q0 = [[1.0, 0.0, 0.0], [0.5, 0.0, 0.0]]
    V0 = [[0.0, 1.0, 0.0], [0.0, 0.5, 0.0]]
    with concurrent.futures.ProcessPoolExecutor(max_workers=2) as ex:
        res = ensemble_integrate(sysm, "gauss-1", 0.0, Q0, V0, 0.1, 10, executor=ex)
    assert "falling back to the generic path" in capsys.readouterr().err
    assert all(s["path"] == "generic" for s in res.stats)
    assert np.max(np.abs(res.constraint)) < 1e-13 and res.q.shape == (2, 11, 3)


def test_bad_shapes(ics):
    scenes, Q0, V0 = ics
    with pytest.raises(InputError):
        ensemble_integrate(scenes[0].system, "mp-lobatto-iiib-a-2", 0.0, Q0[:, :3], V0, 0.05, 10)


def test_fig4_data_contract(serial):
    """Keys and values of figure4_data on a short run (J = 9 -> ICs j = 0..9 of which the
    serial fixture holds j = 0, 4, 9)."""
    d = figure4_data(t_end=100.0, h=0.05, J=9, every=100, executor=InlineExecutor())
    assert d["methods"] == list(FIG4_METHODS)
    assert abs(d["E0"] - 3.06) < 1e-14 and d["E0_spread"] < 1e-14
    assert len(d["t"]) == 21 and d["t"][-1] == pytest.approx(100.0)
    for name in FIG4_METHODS:
        assert len(d["mu_over_h4"][name]) == 21 and d["mu_over_h4"][name][0] < 1e-20
        assert set(d["fit"][name]) == {"exponent", "window"}
    # mu recomputed from the individual runs (3 of the 10 ICs here cover j = 0, 4, 9 only, so
    # recompute from all 10 with the serial path)
    E = np.array([fast_integrate(mp_particles(J=9, j=j), "mp-lobatto-iiib-a-2", h=0.05, n_steps=2000,
                                 every=100).energy for j in range(10)])
    mu = np.mean((E - d["E0"]) ** 2, axis=0) / 0.05 ** 4
    assert np.allclose(mu, d["mu_over_h4"]["mp-lobatto-iiib-a-2"], rtol=1e-12, atol=0)
    assert np.array_equal(E[[0, 4, 9]], np.array([s.energy for s in serial]))


def test_fit_growth_recovers_exponents():
    t = np.linspace(1, 1000, 500)
    assert fit_growth(t, 3 * t, [10, 1000]) == pytest.approx(1.0)
    assert fit_growth(t, 3 * np.ones_like(t), [10, 1000]) == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(InputError):
        fit_growth(t, t, [2000, 3000])


def test_members_run_with_the_summation_asked_for():
    # RunSpec(compensated=False) reaches the kernel tasks: each member is bit for bit the kernel
    # run with plain sums, which differs from the compensated one (the negative control: 2000
    # skate steps move the last bits of q)
    from concurrent.futures import ThreadPoolExecutor

    from ldaspark.compiled.fast import compile_system, kernel_spec
    from ldaspark.compiled.runner import run_kernels
    from ldaspark.ensemble import RunSpec, run_many
    sc = ldaspark.get_scene("skate")
    t0, q0, v0 = (float(sc.initial()[0]), np.array(sc.initial()[1], float), np.array(sc.initial()[2], float))
    cs, spec = compile_system(sc.system), kernel_spec("gauss-2", "auto")
    for comp in (False, True):
        with ThreadPoolExecutor(1) as ex:
            (ens,) = run_many([RunSpec(sc.system, "gauss-2", t0, [q0], [v0], 0.1, N_STEPS, 100, compensated=comp)],
                              where=ex, guard=False)
        ref = run_kernels(cs, spec, t0, q0, v0, 0.1, N_STEPS, 100, comp, None)
        other = run_kernels(cs, spec, t0, q0, v0, 0.1, N_STEPS, 100, not comp, None)
        assert np.array_equal(ens.q[0], ref.q) and not np.array_equal(ens.q[0], other.q), comp
