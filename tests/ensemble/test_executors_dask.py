"""Work on a real Dask cluster (``distributed.LocalCluster``, 2 worker processes) and on the local
pool: one way to name where work runs (``ldaspark.executors``), shared by ensembles, the
claims ledger, the mutation catalogue and the main job. Results must equal the serial run's
(records field by field, trajectories bit for bit), a killed worker must lose nothing, and a
rerun resumes from what an interrupted run finished. Skipped only without the ``dist`` extra
(``.ci/run`` installs it)."""
import functools
import json
import os
import signal
import sys
import time

import numpy as np
import pytest

from ldaspark.core.errors import InputError, LdasparkError
from ldaspark.executors import InlineExecutor, Unit, UnitsFailed, run_units
from ldaspark.lab.checkpoint import Checkpoint, run_resumable, source_fingerprint

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def client():
    import cloudpickle
    # this module's helper functions go to the workers by value (the workers cannot import it)
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=50)
    c = distributed.Client(cluster, set_as_default=False)
    try:
        yield c
    finally:
        c.close()
        cluster.close()
        cloudpickle.unregister_pickle_by_value(sys.modules[__name__])


# --- helpers that run in the workers --------------------------------------------------------------
def _square(x):
    return x * x


def _die_once(flag, value):
    """Kill this worker process the first time (the flag file marks it), return ``value`` after."""
    if not os.path.exists(flag):
        with open(flag, "w") as fh:
            fh.write(str(os.getpid()))
        os.kill(os.getpid(), signal.SIGKILL)
    return value


def _always_die():
    os.kill(os.getpid(), signal.SIGKILL)


def _count_and_return(path, value, fail_flag=None):
    """Append one line to ``path`` per call; raise while ``fail_flag`` exists."""
    with open(path, "a") as fh:
        fh.write(f"{value}\n")
    if fail_flag is not None and os.path.exists(fail_flag):
        raise ValueError(f"unit {value} fails while {os.path.basename(fail_flag)} exists")
    return {"value": value}


def _sleep(x):
    time.sleep(x)
    return x


# --- ensembles -------------------------------------------------------------------------------------
def test_ensemble_on_the_cluster_equals_the_serial_run_bit_for_bit(client):
    from ldaspark.ensemble import RunSpec, run_many
    from ldaspark.models.scenes import get_scene
    sc = get_scene("skate")
    Q0 = np.array([np.asarray(sc.q0, dtype=float) + 0.01 * j for j in range(4)])
    V0 = np.array([np.asarray(sc.v0, dtype=float) for _ in range(4)])
    specs = [RunSpec(sc.system, "gauss-2", 0.0, Q0, V0, 0.05, 200, every=10),
             RunSpec(sc.system, "lobatto-iiia-iiib-2", 0.0, Q0[:2], V0[:2], 0.05, 100, every=10)]
    serial = run_many(specs, executor=InlineExecutor())
    for where in (client, client.scheduler.address):
        dist = run_many(specs, where=where)
        for a, b in zip(serial, dist):
            for f in ("t", "q", "v", "energy", "constraint"):
                assert np.array_equal(getattr(a, f), getattr(b, f)), f
            assert a.stats == b.stats
    # control: a different initial datum gives different arrays (the comparison can fail)
    other = run_many([RunSpec(sc.system, "gauss-2", 0.0, Q0 + 1e-9, V0, 0.05, 200, every=10)], executor=InlineExecutor())
    assert not np.array_equal(other[0].q, serial[0].q)


def test_parameter_list_and_dense_ensembles_run_on_process_pools_and_clusters(client):
    # "Can't pickle local object" before: the members were a closure, the tableau's builder a lambda
    import concurrent.futures as cf
    import sympy
    import ldaspark
    x, y, vx, vy, m = sympy.symbols("x y vx vy m")
    sysm = ldaspark.LagrangianSystem(m * (vx**2 + vy**2) / 2 - y, [vx - y * vy], [x, y], [vx, vy], params=[m])
    kw = dict(t_span=(0, 0.5), q0=[0.0, 1.0], v0=[1.0, 1.0], h=0.05, engine="generic", dense_output=True)
    plist = [{"m": 1.0}, {"m": 2.0}, {"m": 3.0}]
    loop = ldaspark.integrate(sysm, "gauss-2", params=plist, **kw)
    with cf.ProcessPoolExecutor(2) as ex:
        pool = ldaspark.integrate(sysm, "gauss-2", params=plist, executor=ex, **kw)
    dist = ldaspark.integrate(sysm, "gauss-2", params=plist, executor=client.get_executor(), **kw)
    for r in (pool, dist):
        assert np.array_equal(r.q, loop.q) and np.array_equal(r.v, loop.v) and np.array_equal(r.psi, loop.psi)
    assert not np.array_equal(loop.q[0], loop.q[1])      # the members differ: the check can fail


