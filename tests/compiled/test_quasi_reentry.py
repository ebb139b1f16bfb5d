"""The curvature block's refresh as a re-entry of ``kernels_quasi.quasi_steps``: the steps run in
one call that is left only when the frozen Hess U needs a new decomposition; ``quasi_loop`` runs
``curvature_refresh`` and re-enters at that step with istate[IS_REFRESHED] set. The state carried
across the re-entry (istate, fstate) must make the run the one of a single loop:

* a refreshed step is counted once, decomposes once and starts without a carried rate (another
  frozen block: ``quasi_newton``'s eta is reset), so it is never a ``rate_first_steps`` step;
* the wait and back-off after failed attempts (QS_SKIPPED) continue across refreshes.

A Hessian that is stale at every step: the particle of 8.1 with a free coordinate q4 (q4 = v4 = 0
stays so: its force is -g(t) q4 = 0) and U = q1^2 + q2^2 + g(t) q4^2 / 2, g = 3 + 2 sin(pi t / h):
at the step midpoints t_k + h / 2, g alternates 5, 1, 5, ... (|H - H_frozen| = 4 > CURV_STALE_REL
|H| = 1.25), so every step refreshes, while the motion (q1, q2, q3) is that of the particle and the
carried rate accepts first increments at a loose tol (the control: g = 3, one refresh).

Tolerance of the trajectory comparison: that of tests/compiled/test_kernels_quasi.py (both root
finders stop at lim = tol (|x| + |v0|) <= 8 eps scale: N steps differ by at most 2 N 8 eps scale).
"""
import numpy as np
import pytest
import sympy

from ldaspark.compiled import kernels_quasi as KQ
from ldaspark.compiled.fast import compile_system, run_compiled
from ldaspark.compiled.quasi import run_quasi
from ldaspark.core.system import LagrangianSystem

EPS = float(np.finfo(float).eps)
N = 30                      # < CURV_WARMUP: the curvature block is never switched off here

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def _difference(a, b):
    """max |dq|, |dv| over the run in units of 2 N * 8 eps * scale (the module docstring's bound)."""
    scale = max(1.0, float(np.abs(a.q).max()), float(np.abs(a.v).max()))
    d = max(float(np.abs(a.q - b.q).max()), float(np.abs(a.v - b.v).max()))
    return d / (2 * len(a.t) * 8 * EPS * scale)


def _particle_with_free_coordinate(h, alternating):
    t = sympy.Symbol("t")
    q, v = list(sympy.symbols("q1:5")), list(sympy.symbols("v1:5"))
    g = 3 + 2 * sympy.sin(sympy.pi * t / sympy.Rational(h)) if alternating else sympy.Integer(3)
    U = q[0] ** 2 + q[1] ** 2 + g * q[3] ** 2 / 2
    L = sum(vi ** 2 for vi in v) / 2 - U
    return compile_system(LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, t=t,
                                           name=f"particle-q4-{h}-{'alternating' if alternating else 'constant'}"))


@pytest.mark.parametrize("method, h, tol", [("gauss-2", 0.1, 1e-3), ("gauss-4", 0.1, 1e-6)])
def test_a_refreshed_step_is_counted_once_and_never_uses_the_carried_rate(method, h, tol):
    """Every step refreshes: curvature_refreshes = curvature_steps = N (one count per step), nlu =
    multiplier_lu + n per refresh (no fallback), and no step is accepted on the carried rate
    (rate_first_steps = 0). Measured with the rate kept across the re-entry (``refreshes -= 1``
    dropped in quasi_steps): 23 and 19 of the 30 steps accepted on it, and a refresh counted twice
    or a re-entry flag never cleared break the counts. Control: g constant, one refresh, and the
    same run accepts steps on the carried rate (so the zero above is evidence). The run with a
    refresh at every step agrees with the Newton engine within the bound."""
    cs = _particle_with_free_coordinate(h, True)
    q0, v0 = [1, 0, 0, 0], [0, 1, 0, 0]
    st = run_quasi(cs, method, 0.0, q0, v0, h, N, tol=tol).stats
    assert st["quasi_fallbacks"] == 0 and st["quasi_steps"] == N, st
    assert st["curvature_refreshes"] == st["curvature_steps"] == N, st
    assert st["nlu"] == st["multiplier_lu"] + cs.n * st["curvature_refreshes"], st
    assert st["rate_first_steps"] == 0, st
    ctl = run_quasi(_particle_with_free_coordinate(h, False), method, 0.0, q0, v0, h, N, tol=tol).stats
    assert ctl["curvature_refreshes"] == 1 and ctl["curvature_steps"] == N, ctl
    assert ctl["rate_first_steps"] > 0, ctl
    a = run_compiled(cs, method, 0.0, q0, v0, h, N, 1, kernel="spark")
    b = run_quasi(cs, method, 0.0, q0, v0, h, N)
    assert b.stats["curvature_refreshes"] == N
    assert _difference(a, b) <= 1.0


