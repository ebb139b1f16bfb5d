"""Nonideal constraints (3.3) on the compiled general kernel (``kernels_general``): the stage
reaction -K^T Psi + N(T, Q, V, Psi) in (21b, d) and N_q, N_v, N_psi in the Newton matrix.

* residual and Newton matrix of the kernel equal the generic path's (``SparkMethod.residual``)
  at a generic point, on ``friction-skate`` and on a system whose N depends nonlinearly on q, v
  and psi; controls: a generated model with one of N_q, N_v, N_psi scaled is seen there;
* 1000 steps: compiled = generic to 1e-12 in q, v, E, k (four SPARK families on friction-skate,
  two on the second system); controls: the compiled run with N dropped is far off, and a wrong
  N_psi block leaves the converged steps unchanged but costs Newton iterations;
* ``ldaspark.integrate(..., engine="auto")`` runs friction-skate compiled, with no notice.

Default cost ~12 s CPU with the process start (15 s wall at load ~6): three generic 1000-step
references at ~2 s each, computed once per module; the ~10 generated models add ~1 s each the
first time on a machine. --exhaustive: three more references. The kernels themselves are
compiled once per machine.
"""
import functools

import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.compiled import kernels_general
from ldaspark.compiled.fast import (CompiledSystem, NotCompilableError, can_compile, compile_system, kernel_spec,
                                    run_compiled)
from ldaspark.core.families import get_method
from ldaspark.models.scenes import get_scene
from ldaspark.core.spark import SparkMethod, integrate
from ldaspark.core.system import LagrangianSystem

AGREE = 1e-12
N_STEPS = 1000
H = 0.01
# in the default run the two families whose A_tilde differ (N enters (21b, d) through A_tilde,
# b_tilde); the other two with --exhaustive (~2 s of generic path each)
SKATE_METHODS = ("gauss-2", "lobatto-iiia-iiib-iiid-2",
                 pytest.param("gauss-1", marks=pytest.mark.exhaustive),
                 pytest.param("lobatto-iiia-iiib-2", marks=pytest.mark.exhaustive))


def nonlinear_nonideal(drop_N=False):
    """The particle of 8.1 (L = |v|^2/2 - (q1^2 + q2^2)/2, k = v3 - q2 v1) with a nonideal term
    nonlinear in q, v and psi, so that N_q, N_v and N_psi all enter the Newton matrix."""
    q = list(sympy.symbols("q1:4"))
    v = list(sympy.symbols("v1:4"))
    psi = sympy.Symbol("psi")
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - (q[0] ** 2 + q[1] ** 2) / 2
    N = [psi ** 2 * sympy.sin(q[1]) / 10 - v[0] ** 3 / 20,
         sympy.cos(q[0]) * v[0] * v[1] * psi / 10,
         -psi * sympy.exp(-q[2] ** 2) * v[2] ** 2 / 10]
    return LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="nonlinear-nonideal",
                            nonideal=None if drop_N else N, psi=[psi])


def _skate(drop_N=False):
    sc = get_scene("friction-skate")
    S = sc.system
    if drop_N:
        S = LagrangianSystem(S.L, list(S.k), S.q, S.v, S.t, name="skate-no-N")
    return S, [float(x) for x in sc.initial()[1]], [float(x) for x in sc.initial()[2]]


SYSTEMS = {"friction-skate": _skate,
           "nonlinear-nonideal": lambda drop_N=False: (nonlinear_nonideal(drop_N), [1.0, 0.0, 0.5], [0.0, 1.0, 0.0])}


@functools.lru_cache(maxsize=None)
def generic_run(name, method):
    S, q0, v0 = SYSTEMS[name]()
    return S, q0, v0, integrate(S, get_method(method), 0.0, q0, v0, H, n_steps=N_STEPS)


def max_diff(fast, sol):
    return max(float(np.max(np.abs(getattr(fast, a) - np.asarray(getattr(sol, b), float))))
               for a, b in (("q", "q"), ("v", "v"), ("energy", "energy"), ("constraint", "constraint")))


def compiled_run(cs, q0, v0, method):
    r = run_compiled(cs, method, 0.0, q0, v0, H, N_STEPS, compensated=False, kernel="spark")
    assert r.stats["kernel"] == "general" and r.stats["steps"] == N_STEPS
    return r


# --- the residual and the Newton matrix at one point -----------------------------------------
def kernel_newton_system(cs, system, method, seed=0):
    """(G, J) of ``kernels_general.general_eval`` and of ``SparkMethod.residual`` at the same
    generic point (kernel unknowns Z = V - v0, Lambda, dv = v1 - v0; the rows are in the same
    order (21b), (21d), (21e), (21f) on both sides)."""
    tab = kernel_spec(method, "spark")[1]
    s, n, m = tab[1].shape[0], system.n, system.m
    t0, q0, v0, h = 0.1, np.array([0.1, -0.2, 0.3]), np.array([0.2, 0.1, 0.9]), 0.1
    x = 0.1 * np.random.default_rng(seed).standard_normal(s * (n + m) + n)
    G, J = np.zeros(x.size), np.zeros((x.size, x.size))
    kernels_general.general_eval(cs.model, tab, True, x, t0, q0, v0, h, np.eye(n),
                                 kernels_general.workspace(s, n, m), G, J)
    sm = SparkMethod(system, get_method(method))
    xg = x.copy()
    xg[:s * n] += np.tile(v0, s)
    xg[s * (n + m):] += v0
    Gg, Jg, _ = sm.residual(t0, q0, system.momentum(sm.backend, t0, q0, v0), h, xg)
    return G, J, np.asarray(Gg, float), np.asarray(Jg, float)


