"""Every option of ``ldaspark.integrate`` on every engine path: the option set to a non-default
value is seen in the Result (counters, numbers, rows, status, stats) or refused with one
InputError naming it, never accepted and ignored. The paths: the generic engine in float64 and at
20 digits, the compiled SPARK kernel (default and quasi-Newton root finder), the semi-implicit
kernel (25) of lobatto-iiia-iiib-2, a comparator on the comparator engine (gauss-irk-2) and on
the compiled kernels (the leapfrog form of (25)), and a compiled run cut into blocks of 4 steps.

One small system with a parameter (a particle in the plane, k = v_y - x v_x, U = w x^2 / 2):
10 steps of h = 0.05 per run."""
from __future__ import annotations

import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark import Newton
from ldaspark.core import chunks
from ldaspark.core.errors import InputError

x, y, vx, vy, w = sympy.symbols("x y vx vy w")
SYSTEM = ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - w * x ** 2 / 2, [vy - x * vx], [x, y], [vx, vy],
                                   params=[w], name="param-particle")
Q0, V0, N = [0.3, 0.0], [0.2, 0.06], 10

PATHS = {
    "generic": dict(method="gauss-2", engine="generic"),
    "mpmath": dict(method="gauss-2", engine="generic", dps=20),
    "compiled": dict(method="gauss-2", engine="compiled"),
    "quasi": dict(method="gauss-2", engine="compiled", newton="quasi"),
    "semi-implicit": dict(method="lobatto-iiia-iiib-2", engine="compiled"),
    "comparator": dict(method="gauss-irk-2", engine="generic"),
    "comparator-compiled": dict(method="lobatto-iiia-iiib-2-leapfrog", engine="compiled"),
    "blocks": dict(method="gauss-2", engine="compiled", chunk=4),
}
#: the Newton field values each path refuses (the comparators run their own Newton iteration)
REFUSED = {("comparator", "full"), ("comparator", "zero"), ("comparator-compiled", "full")}


def run(path, monkeypatch, **kw):
    p = dict(PATHS[path])
    method, chunk = p.pop("method"), p.pop("chunk", None)
    if chunk:
        monkeypatch.setattr(chunks, "COMPILED_CHUNK", chunk)
    if path == "quasi" and isinstance(kw.get("newton"), Newton):      # the quasi kind with the field asked
        kw["newton"] = Newton(**{**kw["newton"].__dict__, "kind": "quasi"})
    args = dict(p, q0=Q0, v0=V0, t0=0.0, n_steps=N, h=0.05, params={"w": 1.5})
    args.update(kw)
    return ldaspark.integrate(SYSTEM, method, **args)


def qf(r):
    return np.asarray(r.q, float)


@pytest.fixture(scope="module")
def base():
    mp = pytest.MonkeyPatch()
    try:
        return {p: run(p, mp) for p in PATHS}
    finally:
        mp.undo()


@pytest.mark.parametrize("path", sorted(PATHS))
def test_the_base_run_of_every_path(base, path):
    # the control of every test below: each path runs the 10 steps and guards them
    r = base[path]
    assert r.status == 0 and len(r.t) == N + 1 and r.stats["guard"] is True
    assert np.all(np.isfinite(qf(r)))


@pytest.mark.parametrize("path", sorted(PATHS))
def test_save_every(base, path, monkeypatch):
    r = run(path, monkeypatch, save_every=3)
    assert len(r.t) == 5                                       # steps 0, 3, 6, 9 and the last, 10
    assert np.array_equal(np.asarray(r.t, float), np.asarray(base[path].t, float)[[0, 3, 6, 9, 10]])


@pytest.mark.parametrize("how", ["tol", "Newton(tol)"])
@pytest.mark.parametrize("path", sorted(PATHS))
def test_a_loose_tolerance_stops_newton_earlier(base, path, how, monkeypatch):
    # tol = 1e-3 against the default (round-off): fewer iterations on every path
    r = run(path, monkeypatch, **({"tol": 1e-3} if how == "tol" else {"newton": Newton(tol=1e-3)}))
    assert r.newton_iterations < base[path].newton_iterations


@pytest.mark.parametrize("path", sorted(PATHS))
def test_max_iter_one_fails_the_first_step(path, monkeypatch):
    # one iteration does not reach the default tolerance from the predictor: status -1 at step 0
    r = run(path, monkeypatch, newton=Newton(max_iter=1))
    assert r.status == -1 and len(r.t) == 1


