"""Rules of ``ldaspark.ensemble`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import numpy as np
import pytest
import ldaspark
from ldaspark.core.errors import InputError
import concurrent.futures as cf
from concurrent.futures import ThreadPoolExecutor

from ldaspark.ensemble import RunSpec
from ldaspark.core.errors import InputError
from system_fakes import _one_line, no_client  # noqa: F401 (pytest fixtures)


def _point():
    t0, q0, v0 = ldaspark.get_scene("skate").initial(None)
    return [float(x) for x in q0], [float(x) for x in v0]


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


def _skate_point():
    t0, q0, v0 = ldaspark.get_scene("skate").initial(None)
    return [float(x) for x in q0], [float(x) for x in v0]


# --- root 6: malformed Dask addresses -------------------------------------------------------------
BAD_ADDRESSES = ["x://y", "tcp://", "inproc://", "tcp://[::1", "tcp://:8786", "tcp://h:0", "tcp://h:99999",
                 "tcp://h:abc", "tcp://h:", "tcp://a b:1", "tcp://h/x", "tcp://u@h:1", "inproc://1.2.3.4/1/1"]


def test_runspec_and_run_many_check_their_arguments():
    from ldaspark.ensemble import RunSpec
    q0, v0 = _skate_point()
    with pytest.raises(InputError, match="system"):
        RunSpec(3, "gauss-2", 0, [q0], [v0], 0.1, 2)
    spec = RunSpec("skate", "gauss-2", 0, [q0], [v0], 0.1, 2)        # a scene name, as integrate takes
    assert spec.system is ldaspark.get_scene("skate").system
    with pytest.raises(InputError, match="list of RunSpec"):
        ldaspark.run_many(3)
    with pytest.raises(InputError, match="progress"):
        ldaspark.run_many([spec], progress=3)
    with pytest.raises(InputError, match="max_workers"):
        ldaspark.run_many([spec], max_workers=0)
    with pytest.raises(InputError, match="class"):
        ldaspark.run_many([spec], executor=cf.ThreadPoolExecutor)
    with pytest.raises(InputError, match="class"):
        ldaspark.run_many([spec], where=cf.ThreadPoolExecutor)
    seen = []
    with cf.ThreadPoolExecutor(1) as ex:
        out = ldaspark.run_many([spec], executor=ex, progress=lambda k, n: seen.append((k, n)))
    assert out[0].q.shape == (1, 3, 3) and seen == [(1, 1)]


def test_steps_that_do_not_advance_t_are_refused():
    with pytest.raises(InputError, match="does not advance t") as ei:
        ldaspark.integrate("skate", "gauss-1", t0=1e17, h=1, n_steps=64)
    _one_line(ei)
    with pytest.raises(InputError, match="does not advance t"):
        ldaspark.integrate("skate", "gauss-1", t0=1.0, h=1e-17, n_steps=2, engine="generic")
    from ldaspark.ensemble import RunSpec
    q0, v0 = _skate_point()
    with pytest.raises(InputError, match="does not advance t"):
        RunSpec("skate", "gauss-2", 1e17, [q0], [v0], 1.0, 4)
    with pytest.raises(InputError, match="does not advance t"):
        ldaspark.integrate("skate", "gauss-1", t0=1, h="1e-25", n_steps=1, dps=20, engine="generic")
    # neighbours: a step the numbers near t resolve, in float64 and at 40 digits
    res = ldaspark.integrate("skate", "gauss-1", t0=1e17, h=64, n_steps=4, engine="generic")
    assert len(set(res.t.tolist())) == 5 and res.status == 0
    res = ldaspark.integrate("skate", "gauss-1", t0=1, h="1e-25", n_steps=1, dps=40, engine="generic")
    assert res.status == 0 and res.t[1] > res.t[0]


@pytest.mark.parametrize("addr", BAD_ADDRESSES)
def test_malformed_addresses_refused_at_once(addr, no_client):
    from ldaspark.ensemble import RunSpec
    from ldaspark.executors import check_where
    with pytest.raises(InputError, match="malformed Dask scheduler address") as ei:
        check_where(addr)
    _one_line(ei)
    q0, v0 = _skate_point()
    spec = RunSpec("skate", "gauss-2", 0, [q0], [v0], 0.1, 2)
    with pytest.raises(InputError, match="malformed"):
        ldaspark.run_many([spec], where=addr)
    assert no_client == []


class _PoolMade(Exception):
    pass


def test_max_workers_sizes_the_local_pool_or_is_refused(monkeypatch):
    # max_workers was ignored with where="local" (the pool had os.cpu_count() workers) and with an
    # executor of the caller's (which runs the tasks on its own workers). The local pool's size is
    # seen without starting processes: a pool of one is the inline executor, larger ones are made
    # by make_process_pool (patched to record its size and stop). cpu_count is patched to 4, so
    # the test does not depend on the machine.
    from ldaspark import executors
    made = []

    def pool(n, **kw):
        made.append(n)
        raise _PoolMade
    monkeypatch.setattr(executors.os, "cpu_count", lambda: 4)
    monkeypatch.setattr(executors, "make_process_pool", pool)
    sc = ldaspark.get_scene("skate")
    t0, q0, v0 = sc.initial(None)
    spec = RunSpec(sc.system, "gauss-2", t0, [q0], [v0], 0.1, 3)
    # five members, five units: a pool is no larger than its units (probe t17), so the sizes asked
    # for here (4, 3) are reached
    five = RunSpec(sc.system, "gauss-2", t0, [q0] * 5, [v0] * 5, 0.1, 3)
    with pytest.raises(_PoolMade):                      # control: the default local pool, all 4 "cores"
        ldaspark.run_many([five], where="local")
    with pytest.raises(_PoolMade):
        ldaspark.run_many([five], where="local", max_workers=3)
    assert made == [4, 3]
    (out,) = ldaspark.run_many([spec], where="local", max_workers=1)      # inline: no pool
    assert made == [4, 3] and out.q.shape == (1, 4, 3)
    with ThreadPoolExecutor(1) as ex:
        with pytest.raises(InputError, match="max_workers sizes the local process pool"):
            ldaspark.run_many([spec], where=ex, max_workers=2)
        with pytest.raises(InputError, match="max_workers sizes the local process pool"):
            ldaspark.run_many([spec], executor=ex, max_workers=2)
        assert ldaspark.run_many([spec], where=ex)[0].q.shape == (1, 4, 3)       # control: no max_workers
