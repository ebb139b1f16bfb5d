"""Section 7: s-stage Gauss SPARK methods have order 2s; s-stage Lobatto IIIA-B and IIIA-B-D
SPARK methods have order 2s - 2 (both q and v), checked as least-squares observed orders over
the asymptotic window within 0.3 of the claim, against references that are never the method
being measured (the skate's closed form; the ODE (3a-b) by mpmath's Taylor solver).

Default: float64 and short intervals; one mpmath case (order 6). ``--exhaustive``: all four
scenes, Gauss s = 1..5, Lobatto IIIA-B / IIIA-B-D s = 2..5, mpmath for orders >= 6.
Psi has no claim; we check only that the stage multipliers converge and record their order.
"""
import pytest

from ldaspark.lab.theory.orders import (claimed_order_of, estimate_order, floor_for, make_reference,
                                  measure_errors, order_records)
from ldaspark.models.scenes import PAPER_SCENES, get_scene
from ldaspark.core.spark import integrate
from ldaspark.core.families import gauss

TOL = 0.3
T_END = 1.0


def _orders(method, scene_name, ref, n_list, dps=None, newton="full"):
    sc = get_scene(scene_name)
    m = measure_errors(method, sc, ref, T_END, n_list, dps=dps, newton=newton)
    recs = order_records(method, scene_name, claimed_order_of(method), m, dps, T_END, ref.kind)
    return {r["variable"]: r for r in recs}


def _psi_converges(r):
    """Stage multipliers converge: an order > 0.5, or exact to round-off at every h."""
    return all(e <= r["floor"] for e in r["errors"]) or (
        r["observed_order"] is not None and r["observed_order"] > 0.5)


def _assert_claim(recs, claimed):
    for var in ("q", "v"):
        r = recs[var]
        assert r["observed_order"] is not None, f"{var}: no asymptotic window: {r['errors']}"
        assert abs(r["observed_order"] - claimed) <= TOL, (
            f"{r['method']} {r['scene']} {var}: observed {r['observed_order']:.3f}, claimed {claimed}, "
            f"pairwise {r['pairwise_orders']}, errors {r['errors']}")


@pytest.fixture(scope="module")
def skate_ref():
    return make_reference(get_scene("skate"), 40)


@pytest.fixture(scope="module")
def particle_ref():
    return make_reference(get_scene("particle"), 30)


@pytest.mark.parametrize("method", ["gauss-1", "gauss-2", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3",
                                    "lobatto-iiia-iiib-iiid-2", "lobatto-iiia-iiib-iiid-3"])
def test_order_skate_float64(method, skate_ref):
    n_list = [8, 16, 32, 64] if claimed_order_of(method) <= 2 else [4, 8, 16, 32]
    recs = _orders(method, "skate", skate_ref, n_list)
    _assert_claim(recs, claimed_order_of(method))
    assert _psi_converges(recs["psi"]), recs["psi"]["errors"]


@pytest.mark.parametrize("method", ["gauss-2", "lobatto-iiia-iiib-iiid-3"])
def test_order_particle_against_ode_reference(method, particle_ref):
    recs = _orders(method, "particle", particle_ref, [4, 8, 16, 32])
    _assert_claim(recs, claimed_order_of(method))


def test_order_mp_particles_nonholonomic_variant():
    """The nonholonomic variant of 8.4 (the printed constraint is integrable): order 2s-2 holds."""
    recs = _orders("lobatto-iiia-iiib-3", "mp-particles-nh", _ref("mp-particles-nh"), [4, 8, 16, 32])
    _assert_claim(recs, 4)


def test_order_6_needs_mpmath_skate(skate_ref):
    """Gauss s = 3 (order 6) at 25 digits: the float64 floor would cut the window short."""
    recs = _orders("gauss-3", "skate", skate_ref, [4, 8, 16, 32], dps=25, newton="simplified")
    _assert_claim(recs, 6)
    assert recs["q"]["window"] == [0, 3] and min(recs["q"]["errors"]) < 1e-12


def test_negative_control_perturbed_tableau_fails_claim(skate_ref):
    """A Gauss-2 tableau with one entry of A off by 1e-2 violates the order-4 check: the
    measurement has teeth."""
    tab = gauss(2).with_entry("A", 0, 1, 1e-2)
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    qr, _, _ = skate_ref(T_END)
    hs, errs = [], []
    for N in (4, 8, 16, 32):
        sol = integrate(sc.system, tab, t0, q0, v0, T_END / N, n_steps=N)
        hs.append(T_END / N)
        errs.append(float(max(abs(a - b) for a, b in zip(sol.q[-1], qr))))
    est = estimate_order(hs, errs, floor_for(None, 1.0))
    assert est.observed_order is not None and abs(est.observed_order - 4) > TOL


# --- exhaustive sweep: every paper scene, s up to 5 ---------------------------------------
def _plan(method):
    p = claimed_order_of(method)
    if p <= 2:
        return None, [8, 16, 32, 64, 128], "full"
    if p <= 4:
        return None, [4, 8, 16, 32, 64], "full"
    return (25 if p <= 8 else 32), [5, 10, 20, 40], "simplified"


_REFS = {}


def _ref(scene_name):
    if scene_name not in _REFS:
        _REFS[scene_name] = make_reference(get_scene(scene_name), 40)
    return _REFS[scene_name]


EXHAUSTIVE_METHODS = ([f"gauss-{s}" for s in range(1, 6)] + [f"lobatto-iiia-iiib-{s}" for s in range(2, 6)]
                      + [f"lobatto-iiia-iiib-iiid-{s}" for s in range(2, 6)])


@pytest.mark.exhaustive
@pytest.mark.parametrize("scene_name", tuple(PAPER_SCENES) + ("mp-particles-nh",))
@pytest.mark.parametrize("method", EXHAUSTIVE_METHODS)
def test_order_exhaustive(method, scene_name):
    dps, n_list, newton = _plan(method)
    recs = _orders(method, scene_name, _ref(scene_name), n_list, dps=dps, newton=newton)
    _assert_claim(recs, claimed_order_of(method))
    assert _psi_converges(recs["psi"]), recs["psi"]["errors"]