@pytest.mark.parametrize("path, field, value", [(p, f, v) for p in sorted(PATHS) for f, v in
                                                  (("kind", "full"), ("predictor", "zero"))
                                                  if not (p == "quasi" and f == "kind")])     # quasi is a kind
def test_a_newton_field_changes_the_work_or_is_refused(base, path, field, value, monkeypatch):
    # full Newton forms a Jacobian at every iteration (njev = newton_iterations), the simplified
    # one once a step; the zero predictor starts further from the root (more iterations)
    if (path, value) in REFUSED:
        with pytest.raises(InputError, match=f"refuses Newton {field}"):
            run(path, monkeypatch, newton=Newton(**{field: value}))
        return
    r, b = run(path, monkeypatch, newton=Newton(**{field: value})), base[path]
    if field == "kind":
        assert r.njev == r.newton_iterations and b.njev < b.newton_iterations
    else:
        assert r.newton_iterations > b.newton_iterations


@pytest.mark.parametrize("path", sorted(PATHS))
def test_dense_output_and_events(base, path, monkeypatch):
    level = float((qf(base[path])[0][0] + qf(base[path])[-1][0]) / 2)

    def g(t, q, v):
        return q[0] - level
    r = run(path, monkeypatch, dense_output=True, events=g)
    assert callable(r.sol) and len(r.t_events[0]) == 1 and r.status == 0
    te = float(r.t_events[0][0])
    # the event on the dense output: g = 0 there to the root finder's tolerance (4 ulp of t,
    # brentq; |dx/dt| <= 1 here)
    assert abs(float(r.sol(te)[0][0]) - level) < 1e-12
    g.terminal = True
    s = run(path, monkeypatch, events=g)
    assert s.status == 1 and float(s.t[-1]) >= te and len(s.t) < N + 1


@pytest.mark.parametrize("path", sorted(PATHS))
def test_energy_jump_and_raise_on_failure(path, monkeypatch):
    # a threshold below any energy change of a step (the round-off of a conserved energy is
    # ~1e-16 relative): the first step ends the run, status -3; raised with raise_on_failure
    r = run(path, monkeypatch, energy_jump=1e-300)
    assert r.status == -3 and len(r.t) == 1
    with pytest.raises(ldaspark.LdasparkError, match="energy jumped"):
        run(path, monkeypatch, energy_jump=1e-300, raise_on_failure=True)


@pytest.mark.parametrize("path", sorted(PATHS))
def test_guard_off(path, monkeypatch):
    r = run(path, monkeypatch, guard=False)
    assert r.stats["guard"] is False and "guard_flagged" not in r.stats


@pytest.mark.parametrize("path", sorted(PATHS))
def test_params_change_the_trajectory(base, path, monkeypatch):
    r = run(path, monkeypatch, params={"w": 3.0})
    assert r.params == {"w": 3.0} and np.max(np.abs(qf(r) - qf(base[path]))) > 1e-6


@pytest.mark.parametrize("path", sorted(PATHS))
def test_a_nonzero_start_and_a_negative_step(base, path, monkeypatch):
    # the system is autonomous: from t0 = 0.5 the same numbers at times shifted by 0.5 (the
    # grid t0 + i h of each path, within 2 ulp of the shifted base times)
    r = run(path, monkeypatch, t0=0.5)
    assert float(r.t[0]) == 0.5
    assert np.allclose(np.asarray(r.t, float) - 0.5, np.asarray(base[path].t, float), rtol=0, atol=4e-16)
    back = run(path, monkeypatch, h=-0.05)
    assert float(back.t[-1]) == pytest.approx(-0.5, abs=1e-15) and back.status == 0
    assert np.max(np.abs(qf(back)[-1] - qf(base[path])[-1])) > 1e-3        # another trajectory


@pytest.mark.parametrize("path", sorted(PATHS))
def test_project_makes_the_start_consistent(path, monkeypatch):
    # v0 = (0.2, 0.1) has k = 0.1 - 0.3 * 0.2 = 0.04: refused, and with project=True moved onto
    # k = 0 (in the metric of L_vv = I: the normal (-x, 1) direction)
    with pytest.raises(ldaspark.LdasparkError, match="inconsistent"):
        run(path, monkeypatch, v0=[0.2, 0.1])
    r = run(path, monkeypatch, v0=[0.2, 0.1], project=True)
    v = np.asarray(r.v[0], float)
    assert r.status == 0 and abs(v[1] - 0.3 * v[0]) < 1e-15 and r.stats["projected_v0_change"] > 1e-2
