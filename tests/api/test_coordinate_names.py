"""``Result.coordinate_names``: the printed names of the system's q, remembered per tuple of
symbols (printed once), a fresh list for every Result, another system's names for another system."""
from __future__ import annotations

import sympy

import ldaspark
from ldaspark import solve
from ldaspark.core.system import LagrangianSystem


def _oscillator(names):
    q = list(sympy.symbols(names))
    v = list(sympy.symbols([f"d{n}" for n in names]))
    L = sum(x ** 2 for x in v) / 2 - sum(x ** 2 for x in q) / 2
    return LagrangianSystem(L, [v[0] - v[1]], q, v, name="osc-" + "-".join(names))


def test_each_system_gets_its_own_names_and_each_result_its_own_list():
    a, b = _oscillator(["x", "y"]), _oscillator(["th", "phi"])
    run = dict(q0=[0.1, 0.2], v0=[0.3, 0.3], t0=0.0, h=0.1, n_steps=2, engine="generic")
    ra = ldaspark.integrate(a, "gauss-1", **run)
    rb = ldaspark.integrate(b, "gauss-1", **run)
    assert ra.coordinate_names == ["x", "y"] and rb.coordinate_names == ["th", "phi"]
    ra.coordinate_names.append("z")                       # a caller's edit stays in its Result
    again = ldaspark.integrate(a, "gauss-1", **run)
    assert again.coordinate_names == ["x", "y"] and again.coordinate_names is not ra.coordinate_names


def test_functions_of_time_are_printed_as_sympy_prints_them():
    t = sympy.Symbol("t")
    x = sympy.Function("x")(t)
    assert solve._coordinate_names(type("S", (), {"q": [x, sympy.Symbol("y")]})()) == ["x(t)", "y"]


def test_an_ensemble_through_an_executor_names_its_coordinates_as_the_loop_does():
    """The compiled initial-data ensemble through an executor (``solve._compiled_ensemble``) gave
    coordinate_names None on the batched Result and on each member, the loop over single runs
    ["x", "y"] (the same ensemble, the same numbers)."""
    from concurrent.futures import ThreadPoolExecutor
    osc = _oscillator(["x", "y"])
    run = dict(q0=[[0.1, 0.2], [0.2, 0.1]], v0=[[0.3, 0.3], [0.1, 0.1]], t0=0.0, h=0.1, n_steps=2, guard=False)
    loop = ldaspark.integrate(osc, "gauss-1", **run)
    with ThreadPoolExecutor(2) as ex:
        pool = ldaspark.integrate(osc, "gauss-1", executor=ex, **run)
    assert pool.engine == loop.engine == "compiled" and (pool.q == loop.q).all()
    assert loop.coordinate_names == pool.coordinate_names == ["x", "y"]
    assert [m.coordinate_names for m in pool.members] == [["x", "y"]] * 2
    for ens in (loop, pool):          # each Result its own list
        assert len({id(ens.coordinate_names)} | {id(m.coordinate_names) for m in ens.members}) == 3
