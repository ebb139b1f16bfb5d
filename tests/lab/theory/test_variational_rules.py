"""Rules of ``ldaspark.lab.theory.variational`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import math
import types
import numpy as np
import pytest
from ldaspark.core.families import gauss, get_method
from ldaspark.lab.theory import variational as var
from types import SimpleNamespace
import mpmath
from ldaspark.lab.theory import audit as au


def approx(expected, rel=1e-9, abs=0.0):
    """pytest.approx without its default absolute tolerance 1e-12, which would let every residual
    of these tests (1e-15 .. 1e-30) equal every other."""
    return pytest.approx(expected, rel=rel, abs=abs)


# ==== variational: the error table and its orders on synthetic solves =========================
def _variational_with(monkeypatch, ld_scale=1.0, ld_const=None, method=None):
    mk = lambda **kw: types.SimpleNamespace(**kw)
    tab = mk(name="T", claimed_order=2, family="gauss", s=1)
    monkeypatch.setattr(var, "get_scene", lambda name: mk(system="S"))
    monkeypatch.setattr(var, "initial_point", lambda name, point, dps: (0.0, [0.0, 0.0], [1.0, 0.0]))
    V = lambda *x: np.array(x, dtype=float)

    def exact(name, h, dps, stages, point):
        return "Q1", mk(L_d=1.0, f_d_minus=V(0.3, 0.5), f_d_plus=V(2.0, 0.0), p0=V(0.2, -0.1), p1=V(1.0, 1.0),
                       v0="V0", v1="V1")
    monkeypatch.setattr(var, "_exact", exact)
    monkeypatch.setattr(var, "base_point", lambda S, tab, t0, q0, v0, h, dps: (None, None, "XG"))

    def dl(S, tab, t0, q0, t1, q1, dps=None, x_guess=None):
        h = t1 - t0
        return mk(L_d=1.0 + ld_scale * h ** 3 if ld_const is None else 1.0 + ld_const, f_d_minus=V(0.3 + h ** 2, 0.5 + h), f_d_plus=V(2.0 + h, h ** 3),
                  p0=V(0.2, -0.1 - h + h ** 5), p1=V(1.0 + h, 1.0))
    monkeypatch.setattr(var, "discrete_lagrangian", dl)
    monkeypatch.setattr(var, "_tangent", lambda S, bk, t, q, v: {"V0": np.diag([1.0, 0.0]),
                                                                 "V1": np.diag([0.0, 1.0])}[v])
    if method is not None:
        monkeypatch.setattr(var, "get_method", lambda name, exact=False: method.append((name, exact)) or tab)
        return var.variational_errors("meth", "sc", dps=None)
    return var.variational_errors(tab, "sc", dps=None)


# ==== variational =============================================================================
def test_predicted_local_order_per_family():
    assert var.predicted_local_order(get_method("gauss-2")) == 5
    assert var.predicted_local_order(get_method("lobatto-iiia-iiib-3")) == 5
    assert var.predicted_local_order(get_method("lobatto-iiia-iiib-iiid-2")) == 3
    assert var.predicted_local_order(get_method("euler-i")) == 2
    assert var.predicted_local_order(types.SimpleNamespace(family="custom", claimed_order=None, s=3)) == 2
    assert var.predicted_local_order(types.SimpleNamespace(family="custom", claimed_order=3, s=3)) == 4


def test_variational_errors_each_quantity_and_its_order(monkeypatch):
    out = _variational_with(monkeypatch)
    hs = [0.2, 0.1, 0.05]
    e = out["errors"]
    assert out["h"] == hs and out["predicted_local_order"] == 3 and out["global_order"] == 2
    assert e["L_d"] == approx([h ** 3 for h in hs], rel=1e-9)
    assert e["f_minus"] == approx(hs, rel=1e-9) and e["f_minus_tangential"] == approx([h ** 2 for h in hs])
    assert e["f_plus"] == approx(hs, rel=1e-9) and e["f_plus_tangential"] == approx([h ** 3 for h in hs])
    assert e["p0+f_minus"] == approx([h ** 2 for h in hs], rel=1e-9)
    assert e["p1-f_plus"] == approx([h ** 3 for h in hs], rel=1e-9)
    o = out["orders"]
    want = {"L_d": 3, "f_minus": 1, "f_minus_tangential": 2, "f_plus": 1, "f_plus_tangential": 3,
            "p0+f_minus": 2, "p1-f_plus": 3}
    assert o == {k: approx(v, abs=1e-6) for k, v in want.items()}


def test_variational_errors_floor(monkeypatch):
    # L_d errors 8e-15, 1e-15, 1.25e-16: all below 1e3 eps, zero to working precision
    assert _variational_with(monkeypatch, 1e-12)["orders"]["L_d"] == math.inf
    # 8e-13 above the floor, the rest below: not zero, but no window of two points
    assert _variational_with(monkeypatch, 1e-10)["orders"]["L_d"] is None


def test_variational_tangent_and_norm():
    K = np.array([[1.0, 2.0, 0.0]])
    S = types.SimpleNamespace(n=3, saddle_matrix=lambda bk, t, q, v: np.block([[np.eye(3), K.T], [K, np.zeros((1, 1))]]))
    from ldaspark.core.backend import Backend
    P = np.array(var._tangent(S, Backend(None), 0.0, None, None), dtype=float)
    assert np.allclose(P @ K.T, 0, atol=1e-14) and np.allclose(P @ P, P, atol=1e-14)
    assert np.allclose(P @ np.array([2.0, -1.0, 3.0]), [2.0, -1.0, 3.0], atol=1e-14)
    assert var._nrm(np.array([[1.0, -3.0], [2.0, 0.5]])) == 3.0 and var._nrm(np.array([])) == 0.0


def test_variational_errors_floor_is_inclusive_and_names_are_exact_tableaux(monkeypatch):
    floor = 1e3 * 2.0 ** -52
    out = _variational_with(monkeypatch, ld_const=floor)        # |L_d - L_d^E| = floor exactly at every h
    assert out["errors"]["L_d"] == [floor] * 3 and out["orders"]["L_d"] == math.inf
    seen = []
    out = _variational_with(monkeypatch, method=seen)
    assert seen == [("meth", True)] and out["method"] == "T"


def _close(x, rel=1e-9):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny numbers."""
    return pytest.approx(x, rel=rel, abs=0.0)


