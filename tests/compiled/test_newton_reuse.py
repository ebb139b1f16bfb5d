"""The Newton matrix reused across steps while it contracts
(``run_compiled(reuse_matrix=True)``, kernels.REUSE_MATRIX). The counts are machine-independent:
Jacobians per step fall where the matrix changes slowly per step, stay ~1 where it does not (the
back-off), and the results agree with a fresh matrix per step to the Newton tolerance."""
import numpy as np
import pytest

from ldaspark.compiled.fast import compile_system, run_compiled
from ldaspark.core.errors import InputError
from ldaspark.models.scenes import get_scene


def _pair(scene, method, h, n, kernel="spark"):
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    a = run_compiled(cs, method, t0, q0, v0, h, n, n, kernel=kernel)
    b = run_compiled(cs, method, t0, q0, v0, h, n, n, kernel=kernel, reuse_matrix=True)
    d = max(np.abs(a.q[-1] - b.q[-1]).max(), np.abs(a.v[-1] - b.v[-1]).max())
    return a.stats, b.stats, d, cs.form


def test_reuse_where_the_matrix_changes_slowly():
    """robot, gauss-2, h = 1e-3, 2000 steps: one Jacobian in the whole run instead of one per
    step (measured 0.00 per step, 2.0 iterations per step either way), results equal to 1e-13
    (measured 3e-17 after 20000 steps)."""
    off, on, d, _ = _pair("robot", "gauss-2", 1e-3, 2000)
    assert off["njev"] == 2000 and on["njev"] <= 20
    assert on["mean_iterations"] <= off["mean_iterations"] + 0.5
    assert d <= 1e-13


def test_back_off_where_the_matrix_changes_fast():
    """particle, gauss-2, h = 0.05: a stale matrix contracts too slowly (theta > REUSE_THETA), so
    reuse is tried rarely: Jacobians per step stay >= 0.9 (measured 0.96) and iterations per step
    within 10% of the fresh-matrix run (measured 3.22 against 3.00). Negative control of the
    first test's count."""
    off, on, d, _ = _pair("particle", "gauss-2", 0.05, 2000)
    assert on["njev"] >= 0.9 * off["njev"] and on["mean_iterations"] <= 1.1 * off["mean_iterations"]
    assert d <= 1e-12


@pytest.mark.parametrize("scene", ["constant-speed", "relativistic"])
def test_reuse_on_the_general_kernel_sets_p0(scene):
    """General form (the momentum map implicit): a step starting from a reused matrix must still
    compute p0 = grad_v L(t0, q0, v0) (``kernels_general.general_begin``); same results as with a
    fresh matrix to 1e-12 over 2000 steps of h = 1e-3."""
    off, on, d, form = _pair(scene, "gauss-2", 1e-3, 2000)
    assert form == "general" and on["njev"] < 0.5 * off["njev"]
    assert d <= 1e-12


def test_semi_implicit_kernel_refuses_the_flag():
    # it factors its m x m matrix in every step: the flag is refused, not dropped (an option is
    # honoured or refused; tests/compiled/test_semi_implicit_kernel_options.py)
    with pytest.raises(InputError, match="engine 'compiled-lf2' refuses Newton reuse=True"):
        _pair("skate", "lobatto-iiia-iiib-2", 1e-3, 10, kernel="auto")


def test_auto_reuses_the_matrix_from_REUSE_AUTO_MIN_N_on():
    """reuse_matrix="auto": off for the paper's scenes (n <= 7: their runs keep one fresh matrix
    per step, so their results do not change), on for mp-particles-nh at n = 41 (Jacobians per
    step well below 1), with results equal to a fresh matrix per step to 1e-12."""
    from ldaspark.compiled import fast
    from ldaspark.models.scenes import mp_particles
    assert 7 < fast.REUSE_AUTO_MIN_N <= 41
    small = get_scene("mp-particles-nh")
    cs = compile_system(small.system)
    r = run_compiled(cs, "gauss-2", *small.initial(), 0.001, 500, 500)
    # one fresh matrix per step (a few more where an increment stalls at round-off)
    assert r.stats["reuse_matrix"] is False and 500 <= r.stats["njev"] <= 510
    big = mp_particles(m=20, constraint="nonholonomic")
    cb = compile_system(big.system)
    on = run_compiled(cb, "gauss-2", *big.initial(), 0.001, 500, 500)
    off = run_compiled(cb, "gauss-2", *big.initial(), 0.001, 500, 500, reuse_matrix=False)
    assert on.stats["reuse_matrix"] is True and on.stats["njev"] <= 0.5 * off.stats["njev"]
    assert np.abs(on.q[-1] - off.q[-1]).max() <= 1e-12
    from ldaspark.core.errors import InputError
    for bad in ("yes", np.array([1, 0]), None, 1):
        with pytest.raises(InputError, match="reuse_matrix"):
            run_compiled(cb, "gauss-2", *big.initial(), 0.001, 5, reuse_matrix=bad)


@pytest.mark.parametrize("kind", ["full", "mixed"])
def test_full_newton_refuses_matrix_reuse(kind):
    """Full Newton (and "mixed", which is full Newton in float64) forms the Newton matrix at every
    iteration: the kernel drops the reuse bit then (kernels.py: ``mode != 1``). Before,
    Newton(kind, reuse=True) on the compiled engine ran 1500 factorisations for 1500 iterations on a
    500-step run, bitwise the run of reuse=False, and stats["reuse_matrix"] said True: accepted and
    ignored. Now refused in one line, as the quasi kind and the semi-implicit kernel refuse it."""
    import ldaspark
    with pytest.raises(InputError, match=f"newton kind '{kind}' on the compiled engine: reuse=True is not honoured"):
        ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.1, engine="compiled",
                           newton=ldaspark.Newton(kind, reuse=True))
    r = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.1, engine="compiled", newton=ldaspark.Newton(kind))
    assert r.status == 0 and r.stats["reuse_matrix"] is False