# --- the claims ledger and the catalogue ----------------------------------------------------------
def _strip(recs):
    return [{k: v for k, v in r.items() if k != "seconds"} for r in recs]


def test_ledger_slice_on_the_cluster_equals_the_serial_run(client):
    from ldaspark.lab.claims.ledger import run_ledger
    kw = dict(max_s=1, scenes=("particle",), perturbed=False, holonomic=False, controls=False)
    serial = run_ledger(jobs=1, **kw)
    dist = run_ledger(where=client, **kw)
    assert len(serial) > 10
    assert _strip(serial) == _strip(dist)


def test_verify_cli_with_a_scheduler_writes_the_local_report(client, tmp_path, monkeypatch, capsys):
    # the CLI path of `ldaspark verify --scheduler`, on a slice of the quick ledger (the units
    # carry their options to the workers, so the slice is the same there)
    from ldaspark import cli
    from ldaspark.lab.reports import claims
    small = functools.partial(claims.run_ledger, max_s=1, scenes=("particle",), groups=())
    monkeypatch.setattr(claims, "run_ledger", lambda **kw: small(**{k: v for k, v in kw.items()
                                                                    if k not in ("max_s", "scenes", "groups")}))
    assert cli.main(["verify", "--quick", "--jobs", "1", "--outdir", str(tmp_path / "local")]) == 0
    assert cli.main(["verify", "--quick", "--scheduler", client.scheduler.address,
                     "--outdir", str(tmp_path / "dask")]) == 0
    a = json.loads((tmp_path / "local" / "claims-quick.json").read_text())
    b = json.loads((tmp_path / "dask" / "claims-quick.json").read_text())
    assert _strip(a) == _strip(b) and len(a) > 5
    assert not (tmp_path / "dask" / "claims-quick.partial.jsonl").exists()   # removed once written


@pytest.mark.exhaustive
def test_three_catalogue_faults_killed_on_the_cluster(client, tmp_path):
    from ldaspark.lab.mutants.mutation import by_id, run_catalogue
    targets = {
        "cond-22b-index-order": ["verification/test_conditions_22_23.py::test_22a_22b_23_families[gauss-2]"],
        "orders-pairwise-log2": ["tests/lab/theory/test_orders_estimates.py::test_pairwise_orders_with_step_ratio_3"],
        "system-K-at-v0": ["verification/test_equations_21.py::test_ivp_step_solves_21_as_printed[general-2]"],
    }
    recs = run_catalogue([by_id(k) for k in targets], where=client, targets=targets)
    assert [r["mutant"] for r in recs] == list(targets)
    assert all(r["status"] == "killed" for r in recs), recs
    for r in recs:
        assert r["first_failing_test"].startswith(targets[r["mutant"]][0].split("[")[0])


# --- faults ----------------------------------------------------------------------------------------
def test_a_worker_killed_mid_run_loses_nothing_on_the_cluster(client, tmp_path):
    flag = str(tmp_path / "died")
    units = [Unit(f"sq{i}", _square, (i,)) for i in range(6)] + [Unit("dies-once", _die_once, (flag, 42))]
    res = run_units(units, where=client)
    assert os.path.exists(flag)                   # the worker did die under the unit
    assert res == {**{f"sq{i}": i * i for i in range(6)}, "dies-once": 42}


def test_a_worker_killed_mid_run_loses_nothing_on_the_local_pool(tmp_path):
    flag = str(tmp_path / "died")
    units = [Unit(f"sq{i}", _square, (i,)) for i in range(6)] + [Unit("dies-once", _die_once, (flag, 42))]
    res = run_units(units, where=None, jobs=2)
    assert os.path.exists(flag)
    assert res == {**{f"sq{i}": i * i for i in range(6)}, "dies-once": 42}


