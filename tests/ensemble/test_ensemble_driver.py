"""Ensembles through ``ldaspark.integrate``'s driver: dense output per member, and an executor
that fails in its own way is one LdasparkError."""
from concurrent.futures import Executor, ThreadPoolExecutor

import numpy as np
import pytest

import ldaspark
from ldaspark.core.errors import LdasparkError

SK = ldaspark.get_scene("skate")
Q0 = [list(SK.q0), [float(SK.q0[0]) + 0.1] + list(SK.q0[1:])]
V0 = [list(SK.v0), list(SK.v0)]


def test_dense_output_per_member():
    res = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.1, q0=Q0, v0=V0, dense_output=True,
                             engine="generic")
    assert res.sol is not None
    q, v = res.sol(0.55)
    assert q.shape == (2, 3) and v.shape == (2, 3)
    for j in range(2):     # each row is that member's own dense output (the same numbers)
        qj, vj = res.members[j].sol(0.55)
        assert np.array_equal(q[j], qj) and np.array_equal(v[j], vj)
    assert not np.allclose(q[0], q[1])        # the members differ (negative control of the rows)
    plain = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.1, q0=Q0, v0=V0, engine="generic")
    assert plain.sol is None


class _NoneExecutor(Executor):
    def submit(self, fn, *args, **kwargs):
        return None


class _RaisingExecutor(Executor):
    def submit(self, fn, *args, **kwargs):
        raise OSError("cluster unreachable")


class _WrongExecutor(ThreadPoolExecutor):
    # its futures resolve to None (the members go through submit, as run_many's units, not map)
    def submit(self, fn, *args, **kwargs):
        return super().submit(lambda: None)


@pytest.mark.parametrize("ex", [_NoneExecutor(), _RaisingExecutor(), _WrongExecutor(1)],
                         ids=["submit-None", "submit-raises", "not-a-Result"])
def test_a_failing_executor_is_one_error(ex):
    with pytest.raises(LdasparkError, match="executor"):
        ldaspark.integrate("skate", "gauss-2", t_span=(0, 0.2), h=0.1, params=[{}, {}], executor=ex,
                           engine="generic")
    # negative control: a working executor runs the same ensemble
    with ThreadPoolExecutor(1) as good:
        ok = ldaspark.integrate("skate", "gauss-2", t_span=(0, 0.2), h=0.1, params=[{}, {}], executor=good,
                                engine="generic")
    assert list(ok.status) == [0, 0]