@pytest.mark.parametrize("name", list(SYSTEMS))
@pytest.mark.parametrize("method", ["gauss-2", "lobatto-iiia-iiib-iiid-3"])
def test_kernel_residual_and_newton_matrix_equal_the_generic_ones(name, method):
    S = SYSTEMS[name]()[0]
    G, J, Gg, Jg = kernel_newton_system(compile_system(S), S, method)
    assert np.abs(G - Gg).max() <= 1e-14 * (1 + np.abs(Gg).max())
    assert np.abs(J - Jg).max() <= 1e-14 * np.abs(Jg).max()
    n, s = S.n, 2 if method == "gauss-2" else 3
    # the nonideal blocks are there: N_psi in the Lambda columns, N_q and N_v in the V columns
    _, Ji, _, _ = kernel_newton_system(compile_system(SYSTEMS[name](drop_N=True)[0], form="general"), S, method)
    assert np.abs(J[:, s * n:s * n + s * S.m] - Ji[:, s * n:s * n + s * S.m]).max() > 1e-3
    assert np.abs(J[:, :s * n] - Ji[:, :s * n]).max() > 1e-4


def scaled_model(system, block, factor):
    """A compiled model whose generated ``block`` (Nq, Nv or Npsi) is multiplied by ``factor``."""
    cs = compile_system(system)
    lines = [f"{ln.split(' = ', 1)[0]} = {factor!r} * ({ln.split(' = ', 1)[1]})"
             if ln.lstrip().startswith(block + "[") else ln for ln in cs.source.splitlines()]
    src = "\n".join(lines) + "\n"
    assert src != cs.source
    return CompiledSystem(cs.name, cs.n, cs.m, src, cs.M, cs.Minv, "general")


@pytest.mark.parametrize("block", ["Nq", "Nv", "Npsi"])
def test_control_a_wrong_nonideal_block_is_seen_in_the_newton_matrix(block):
    S = nonlinear_nonideal()
    G, J, Gg, Jg = kernel_newton_system(scaled_model(S, block, 3.0), S, "gauss-2")
    assert np.abs(G - Gg).max() <= 1e-14 * (1 + np.abs(Gg).max())      # the residual does not use it
    assert np.abs(J - Jg).max() > 1e-4 * np.abs(Jg).max()


# --- 1000 steps against the generic path ------------------------------------------------------
@pytest.mark.parametrize("method", SKATE_METHODS)
def test_friction_skate_compiled_agrees_with_generic(method):
    """1000 steps of h = 0.01 on the general kernel (lobatto-iiia-iiib-2 too: the semi-implicit
    kernel (25) is for mechanical systems); friction takes ~2.8 of the energy (8), |q| ~ 10."""
    S, q0, v0, sol = generic_run("friction-skate", method)
    ok, form = can_compile(S)
    assert (ok, form) == (True, "general")
    fast = compiled_run(compile_system(S), q0, v0, method)
    assert max_diff(fast, sol) <= AGREE
    assert fast.energy[0] - fast.energy[-1] > 1.0          # the friction acts


@pytest.mark.parametrize("method", ["gauss-2", pytest.param("lobatto-iiia-iiib-iiid-2", marks=pytest.mark.exhaustive)])
def test_nonlinear_nonideal_compiled_agrees_with_generic(method):
    S, q0, v0, sol = generic_run("nonlinear-nonideal", method)
    assert max_diff(compiled_run(compile_system(S), q0, v0, method), sol) <= AGREE


@pytest.mark.parametrize("name", list(SYSTEMS))
def test_control_the_compiled_run_without_N_differs(name):
    _, q0, v0, sol = generic_run(name, "gauss-2")
    ideal = compiled_run(compile_system(SYSTEMS[name](drop_N=True)[0], form="general"), q0, v0, "gauss-2")
    assert max_diff(ideal, sol) > 1e-6


def test_control_a_wrong_N_psi_costs_iterations_not_accuracy():
    """Simplified Newton converges to the solution of (21) with any Newton matrix close enough;
    a wrong N_psi block (x 3) shows as slower convergence (the converged steps stay within the
    Newton tolerance of the right ones)."""
    S, q0, v0, sol = generic_run("friction-skate", "gauss-2")
    good = compiled_run(compile_system(S), q0, v0, "gauss-2")
    bad = compiled_run(scaled_model(S, "Npsi", 3.0), q0, v0, "gauss-2")
    assert max_diff(bad, sol) <= 1e-10
    assert bad.stats["newton_iterations"] >= good.stats["newton_iterations"] + N_STEPS // 2


# --- form and engine selection ----------------------------------------------------------------
def test_nonideal_systems_take_the_general_form():
    S = get_scene("friction-skate").system
    assert compile_system(S).form == "general"
    with pytest.raises(NotCompilableError, match="nonideal"):
        compile_system(S, form="mechanical")
    src = compile_system(S).source
    assert "N[2]" not in src and "Npsi[0, 0]" in src        # structural zeros are not emitted
    ideal = compile_system(get_scene("skate").system, form="general").source
    assert "def nonideal(" in ideal and "N[" not in ideal.split("def nonideal(")[1]
    from ldaspark.compiled.ode import ode_source        # the ideal ODE (3a-b) only: refused, not wrong
    with pytest.raises(NotCompilableError, match="nonideal"):
        ode_source(S)


def test_integrate_auto_runs_friction_skate_compiled(capsys):
    res = ldaspark.integrate("friction-skate", "lobatto-iiia-iiib-iiid-2", t_span=(0, 1), h=0.01)
    assert res.engine == "compiled" and res.status == 0
    assert capsys.readouterr().err == ""
    gen = ldaspark.integrate("friction-skate", "lobatto-iiia-iiib-iiid-2", t_span=(0, 1), h=0.01, engine="generic")
    assert np.abs(np.asarray(res.q) - np.asarray(gen.q)).max() <= AGREE
