"""(3a-b) as ``LagrangianSystem.ode_rhs`` evaluates it: one flat expression list, so that the
generated function shares its subexpressions (lambdify's CSE does nothing across the nested
lists of ``_fn``). mpmath.odefun, the convergence report's 40-digit reference, evaluates (3a-b)
at ~2600 digits: the bicycle's 18,880 sines and cosines took 1.7 s per evaluation, its first
Taylor segment 197 s, and ``report convergence --scenes bicycle --t-end 0.1`` had not built its
reference after 90 s (now 14 s)."""
from __future__ import annotations

import re

import mpmath
import numpy as np
import pytest
import sympy

from ldaspark.core import gensource
from ldaspark.core.backend import Backend
from ldaspark.core.system import LagrangianSystem
from ldaspark.models.scenes import get_scene

TRIG = re.compile(r"\b(?:sin|cos)\(")


def _sources(monkeypatch, system, call):
    """The generated sources compiled while ``call`` runs on a fresh system."""
    seen = []
    real = gensource._compile

    def spy(src):
        seen.append(src)
        return real(src)
    monkeypatch.setattr(gensource, "_compile", spy)
    call()
    return seen


def test_the_bicycles_ode_evaluator_computes_each_sine_and_cosine_once(monkeypatch):
    """The generated evaluator of (3a-b) on the bicycle (8 angles) had 18,880 calls of sin and
    cos in its source (no shared subexpressions); with the shared ones, each distinct call once:
    at most 2 x 2 x 8 (sin and cos of each angle and of each shifted angle: 8 angles is a
    generous bound on the distinct arguments; measured 10). Control: the nested form of ``_fn``
    (what ode_rhs used) still has them all."""
    bk = Backend(40)
    sc = get_scene("bicycle")
    t0, q0, v0 = sc.initial(40)
    s = sc.system
    s._compiled.pop(("ode-flat", bk.lambdify_module), None)
    src = _sources(monkeypatch, s, lambda: s.ode_rhs(bk, t0, q0, v0))
    assert len(src) == 1 and len(TRIG.findall(src[0])) <= 32, len(TRIG.findall(src[0]))
    exprs = [s.L_vv, s.k_v, s.L_vt, s.L_vq, s.L_q, s.k_t, s.k_q]
    s._compiled.pop(("ode", bk.lambdify_module), None)
    nested = _sources(monkeypatch, s, lambda: s._fn("ode", exprs, bk))
    assert len(TRIG.findall(nested[0])) > 10_000


def _nested_ode_rhs(system, bk, t, q, v):
    """(3a-b) through ``_fn``'s nested form (ode_rhs before): the reference values."""
    exprs = [system.L_vv, system.k_v, system.L_vt, system.L_vq, system.L_q, system.k_t, system.k_q]
    f = system._fn("ode-nested-reference", exprs, bk)
    Lvv, kv, Lvt, Lvq, Lq, kt, kq = system._arrays("ode-nested-reference", f(t, *q, *v), bk)
    n, m = system.n, system.m
    kv, kq = kv.reshape(m, n), kq.reshape(m, n)
    S = bk.zeros((n + m, n + m))
    S[:n, :n], S[:n, n:], S[n:, :n] = Lvv, kv.T, kv
    rhs = np.concatenate([-Lvt[:, 0] - Lvq.dot(np.asarray(v)) + Lq[:, 0], -kt[:, 0] - kq.dot(np.asarray(v))])
    sol = bk.solve(S, rhs)
    return sol[:n], sol[n:]


@pytest.mark.parametrize("name", ["particle", "robot", "rheonomic-skate", "bicycle"])
@pytest.mark.parametrize("dps", [None, 40])
def test_ode_rhs_gives_the_values_of_the_nested_form(name, dps):
    """The same (dv/dt, psi) as the nested form, to the round-off of a different order of the
    same operations: 1e3 eps relative (eps of float64 or of 40 digits; the saddle system is
    well conditioned at these points, cond < 1e3: 1e3 eps leaves a factor >= 1 for it)."""
    bk = Backend(dps)
    sc = get_scene(name)
    t0, q0, v0 = sc.initial(dps)
    with bk.context():
        a, psi = sc.system.ode_rhs(bk, bk.scalar(t0), bk.array(q0), bk.array(v0))
        a0, psi0 = _nested_ode_rhs(sc.system, bk, bk.scalar(t0), bk.array(q0), bk.array(v0))
        eps = float(bk.eps)
        scale = max(1.0, max(abs(float(x)) for x in list(a0) + list(psi0)))
        diff = max(abs(float(x - y)) for x, y in zip(list(a) + list(psi), list(a0) + list(psi0)))
    assert diff <= 1e3 * eps * scale, (diff, eps)


def test_ode_rhs_of_an_unconstrained_system_and_of_parameters():
    """m = 0 (empty K, k_t, k_q: their shapes kept) and a parameter (the trailing argument):
    v' = -(k/m) x for L = m v^2/2 - k x^2/2, psi empty."""
    x, u, k, mass = sympy.symbols("x u k mass")
    S = LagrangianSystem(mass * u ** 2 / 2 - k * x ** 2 / 2, [], [x], [u], params={k: 3, mass: 2}, name="spring")
    bk = Backend(30)
    with bk.context():
        a, psi = S.ode_rhs(bk, bk.scalar(0), bk.array([mpmath.mpf(1)]), bk.array([mpmath.mpf(0)]))
    assert len(psi) == 0 and abs(a[0] - mpmath.mpf(-3) / 2) <= 10 * mpmath.mpf(10) ** -30
