"""The verdict rules of ``ldaspark.lab.claims.claims_paper`` fed their failing values: the value a
computation that dropped the term a claim is about gives, computed for real on a system where
that term is nonzero (docs/verification.md, "Every check fed its failing value").

Each computation returns the identity's residual and, beside it, the same identity without one
term (the energy balance of 2.2 without L_t or without the psi b_t term, (16)/(18) without the
discrete force f_d^{E-}, (15a) without the forces, the printed (20b)). Fed that companion as the
identity's residual, the record must say "fail"; fed the real residual, "pass" (same data). The
system is chosen so that the term is nonzero there (the time-L system has L_t != 0, affine-b
has b_t != 0, the rheonomic skate off C_d has f_d^{E-} != 0); on a system where the term
vanishes the companion equals the residual, and the check could not tell.
Cost: ~3 s (each computation once, memoized)."""
from __future__ import annotations

import functools

import pytest

from ldaspark.core.families import get_method
from ldaspark.lab.claims import claims_paper as cp
from ldaspark.models.scenes import get_scene

# the real computations, bound before any test replaces the module's names
REAL = {n: getattr(cp, n) for n in ("exact_balance", "discrete_balance", "exact_identities", "definition1_residuals")}


@functools.lru_cache(maxsize=None)
def _exact_balance(name):
    return REAL["exact_balance"](name, dps=28, stages=8)


@functools.lru_cache(maxsize=None)
def _discrete_balance(name, method):
    return REAL["discrete_balance"](name, get_method(method, exact=True), hs=cp.ENERGY_HS)


@functools.lru_cache(maxsize=None)
def _identities(scene):
    return REAL["exact_identities"](scene, offset=cp.OFF_CD)


@functools.lru_cache(maxsize=None)
def _definition1():
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial(60)
    return REAL["definition1_residuals"](sc.system, get_method("euler-ii", exact=True), t0, q0, v0, "0.1", n_steps=10,
                                    dps=30)


def _fed(real, **swap):
    """The real result with entry ``key`` replaced by the real entry ``swap[key]``."""
    return {**real, **{k: real[v] for k, v in swap.items()}}


def _energy(monkeypatch, exact_swap=None, discrete_swap=None):
    monkeypatch.setattr(cp, "exact_balance", lambda name, **k: _fed(_exact_balance(name), **(exact_swap or {}).get(
        name, {})))
    monkeypatch.setattr(cp, "discrete_balance", lambda name, tab, **k: _fed(_discrete_balance(name, tab.name),
                                                                              **(discrete_swap or {})))
    return {(r["scene"], r["method"]): r for r in cp.energy_records(quick=True)}


@pytest.mark.parametrize("system, dropped", [("time-L", "without_L_t"), ("affine-b", "without_psi_term")])
def test_the_energy_balance_fails_without_the_term_its_system_has(monkeypatch, system, dropped):
    """2.2: dE/dt = -L_t - psi^T b_t along the exact flow. time-L has L_t != 0 (b_t = 0),
    affine-b has b_t != 0 (L_t = 0): each balance without its system's term misses by Delta E's
    size (measured 0.58 and 0.16), far above TOL_EXACT; the other term's absence changes
    nothing there (the companion equals the residual to the 28 digits)."""
    real = _exact_balance(system)
    assert real[dropped] >= cp.NEG and real["delta_E"] > 1e-3          # the term moves E here
    other = {"without_L_t": "without_psi_term", "without_psi_term": "without_L_t"}[dropped]
    good = _energy(monkeypatch)[(system, "exact-flow")]
    assert good["status"] == "pass"
    bad = _energy(monkeypatch, exact_swap={system: {"pointwise": dropped}})[(system, "exact-flow")]
    assert bad["status"] == "fail" and bad["residual"] >= cp.NEG
    if system == "affine-b":        # L_t = 0 here: dropping it is invisible, as the docstring says
        assert real[other] <= cp.TOL_EXACT