def _stiff_quartic():
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    r2 = q[0] ** 2 + q[1] ** 2
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - (5000 * r2 + 2000 * r2 ** 2)
    return compile_system(LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="stiff-quartic-particle"))


def _quartic():
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    r2 = q[0] ** 2 + q[1] ** 2
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - (r2 + r2 ** 2 / 4)
    return compile_system(LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="quartic-particle-1/4"))


def _waits(n_steps):
    """(attempts, skipped) of ``quasi_steps``' wait rule when every attempt fails: after a failure
    the next `wait` steps go to the Newton chain, wait = backoff, backoff doubling up to
    QUASI_WAIT_MAX (a Python model of IS_WAIT / IS_BACKOFF)."""
    wait, backoff, attempts, skipped = 0, 1, 0, 0
    for _ in range(n_steps):
        if wait > 0:
            wait -= 1
            skipped += 1
        else:
            attempts += 1
            wait, backoff = backoff, min(2 * backoff, KQ.QUASI_WAIT_MAX)
    return attempts, skipped


def test_the_wait_after_failed_attempts_continues_across_refreshes():
    """A stiff varying spring, U = 5000 r^2 + 2000 r^4 (r^2 = q1^2 + q2^2), gauss-2, h = 0.2: no
    quasi-Newton attempt converges (every step is solved by the Newton chain) and the curvature
    block is refreshed at several attempts; the waits between attempts are those of the doubling
    rule all the same (exact: 300 steps, 10 attempts, 290 skipped; measured 6 refreshes). Measured
    with the back-off reset at a re-entered step (istate[IS_BACKOFF] = 1 there): 26 attempts, 274
    skipped, 16 refreshes. Control of the model: the same rule with the curvature off (no refresh)."""
    cs = _stiff_quartic()
    n = 300
    attempts, skipped = _waits(n)
    assert (attempts, skipped) == (10, 290)
    for curvature in (True, False):
        st = run_quasi(cs, "gauss-2", 0.0, [1, 0, 0], [0, 1, 0], 0.2, n, curvature=curvature).stats
        assert st["quasi_steps"] == 0 and st["quasi_fallbacks"] == n, st
        assert (curvature and st["curvature_refreshes"] >= 2) or (not curvature and st["curvature_refreshes"] == 0), st
        assert st["quasi_skipped"] == skipped and st["multiplier_lu"] == attempts, st


@pytest.mark.parametrize("which, h, n_steps, every", [("quartic", 0.2, 300, 1), ("quartic", 1.0, 100, 3),
                                                      ("stiff", 0.2, 120, 1)])
