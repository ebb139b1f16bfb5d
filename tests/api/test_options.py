"""``ldaspark.integrate`` checks its options once into one frozen ``IntegrationOptions`` and
carries that object to every engine path; the private functions of ``solve.py`` take a handful
of parameters (the options object and the problem instead of a dozen loose values)."""
from __future__ import annotations

import ast
import dataclasses
import inspect

import pytest

import ldaspark
from ldaspark import solve
from ldaspark.core.errors import InputError
from ldaspark.core.options import IntegrationOptions

MAX_PARAMS = 6


def _wide_private_functions(source: str, limit=MAX_PARAMS) -> list[str]:
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef) and node.name.startswith("_") and not node.name.startswith("__"):
            a = node.args
            n = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + bool(a.vararg) + bool(a.kwarg)
            if n > limit:
                out.append(f"{node.name}: {n} parameters")
    return out


def test_private_functions_of_solve_take_few_parameters():
    assert _wide_private_functions(inspect.getsource(solve)) == []


def test_negative_control_a_wide_private_function_is_reported():
    src = "def _wide(a, b, c, d, e, f, g):\n    pass\ndef public(a, b, c, d, e, f, g):\n    pass\n"
    assert _wide_private_functions(src) == ["_wide: 7 parameters"]


def test_options_are_frozen_and_checked_once():
    opts = IntegrationOptions.checked(engine="generic", dps=30, save_every=2)
    assert (opts.engine, opts.dps, opts.save_every, opts.events) == ("generic", 30, 2, ())
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.dps = 40
    assert opts.replace(dps=40).dps == 40 and opts.dps == 30
    # the same checks and messages as integrate's, the first wrong value named
    with pytest.raises(InputError, match="engine"):
        IntegrationOptions.checked(engine="fast", dps=1)
    with pytest.raises(InputError, match="float64 only"):
        IntegrationOptions.checked(engine="compiled", dps=30)
    with pytest.raises(InputError, match="dense_output must be True or False"):
        IntegrationOptions.checked(dense_output=1)
    with pytest.raises(InputError, match="events must be a callable"):
        opts.with_events(3)
    assert not opts.every_step and opts.with_events(lambda t, q, v: q[0]).every_step


def _spy(monkeypatch, name):
    """The (problem, options) each run hands to the engine ``name`` (``ldaspark.engines.ENGINES``)
    through the protocol's ``prepare``."""
    from ldaspark.engines import ENGINES
    seen = []
    engine = ENGINES[name]
    real = engine.prepare

    def spy(system, prob, opts):
        seen.append((prob, opts))
        return real(system, prob, opts)
    monkeypatch.setitem(vars(engine), "prepare", spy)     # removed at teardown (see test_engine_protocol)
    return seen


def test_one_options_object_reaches_the_generic_engine(monkeypatch):
    seen = _spy(monkeypatch, "generic")
    ev = lambda t, q, v: q[0] - 10.0               # noqa: E731  (never fires)
    r = ldaspark.integrate("skate", "gauss-1", t_span=(0, 0.2), h=0.1, engine="generic", newton="full",
                           save_every=2, events=ev, energy_jump=0.5)
    assert r.status == 0 and len(seen) == 1
    prob, opts = seen[0]
    assert isinstance(opts, IntegrationOptions)
    assert (opts.engine, opts.newton, opts.save_every, opts.energy_jump) == ("generic", "full", 2, 0.5)
    assert len(opts.events) == 1 and opts.events[0].g is ev
    assert (prob.kind, prob.name, prob.N) == ("spark", "gauss-1", 2)


def test_one_options_object_reaches_the_comparator_and_every_member(monkeypatch):
    seen = _spy(monkeypatch, "comparator")
    r = ldaspark.integrate("skate", "lobatto-iiia-iiib-2-leapfrog", n_steps=2, h=0.1, engine="generic",
                           params=None)
    assert r.status == 0 and len(seen) == 1 and seen[0][1].engine == "generic"
    seen_g = _spy(monkeypatch, "generic")
    q0 = [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]
    v0 = [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]
    b = ldaspark.integrate("skate", "gauss-1", n_steps=2, h=0.1, q0=q0, v0=v0, engine="generic", tol=1e-12)
    assert len(seen_g) == 2 and seen_g[0][1] is seen_g[1][1]          # one object for the members
    assert seen_g[0][1].tol == 1e-12 and b.q.shape[0] == 2
