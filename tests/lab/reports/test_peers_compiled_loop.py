"""The peers' strongest right-hand sides (``ldaspark.compiled.ode``: the closed form of the saddle
system (4) and the numeric solve into a work array) against the LAPACK saddle solve on every
scene of the peer study, and the compiled-loop peers (CyRK, skipped without it) and the study's
interleaved rounds (``ldaspark.lab.reports.peers``).
Cost: ~30 s (five generated ODE modules compiled, CyRK's loops compiled)."""
import numpy as np
import pytest
import sympy

from ldaspark.compiled import ode
from ldaspark.compiled.codegen import _Symbols
from ldaspark.models.scenes import get_scene
from ldaspark.lab.reports import peers

SCENES = peers.SCENES


def _points(scene, k=4, seed=0):
    """``k`` states near the scene's initial state (t, y = (q, v)), small steps off it so that
    every entry of the saddle system is generic but the point stays in L's domain (relativistic:
    |v| < 1)."""
    rng = np.random.default_rng(seed)
    t0, q0, v0 = scene.initial()
    y0 = np.array([float(x) for x in list(q0) + list(v0)])
    return [(float(t0) + 0.3 * i, y0 + 0.03 * rng.standard_normal(y0.size)) for i in range(k)]


def _agree(a, b):
    """Equal to float64 round-off of a small, well-conditioned saddle solve (1e-12 relative to the
    size of the acceleration): a formula error is of the size of the acceleration itself."""
    return np.max(np.abs(np.asarray(a) - np.asarray(b))) <= 1e-12 * (1.0 + np.max(np.abs(b)))


def _numeric_parts(system):
    """L_vv, K, r1, r2 of (4) as numpy functions of (t, y): an independent evaluation, not the
    generated module."""
    S = _Symbols(system, system.m)
    Lvv, kv, r1, r2 = ode._parts(system, S)
    args = [S.t] + S.q + S.v
    fns = [sympy.lambdify(args, M, "numpy") for M in (Lvv, kv, r1, r2)]
    return lambda t, y: [np.array(f(t, *y), float) for f in fns]


@pytest.fixture(scope="module", params=SCENES)
def scene_mod(request):
    sc = get_scene(request.param)
    return sc, ode.compiled_ode_module(sc.system)


def test_closed_form_equals_the_saddle_solve_to_round_off(scene_mod):
    sc, mod = scene_mod
    n, m = sc.system.n, sc.system.m
    assert mod.HAS_CLOSED, mod.CLOSED_INFO
    W = np.zeros(ode.n_work(n, m))
    parts = _numeric_parts(sc.system)
    for t, y in _points(sc):
        ref = mod.rhs(t, y)                                  # LAPACK, partial pivoting
        closed = mod.rhs_closed(t, y, W)
        assert np.array_equal(closed[:n], y[n:])
        assert _agree(closed, ref)
        # independent of the LAPACK path: the closed-form acceleration satisfies the constraint
        # row of (4), K a = r2, and r1 - L_vv a lies in the range of K^T
        M, K, r1, r2 = parts(t, y)
        a = closed[n:]
        assert np.max(np.abs(K @ a - r2.ravel())) <= 1e-12 * (1 + np.max(np.abs(r2)) + np.max(np.abs(K)) * np.max(np.abs(a)))
        res = r1.ravel() - M @ a
        psi = np.linalg.lstsq(K.T, res, rcond=None)[0]
        assert np.max(np.abs(K.T @ psi - res)) <= 1e-11 * (1 + np.max(np.abs(r1)))
        # negative control: the acceleration without the constraint force, L_vv^-1 r1, fails the
        # same comparison (the multipliers matter on every scene at these points)
        free = np.concatenate([y[n:], np.linalg.solve(M, r1.ravel())])
        assert not _agree(free, ref)


def test_buffered_numeric_solve_equals_lapack_and_writes_only_its_outputs(scene_mod):
    sc, mod = scene_mod
    n, m = sc.system.n, sc.system.m
    W = np.full(ode.n_work(n, m), np.nan)        # every entry it reads must be written first
    for t, y in _points(sc, seed=1):
        ref = mod.rhs(t, y)
        out = mod.rhs_solve(t, y, W)
        assert _agree(out, ref)
        yp = np.full(2 * n, np.nan)
        mod.rhs_into_solve(t, y, yp, W)
        assert np.array_equal(yp, out)
        yp2 = np.full(2 * n, np.nan)
        mod.rhs_into_closed(t, y, yp2, W)
        assert np.array_equal(yp2, mod.rhs_closed(t, y, W))
    # control: another state gives another derivative (the comparison sees the state)
    (t, y), = _points(sc, k=1, seed=2)
    assert not _agree(mod.rhs_solve(t, y + 0.05, W), mod.rhs(t, y))


