"""The compiled model cache's content key (``codegen.model_key``) covers every function's name:
two models that differ only by one function (sin against cos) have different keys and, served
from a warm cache, different results (each its own)."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.compiled import codegen
from ldaspark.core.gensource import SUPPORTED_FUNCTIONS

x, y, vx, vy = sympy.symbols("x y vx vy")


def _system(f):
    return ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - f, [vy - x * vx], [x, y], [vx, vy])


def _applied(name):
    fn = getattr(sympy, name)
    if name == "atan2":
        return fn(x, y + 2)
    if name == "Piecewise":
        return sympy.Piecewise((x, x > 0), (x ** 2, True))
    if name in ("Min", "Max"):
        return fn(x, y / 3)
    return fn(x / 3 + sympy.Rational(1, 7))


def test_every_supported_function_gives_its_own_key():
    keys = {}
    for name in sorted(SUPPORTED_FUNCTIONS):
        e = _applied(name)
        keys[name] = codegen.model_key(_system(e), "general")
    same_key = [p for p in itertools.combinations(keys, 2) if keys[p[0]] == keys[p[1]]]
    assert len(set(keys.values())) == len(keys), same_key
    # the control: the same model (renamed symbols) has the same key
    a, b = sympy.symbols("a b")
    same = ldaspark.LagrangianSystem((a ** 2 + b ** 2) / 2 - sympy.sin(x / 3 + sympy.Rational(1, 7)), [b - x * a],
                                     [x, y], [a, b])
    assert codegen.model_key(same, "general") == keys["sin"]


def test_sin_and_cos_served_from_a_warm_cache_keep_their_own_results(tmp_path, monkeypatch):
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(tmp_path))
    kw = dict(t_span=(0, 0.2), q0=[0.4, 0], v0=[0.1, 0.04], h=0.05)
    runs = {}
    for rnd in ("cold", "warm"):
        monkeypatch.setattr(codegen, "_SOURCES", {})          # the warm round reads the disk cache
        for name in ("sin", "cos"):
            S = _system(getattr(sympy, name)(x))
            runs[rnd, name] = np.asarray(ldaspark.integrate(S, "gauss-2", engine="compiled", **kw).q)
    for name in ("sin", "cos"):
        ref = np.asarray(ldaspark.integrate(_system(getattr(sympy, name)(x)), "gauss-2", engine="generic", **kw).q)
        assert np.abs(runs["warm", name] - ref).max() <= 1e-12
        assert np.array_equal(runs["warm", name], runs["cold", name])
    assert np.abs(runs["warm", "sin"] - runs["warm", "cos"]).max() > 1e-4