def test_a_unit_that_always_kills_its_worker_is_reported_by_name_and_the_rest_kept():
    units = [Unit(f"sq{i}", _square, (i,)) for i in range(4)] + [Unit("killer", _always_die, ())]
    with pytest.raises(UnitsFailed, match="killer") as ei:
        run_units(units, where=None, jobs=2, retries=1)
    assert list(ei.value.failed) == ["killer"] and "worker lost 2 times" in ei.value.failed["killer"]
    assert ei.value.results == {f"sq{i}": i * i for i in range(4)}
    assert isinstance(ei.value, LdasparkError)


def test_an_error_in_a_unit_is_not_retried_and_names_the_unit(tmp_path):
    calls, flag = tmp_path / "calls", tmp_path / "fail"
    flag.write_text("")
    units = [Unit("good", _count_and_return, (str(calls), 1)), Unit("bad", _count_and_return, (str(calls), 2, str(flag)))]
    with pytest.raises(UnitsFailed, match=r"bad: ValueError: unit 2 fails") as ei:
        run_units(units, where=None, jobs=1)
    assert ei.value.results == {"good": {"value": 1}}
    assert calls.read_text().split() == ["1", "2"]          # once each: an error is not retried


def test_a_rerun_resumes_from_the_checkpoint_of_a_failed_run(tmp_path):
    calls, flag = tmp_path / "calls", tmp_path / "fail"
    flag.write_text("")
    units = [Unit(f"u{i}", _count_and_return, (str(calls), i, str(flag) if i == 2 else None)) for i in range(4)]
    ck = Checkpoint(tmp_path / "run.partial.jsonl", source_fingerprint("test", 1))
    with pytest.raises(UnitsFailed):
        run_resumable(units, ck, where=None, jobs=1)
    assert sorted(calls.read_text().split()) == ["0", "1", "2", "3"]
    flag.unlink()
    calls.write_text("")
    res = run_resumable(units, ck, where=None, jobs=1)
    assert calls.read_text().split() == ["2"]                # only the failed unit ran again
    assert res == {f"u{i}": {"value": i} for i in range(4)}
    # control: another fingerprint (other code or options) resumes nothing
    calls.write_text("")
    run_resumable(units, Checkpoint(tmp_path / "run.partial.jsonl", source_fingerprint("test", 2)), where=None, jobs=1)
    assert sorted(calls.read_text().split()) == ["0", "1", "2", "3"]


def test_a_checkpoint_path_that_is_not_a_regular_file_is_refused(tmp_path):
    target = tmp_path / "notes.txt"
    target.write_text("keep me")
    link = tmp_path / "run.partial.jsonl"
    link.symlink_to(target)
    with pytest.raises(InputError, match="not a regular file"):
        run_resumable([Unit("a", _square, (2,))], Checkpoint(link, "f"), where=None, jobs=1)
    assert target.read_text() == "keep me"


def test_ctrl_c_cancels_the_clusters_futures(client):
    units = [Unit(f"s{i}", _sleep, (0.2 if i == 0 else 30.0,)) for i in range(6)]

    def interrupt(name, val):
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        run_units(units, where=client, on_done=interrupt)
    # the 30 s sleepers are cancelled on the scheduler (polled; the bound is far above the
    # cancellation's few round trips and far below the 5 x 30 s of queued work)
    n = None
    for _ in range(200):
        n = client.run_on_scheduler(lambda dask_scheduler: sum(
            1 for ts in dask_scheduler.tasks.values() if "_sleep" in str(ts.key)))
        if n == 0:
            break
        time.sleep(0.1)
    assert n == 0


def test_where_is_validated():
    with pytest.raises(InputError, match="where work runs"):
        run_units([Unit("a", _square, (1,))], where=42)
    for jobs in (0, -3, True, 1.5):
        with pytest.raises(InputError, match="jobs must be a positive integer"):
            run_units([Unit("a", _square, (1,))], where=None, jobs=jobs)
    with pytest.raises(InputError, match="unique"):
        run_units([Unit("a", _square, (1,)), Unit("a", _square, (2,))])


def test_ctrl_c_in_verify_says_where_the_finished_units_are(monkeypatch, capsys):
    # the ledger and the catalogue keep a checkpoint: "no partial output" would be wrong there
    from ldaspark import cli
    from ldaspark.lab.reports import claims

    def interrupted(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(claims, "run_verify", interrupted)
    rc = cli.main(["verify", "--quick"])
    err = capsys.readouterr().err
    assert rc != 0 and "partial.jsonl" in err and "no partial output" not in err
    assert len(err.strip().splitlines()) == 1