def test_closed_form_is_dropped_when_too_large(monkeypatch):
    sy = get_scene("skate").system
    assert "HAS_CLOSED = True" in ode.ode_source(sy) and "def accel_closed" in ode.ode_source(sy)
    monkeypatch.setattr(ode, "CLOSED_MAX_OPS", 1)
    src = ode.ode_source(sy)
    assert "HAS_CLOSED = False" in src and "def accel_closed" not in src and "def rhs_into_solve" in src
    assert "more than 1" in src


def test_rhs_choice_is_the_faster_measured_form():
    sc = get_scene("skate")
    peers._RHS_CHOICE.pop(sc.system.name, None)
    t0, y0 = peers._initial(sc)
    c = peers.rhs_choice(sc.system, y0)
    assert set(c["ns_per_call"]) == {"solve", "closed"} and all(v > 0 for v in c["ns_per_call"].values())
    assert c["form"] == min(c["ns_per_call"], key=c["ns_per_call"].get)
    assert peers.rhs_choice(sc.system, y0) is c                   # measured once per scene


def test_interleaved_rounds_repeat_short_runs_and_drop_failures():
    calls = {"a": 0, "b": 0, "bad": 0}

    def task(name, fail=False):
        def go():
            calls[name] += 1
            if fail:
                raise peers.PeerFailure("stopped")
            return calls[name]
        return (name, go, lambda cpu, out: {"method": name, "cpu": cpu, "out": out})
    failed = []
    rows = peers.run_interleaved([task("a"), task("bad", True), task("b")], rounds=3, short=1e9, failed=failed)
    assert [r["method"] for r in rows] == ["a", "b"] and calls == {"a": 3, "b": 3, "bad": 1}
    assert failed == ["bad: PeerFailure: stopped"] and all(r["cpu"] >= 0 for r in rows)
    # control: runs longer than ``short`` are not repeated
    calls.update(a=0, b=0)
    peers.run_interleaved([task("a"), task("b")], rounds=3, short=-1.0)
    assert calls["a"] == 1 and calls["b"] == 1


def test_speedups_of_the_public_and_the_internal_spark_path():
    e = [10.0 ** -k for k in range(1, 10)]

    def law(kind, method, c0):
        return [{"kind": kind, "method": method, "param": x, "cpu": c0 * x ** -0.25, "error": x,
                 "energy_error": x} for x in e]
    rows = law("spark", "gauss-4", 2e-3) + law("spark-fast", "gauss-4", 1e-3) + law("peer", "cyrk-nbsolve2-DOP853", 1e-3)
    (pub,) = peers.speedups(rows, (1e-6,))
    (fast,) = peers.speedups(rows, (1e-6,), spark="spark-fast")
    assert abs(pub["speedup"] - 0.5) <= 1e-12 and abs(fast["speedup"] - 1.0) <= 1e-12


def test_cyrk_is_optional(monkeypatch):
    monkeypatch.setattr(peers, "cyrk", lambda: None)
    ok, notes = peers.available_peers()
    assert not set(ok) & set(peers.CYRK_PEERS)
    assert any("CyRK" in x and "cyrk-nbsolve2-DOP853" in x for x in notes)
    with pytest.raises(peers.PeerFailure, match="CyRK"):
        peers.peer_solver(get_scene("skate").system, "cyrk-nbsolve2-DOP853", 1e-6, 0.0, np.zeros(6), [1.0])
    monkeypatch.setattr(peers, "cyrk", lambda: object())           # control
    assert set(peers.CYRK_PEERS) <= set(peers.available_peers()[0])


# CyRK's numba loop compiles CyRK itself (~10 s): --exhaustive; nbsolve2 and pysolve stay
@pytest.mark.parametrize("peer", [pytest.param(p, marks=pytest.mark.exhaustive) if p == "cyrk-nbsolve-DOP853" else p
                                  for p in peers.CYRK_PEERS])
