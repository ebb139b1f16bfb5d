"""Nonideal constraints (3.3) in LagrangianSystem and the SPARK step: the term h N(T, Q, V,
Lambda / h) in the stage reactions, its Jacobians in the Newton matrix (against central
differences of the residual), the ODE (3a) with N, and the places that must refuse N."""
import numpy as np
import pytest
import sympy

from ldaspark.core.backend import Backend
from ldaspark.core.errors import SystemDefinitionError
from ldaspark.core.families import get_method
from ldaspark.models.scenes import get_scene
from ldaspark.core.spark import SparkMethod, integrate
from ldaspark.core.system import LagrangianSystem


def _newton_matrix_error(system, method):
    """max |J - central differences of G| / max |J| at a generic packed point (float64)."""
    sm = SparkMethod(system, get_method(method))
    bk = sm.backend
    rng = np.random.default_rng(0)
    t0, q0, v0 = 0.1, np.array([0.1, -0.2, 0.3]), np.array([0.2, 0.1, 0.9])
    p0 = system.momentum(bk, t0, q0, v0)
    x = sm.initial_guess(v0) + 0.1 * rng.standard_normal(sm.size)
    h = 0.1
    _, J, _ = sm.residual(t0, q0, p0, h, x)
    fd = np.zeros_like(J)
    d = 1e-6
    for k in range(sm.size):
        e = np.zeros(sm.size)
        e[k] = d
        fd[:, k] = (sm.residual(t0, q0, p0, h, x + e, False)[0] - sm.residual(t0, q0, p0, h, x - e, False)[0]) / (2 * d)
    return np.abs(J - fd).max() / np.abs(J).max()


@pytest.mark.parametrize("method", ["gauss-2", "lobatto-iiia-iiib-iiid-3"])
def test_newton_matrix_with_nonideal_term_matches_differences(method):
    S = get_scene("friction-skate").system
    assert _newton_matrix_error(S, method) < 1e-8


def test_newton_matrix_control_without_N_psi():
    """Control: dropping N_psi from d(h R)/dLambda (treating N as psi-independent) is detected."""
    S = get_scene("friction-skate").system
    orig = S._add_nonideal

    def no_npsi(backend, st, *a):
        orig(backend, st, *a)
        if st.R_L is not None:
            st.R_L = -st.k_v.T
    S._add_nonideal = no_npsi
    try:
        assert _newton_matrix_error(S, "gauss-2") > 1e-4
    finally:
        del S._add_nonideal


def test_nonideal_term_changes_the_step_and_zero_N_does_not():
    sk = get_scene("skate")
    q, v = sk.system.q, sk.system.v
    zero = LagrangianSystem(sk.system.L, list(sk.system.k), q, v, nonideal=[0, 0, 0], name="skate-N0")
    fr = get_scene("friction-skate")
    t0, q0, v0 = sk.initial()
    a = integrate(sk.system, get_method("gauss-2"), t0, q0, v0, 0.1, n_steps=3)
    b = integrate(zero, get_method("gauss-2"), t0, q0, v0, 0.1, n_steps=3)
    c = integrate(fr.system, get_method("gauss-2"), t0, q0, v0, 0.1, n_steps=3)
    assert np.abs(a.q - b.q).max() < 1e-14
    assert np.abs(a.q - c.q).max() > 1e-3
    # the friction dissipates: E decreases (2.2 with the nonideal power N . v < 0)
    assert c.energy[-1] < c.energy[0] - 1e-3


def test_ode_3a_with_nonideal_term_solves_for_psi():
    S = get_scene("friction-skate").system
    bk = Backend(30)
    with bk.context():
        q, v = bk.array(["0.1", "0.2", "0.3"]), bk.array(["-0.4", "0.1", "1"])
        a, psi = S.ode_rhs(bk, 0, q, v)
        Sm = S.saddle_matrix(bk, 0, q, v)
        N = S.nonideal_terms(bk, 0, q, v, psi, partials=False)[0]
        Lq = np.array([-1, 0, 0], dtype=object)
        r = Sm[:3, :3].dot(a) + Sm[:3, 3:].dot(psi) - N - Lq
        assert bk.norm_inf(r) < 1e-27 and bk.norm_inf(N) > 1e-3


def test_nonideal_definition_errors_and_refusals():
    sk = get_scene("skate")
    q, v = sk.system.q, sk.system.v
    with pytest.raises(SystemDefinitionError):
        LagrangianSystem(sk.system.L, list(sk.system.k), q, v, nonideal=[0, 0])       # n components
    with pytest.raises(SystemDefinitionError):
        LagrangianSystem(sk.system.L, list(sk.system.k), q, v, nonideal=[sympy.Symbol("mu"), 0, 0])
    from ldaspark.compiled.fast import NotCompilableError, mechanical_parts
    from ldaspark.analysis.discrete import DiscreteBVP, DiscreteSolveError
    fr = get_scene("friction-skate").system
    with pytest.raises(NotCompilableError):
        mechanical_parts(fr)
    with pytest.raises(DiscreteSolveError):
        DiscreteBVP(fr, get_method("gauss-1"))


@pytest.mark.parametrize("engine", ["compiled", "generic"])
def test_a_nonideal_term_set_after_construction_is_refused_never_sympified(engine, capfd):
    """``system.N = [...]`` after the system was built: text in it was executed by sympy.Matrix in
    the code generator (the compiled engine ran with it, status 0), the generic engine raised a raw
    AttributeError (no N_q: the derivation never saw N). Both refuse it in one SystemDefinitionError;
    nothing of the text runs. Control: N given to LagrangianSystem runs on both."""
    import ldaspark
    S = LagrangianSystem("vx**2/2 + vy**2/2", ["vy - x*vx"], ["x", "y"], ["vx", "vy"])
    kw = dict(t_span=(0, 0.2), h=0.1, q0=[0.5, 0], v0=[1, 0.5], engine=engine)
    for N in (["print('EXECUTED-N') or 0", "0"], sympy.Matrix([0, S.q[0] * 0 + S.v[0] / 10])):
        S.N = N
        with pytest.raises(SystemDefinitionError, match="after the system was built"):
            ldaspark.integrate(S, "gauss-1", **kw)
    assert "EXECUTED-N" not in capfd.readouterr().out
    ok = LagrangianSystem("vx**2/2 + vy**2/2", ["vy - x*vx"], ["x", "y"], ["vx", "vy"], nonideal=["0", "vx/10"])
    assert ldaspark.integrate(ok, "gauss-1", **kw).status == 0