def test_the_specialised_kernel_returns_the_same_bits_across_refreshes(which, h, n_steps, every):
    """The kernel specialised to (s, n, m) = (2, 3, 1) (``specialised``: kernels_quasi's text with
    the sizes as constants, the re-entry included) against the generic one, every output and
    counter equal, on runs that re-enter quasi_steps many times: U = r^2 + r^4 / 4 at h = 0.2 (16
    refreshes, then the M-only block after CURV_WARMUP) and at h = 1 with save_every = 3 (refreshes
    between fallbacks and waits: 12 refreshes, 94 fallbacks, 78 skipped), the stiff quartic
    (refreshes at failed attempts, every step by the Newton chain), t0 = 0.7. Control: the
    comparison sees the last-bit change of Kahan summation off."""
    from ldaspark.compiled import specialised as SP
    ep = SP.build(2, 3, 1)
    cs = _quartic() if which == "quartic" else _stiff_quartic()
    out = []
    for e, comp in ((None, True), (ep, True), (None, False)):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(SP, "kernel", lambda *a, e=e: e)
            mp.setattr(SP, "note", lambda *a: None)
            out.append(run_quasi(cs, "gauss-2", 0.7, [1, 0, 0], [0, 1, 0], h, n_steps, every, comp))
    gen, spec, ctl = out
    assert spec.stats["kernel_specialised"] and not gen.stats["kernel_specialised"]
    assert gen.stats["curvature_refreshes"] >= 6, gen.stats

    def same(a, b):
        arrays = all(np.array_equal(getattr(a, f), getattr(b, f))
                     for f in ("t", "q", "v", "energy", "constraint", "psi"))
        keys = set(a.stats) - {"kernel_specialised"}
        return arrays and all(a.stats[k] == b.stats[k] for k in keys)

    assert same(gen, spec)
    assert not same(gen, ctl)


def _particle_with_an_overflowing_hessian():
    """The particle of 8.1 with the free coordinate q4 of stiffness g(t) = 1 + exp(800 - 10^6 (t - 9/8)^2):
    Hess U has g = inf (exp overflows) at t = 9/8 and g = 1 at the stage times of a step of h = 0.25
    whose midpoint is 9/8 (10^6 ((c_i - 1/2) h)^2 >= 5200 for gauss-2), so the step itself is that of
    the particle (q4 = v4 = 0 stays so) while ``curvature_refresh`` sees a Hessian that is not finite."""
    t = sympy.Symbol("t")
    q, v = list(sympy.symbols("q1:5")), list(sympy.symbols("v1:5"))
    g = 1 + sympy.exp(800 - 10 ** 6 * (t - sympy.Rational(9, 8)) ** 2)
    L = sum(vi ** 2 for vi in v) / 2 - (q[0] ** 2 + q[1] ** 2 + g * q[3] ** 2 / 2)
    return compile_system(LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, t=t, name="particle-q4-overflow"))


@pytest.mark.parametrize("method", ["gauss-2", "gauss-4"])
def test_a_failed_refresh_leaves_its_step_to_the_mass_block_and_the_next_step_refreshes(method):
    """t0 = 1, h = 0.25: step 0's midpoint is t = 9/8, its Hessian not finite, so the first
    decomposition fails (counted, no LU factored: nlu = multiplier_lu); the re-entered step runs
    the M-only block (curvature_steps 0) and converges without the Newton chain; step 1 decomposes
    again (2 refreshes, n = 4 LUs) and the remaining steps use it. Measured with the re-entered step
    using the curvature block whatever the refresh returned: the zero block's S is singular and the
    step falls back. Control: t0 = 0, the pole at step 4's midpoint, where a frozen block exists:
    |H - H_frozen| = inf is not above CURV_STALE_REL |H| = inf, the block is kept (one refresh, every
    step a curvature step). The trajectory is the Newton engine's within the bound."""
    cs = _particle_with_an_overflowing_hessian()
    q0, v0 = [1, 0, 0, 0], [0, 1, 0, 0]
    one = run_quasi(cs, method, 1.0, q0, v0, 0.25, 1).stats
    assert one["curvature_refreshes"] == 1 and one["curvature_steps"] == 0, one
    assert one["quasi_steps"] == 1 and one["quasi_fallbacks"] == 0 and one["nlu"] == one["multiplier_lu"] == 1, one
    n = 40
    b = run_quasi(cs, method, 1.0, q0, v0, 0.25, n)
    st = b.stats
    assert st["curvature_refreshes"] == 2 and st["curvature_steps"] == n - 1, st
    assert st["quasi_fallbacks"] == 0 and st["nlu"] == st["multiplier_lu"] + cs.n, st
    a = run_compiled(cs, method, 1.0, q0, v0, 0.25, n, 1, kernel="spark")
    assert _difference(a, b) <= 1.0
    ctl = run_quasi(cs, method, 0.0, q0, v0, 0.25, n).stats
    assert ctl["curvature_refreshes"] == 1 and ctl["curvature_steps"] == n, ctl