def test_the_discrete_energy_order_fails_without_L_t(monkeypatch):
    """Delta E - h sum b_i (-L_t - psi b_t)(T_i) ~ h^{p+1} (Gauss-2: 5); the quadrature without
    L_t leaves Delta E itself, ~h^1 on the time-L system (measured 1.02): the two-sided order
    rule (|observed - 5| <= 0.4) must fail on it."""
    real = _discrete_balance("time-L", "gauss-2")
    assert abs(real["order_mismatch_without_L_t"] - 1) < 0.5
    assert _energy(monkeypatch)[("time-L", "gauss-2")]["status"] == "pass"
    bad = _energy(monkeypatch, discrete_swap={"order_mismatch": "order_mismatch_without_L_t"})
    assert bad[("time-L", "gauss-2")]["status"] == "fail"


def _section5(monkeypatch, swap):
    monkeypatch.setattr(cp, "exact_identities", lambda scn, **k: _fed(_identities("rheonomic-skate"), **swap))
    # the other section-5 computations are not under test here: their passing values
    monkeypatch.setattr(cp, "antisymmetry", lambda scn, **k: {"L": 0.0, "f_plus": 0.0, "f_minus": 0.0,
                                                              "wrong-pairing": 1.0})
    monkeypatch.setattr(cp, "holonomic_exact", lambda scn, **k: {"tangential": 0.0 if scn == "pendulum" else 1.0,
                                                                 "full": 1.0})
    return cp.section5_records(quick=True)


@pytest.mark.parametrize("claim, swap", [("16", {"16": "16-without-force"}), ("18", {"18": "18-without-force"}),
                                         ("20-integral", {"20b-corrected": "20b-printed"})])
def test_the_exact_discrete_identities_fail_without_the_discrete_force(monkeypatch, claim, swap):
    """(16), (18): dL_d^E/dq0 = -p0 - f_d^{E-} (and at q1 with f_d^{E+}); off C_d on the
    rheonomic skate the exact discrete forces are nonzero (|f_d^{E-}| ~ 4e-4, |f_d^{E+}| ~ 7e-3),
    so the identity against the bare momentum misses by them. (20b) as printed (sign slip)
    misses by 0.11. Fed those, the records fail; fed the real residuals (<= 1e-40), they pass."""
    real = _identities("rheonomic-skate")
    assert real["f_d_minus"] > 1e-4 and real["f_d_plus"] > 1e-4
    mine = [r for r in _section5(monkeypatch, {}) if r["claim"] == claim and r["method"] == "exact-flow"]
    assert mine and all(r["status"] == "pass" for r in mine)
    bad = [r for r in _section5(monkeypatch, swap) if r["claim"] == claim and r["method"] == "exact-flow"]
    assert bad and all(r["status"] == "fail" for r in bad), bad


def test_definition1_15a_fails_without_the_forces(monkeypatch):
    """(15a) sums the discrete momenta and forces along a trajectory; on the particle with
    Euler II the forces are nonzero (|f| ~ 0.11), and the sum without them misses by 0.13."""
    real = _definition1()
    assert real["f_scale"] > 1e-2

    def run(swap):
        monkeypatch.setattr(cp, "definition1_residuals", lambda *a, **k: _fed(real, **swap))
        return [r for r in cp.definition1_records(quick=True) if r["claim"] == "15a" and r["expected"] == "pass"]
    assert [r["status"] for r in run({})] == ["pass"]
    assert [r["status"] for r in run({"15a": "15a_without_forces"})] == ["fail"]


def test_the_section7_reduction_fails_for_the_other_euler_system():
    """Section 7: the Euler I step is not the printed Euler II system on a K(q) that varies
    (the reduction's term K(q1) vs K(q0) is nonzero): judged as a pass claim it fails (0.02)."""
    r = cp.reduction("euler-ii", get_method("euler-i", exact=True), constant_K=False)
    assert cp._st(r["diff"], cp.TOL_S7) == "fail"
    r_ok = cp.reduction("euler-ii", get_method("euler-ii", exact=True), constant_K=False)
    assert cp._st(max(r_ok["diff"], r_ok["stage"]), cp.TOL_S7) == "pass"


def test_one_newton_iteration_fails_when_K_varies():
    """7.1: Euler I is linearly implicit (one Newton iteration solves (21)) only for constant K;
    with K(q) the residual after one iteration stays (0.058)."""
    r = cp.one_newton_iteration(get_method("euler-i", exact=True), False, "generic")
    assert cp._st(r["after_one"], cp.TOL_S7) == "fail"
    r_ok = cp.one_newton_iteration(get_method("euler-i", exact=True), True, "generic")
    assert cp._st(r_ok["after_one"], cp.TOL_S7) == "pass"