P, F, S, I = au.PASS, au.FAIL, au.SKIP, au.INFO


# --- variational error analysis: orders per quantity, "zero at every h" only if every error is -----
def test_variational_errors_order_unless_zero_at_every_step(monkeypatch):
    from ldaspark.lab.theory import variational as va
    hs = ("0.2", "0.1", "0.05")
    z = np.array([mpmath.mpf(0), mpmath.mpf(0)], dtype=object)
    ex = SimpleNamespace(L_d=mpmath.mpf(0), f_d_minus=z, f_d_plus=z, p0=z, p1=z, v0=z, v1=z)
    # |L_d - L_d^E| = 1e-3, 1e-6 and exactly 0 at the smallest h; |f_d^- - f^E-| ~ h^2 in one component
    Ld = [mpmath.mpf("1e-3"), mpmath.mpf("1e-6"), mpmath.mpf(0)]
    fm = [np.array([mpmath.mpf(h) ** 2, mpmath.mpf(0)], dtype=object) for h in hs]
    calls = []

    def dl(S, tab, t0, q0, t1, q1, dps, x_guess):
        i = len(calls)
        calls.append(i)
        return SimpleNamespace(L_d=Ld[i], f_d_minus=fm[i], f_d_plus=z, p0=z, p1=z)
    monkeypatch.setattr(va, "get_scene", lambda name: SimpleNamespace(system=None))
    monkeypatch.setattr(va, "initial_point", lambda name, point, dps: (0, [0, 0], [0, 0]))
    monkeypatch.setattr(va, "_exact", lambda name, h, dps, stages, point: (z, ex))
    monkeypatch.setattr(va, "base_point", lambda *a: (None, None, None))
    monkeypatch.setattr(va, "discrete_lagrangian", dl)
    monkeypatch.setattr(va, "_tangent", lambda S, bk, t, q, v: np.eye(2, dtype=object))
    tab = SimpleNamespace(name="fake", family="gauss", s=1, claimed_order=2)
    out = va.variational_errors(tab, "fake", hs=hs, dps=20)
    assert out["errors"]["f_minus"] == [_close(0.04), _close(0.01), _close(0.0025)]
    assert out["orders"]["f_minus"] == _close(2.0, rel=1e-6)
    # L_d is zero at h = 0.05 only: an order from the two larger h, not "zero at every h"
    assert out["orders"]["L_d"] == _close(math.log2(1e3), rel=1e-6)
    assert out["orders"]["f_plus"] == math.inf          # zero at every h