@pytest.mark.parametrize("form", ["closed", "solve"])
def test_cyrk_peer_follows_the_skate_closed_form(peer, form):
    if peers.cyrk() is None:
        pytest.skip("CyRK is not installed (the bench extra)")
    sk = get_scene("skate")
    # as tests/lab/reports/test_peers.py for the other peers: T = 10, the global error of a tolerance-
    # controlled solver on this smooth problem is a modest multiple of rtol (bounded by 1e3
    # rtol), and it responds to the tolerance (the control that the error is the solver's)
    q_ref = np.asarray(sk.exact_solution(10.0)[0], float)
    err = {}
    for tol in (1e-8, 1e-4):
        r = peers.run_peer(sk, peer, tol, 10.0, repeats=1, form=form)
        err[tol] = float(np.max(np.abs(np.asarray(r["q_final"]) - q_ref)))
        assert r["kind"] == "peer" and r["method"] == peer and r["cpu"] > 0
    assert 0 < err[1e-8] <= 1e-5
    assert err[1e-4] >= 10 * err[1e-8]
    # the long runs' output times: one row per output time, the last at T
    r = peers.run_peer(sk, peer, 1e-8, 10.0, n_out=5, repeats=1, form=form)
    assert float(np.max(np.abs(np.asarray(r["q_final"]) - q_ref))) <= 1e-5


class _Payload:
    """Unpickling this creates ``marker`` (what a hostile numba index would do with os.system)."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def test_the_ode_modules_numba_cache_is_the_trusted_one_never_numba_cache_dir(tmp_path, monkeypatch):
    """rhs_into, psi_of and dae_residual were ``numba.njit(cache=True)``: numba's own cache, which
    under NUMBA_CACHE_DIR lives there, unrecorded, and was unpickled from a directory others can
    write (a planted index in a 0777 NUMBA_CACHE_DIR ran its payload). Now every function of the
    module goes through the trusted cache (``cache.model_jit``): nothing is written to
    NUMBA_CACHE_DIR, a planted index is deleted and compiled again, the same bits come back, and
    the recorded cache is loaded by the next load (control: caching still works)."""
    import os
    import pickle
    from numba.core import config
    from ldaspark import LagrangianSystem
    from ldaspark.compiled import cache
    shared = tmp_path / "numba-shared"
    shared.mkdir()
    os.chmod(shared, 0o777)
    monkeypatch.setattr(config, "CACHE_DIR", str(shared))     # what NUMBA_CACHE_DIR sets at import
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(tmp_path / "c"))
    x, y, vx, vy = sympy.symbols("x y vx vy")
    system = LagrangianSystem((vx**2 + vy**2) / 2 - x**2 / 3 - y / 7, [vy - x * vx], [x, y], [vx, vy],
                              name="ode-trust")
    src = ode.ode_source(system)

    def fresh():                                  # as a new process loads it
        cache._MODULES.pop(cache.source_key(src), None)
        return ode.compiled_ode_module(system)

    state = np.array([0.1, 0.2, 0.3, 0.03])

    def evaluate(mod):
        yp = np.zeros(4)
        mod.rhs_into(0.5, state, yp)
        psi = mod.psi_of(0.5, state)
        res = np.zeros(5)
        mod.dae_residual(0.5, np.concatenate([state, psi]), np.concatenate([yp, [0.0]]), res)
        return yp.tobytes() + psi.tobytes() + res.tobytes()

    first = evaluate(fresh())
    marker = tmp_path / "executed"
    planted = list(shared.rglob("*.nbi")) + list((tmp_path / "c" / "__pycache__").glob("ldaspark_ode_*.nbi"))
    assert len(planted) >= 5                      # rhs, rhs_into, psi_of, dae_residual, ...: numba wrote them
    for p in planted:
        p.write_bytes(pickle.dumps(_Payload(marker)))
    mod = fresh()
    assert evaluate(mod) == first
    assert not marker.exists()
    assert not [p.name for p in shared.rglob("*.nb*")]       # nothing numba reads unrecorded
    assert sum(mod.rhs_into.stats.cache_misses.values()) == 1      # the planted index: compiled again
    again = fresh()                                           # control: the recorded cache is used
    assert evaluate(again) == first
    assert sum(again.rhs_into.stats.cache_hits.values()) == 1
    # control: numba's own loader runs the same payload (the plant is live)
    from numba.core.caching import IndexDataCacheFile
    ctrl = tmp_path / "control"
    p = planted[0]
    p.write_bytes(pickle.dumps(_Payload(ctrl)))
    try:
        IndexDataCacheFile(cache_path=str(p.parent), filename_base=p.name[: -len(".nbi")],
                           source_stamp=None)._load_index()
    except Exception:
        pass
    assert ctrl.exists()
