"""``run_many`` stops a member that crosses the singular set of the saddle matrix (4) as every
``integrate`` engine does (status -2 there, SingularSaddleError): the kernel tasks solve (21)
with no det (4) monitor and went on, on another branch, past the crossing in silence.

The system: L_vv = diag(1, -1) (indefinite), k = v2 - q1 v1, so det (4) = 1 - q1^2 changes sign
at q1 = 1; a nonideal term N = (-psi^2 v1 / 20, 0) (section 3.3, nonlinear in psi) lets Newton
converge on the step that crosses (without it Newton fails there, status -1, on every engine)."""
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.core.errors import SingularSaddleError
from ldaspark.ensemble import RunSpec

q1, q2, v1, v2, psi = sympy.symbols("q1 q2 v1 v2 psi1")
LORENTZ = ldaspark.LagrangianSystem(v1 ** 2 / 2 - v2 ** 2 / 2 - q1 ** 2 / 8, [v2 - q1 * v1], [q1, q2], [v1, v2],
                                    name="lorentz-nonideal", nonideal=[-psi ** 2 * v1 / 20, 0], psi=[psi])
Q0, V0, H = [0.5, 0.0], [1.0, 0.5], 0.05


def _many(n_steps, every=1):
    with ThreadPoolExecutor(1) as ex:
        return ldaspark.run_many([RunSpec(LORENTZ, "gauss-2", 0.0, [Q0, Q0], [V0, V0], H, n_steps, every=every)],
                                 where=ex)


@pytest.mark.parametrize("every", [1, 3])
def test_run_many_stops_a_member_that_crosses_the_singular_set_of_4(every):
    """Before the fix run_many returned all 30 steps (q1 past 1) with no error; integrate stops
    at step 8 (t = 0.4 -> 0.45) on every engine. Now run_many raises the same error class naming
    the spec, the member and the same step, also when save_every skips the step (every = 3)."""
    one = ldaspark.integrate(LORENTZ, "gauss-2", t_span=(0, 30 * H), q0=Q0, v0=V0, h=H, engine="compiled")
    assert one.status == -2 and "step 8 (t = 0.4 -> 0.45)" in one.message
    with pytest.raises(SingularSaddleError) as info:
        _many(30, every)
    msg = str(info.value)
    assert msg.startswith("run_many: spec 0 (gauss-2), member 0: step 8 (t = 0.4 -> 0.45) crossed the singular set "
                          "of the saddle matrix (4)"), msg


def test_run_many_before_the_crossing_is_unchanged():
    """Control: 8 steps end before the crossing: both members returned, equal to the single
    compiled run to rounding (the same kernel; tolerance 0: the same arithmetic)."""
    (ens,) = _many(8)
    one = ldaspark.integrate(LORENTZ, "gauss-2", t_span=(0, 8 * H), q0=Q0, v0=V0, h=H, engine="compiled")
    assert one.status == 0
    for r in range(2):
        np.testing.assert_array_equal(ens.q[r], np.asarray(one.q, float))


def test_integrate_ensemble_through_an_executor_gives_each_member_status_minus_2():
    """``integrate`` with (B, n) initial data and an executor (guard=False: the kernel tasks of
    ``run_ensemble``) catches the crossing that run_many now raises and runs the loop of single
    runs: every member ends with status -2 at step 8, as without an executor (the control)."""
    kw = dict(t_span=(0, 30 * H), q0=[Q0, Q0], v0=[V0, V0], h=H, guard=False)
    with ThreadPoolExecutor(1) as ex:
        pooled = ldaspark.integrate(LORENTZ, "gauss-2", executor=ex, **kw)
    loop = ldaspark.integrate(LORENTZ, "gauss-2", **kw)
    assert list(pooled.status) == list(loop.status) == [-2, -2]
    assert all("step 8 (t = 0.4 -> 0.45)" in m for m in pooled.message)
    np.testing.assert_array_equal(np.asarray(pooled.q, float), np.asarray(loop.q, float))
