"""Rules of ``ldaspark.analysis.wellposedness`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import mpmath
import numpy as np
import pytest
from ldaspark.core.errors import InputError, NonFiniteError
from ldaspark.analysis import discrete as D
from ldaspark.analysis import wellposedness as W


# ---------------------------------------------------------------------------------------------
# wellposedness: the classification rule on synthetic singular values
def _fake_wellposed(monkeypatch, sigmas, support, svd_calls=None):
    """``sigmas(d, hf)`` -> the singular values (descending, relative to 1) the BVP Jacobian has
    at dps d and step hf; ``support`` the null-vector support the classification reads."""
    class BVP:
        def __init__(self, system, tableau, d):
            self.d = d

        def evaluate(self, t0, q0, t1, q1, xg):
            return None, ("J", self.d, t1), None, None

    def rank_info(bk, J, d):
        sig = [mpmath.mpf(x) for x in sigmas(J[1], float(J[2]))]
        return np.array(sig, dtype=object), D._deficiency(sig, d), None, "Vh-float"

    def svd(bk, J):
        if svd_calls is not None:
            svd_calls.append(J)
        return None, None, "Vh-full"
    seen = {}

    def null_support(bvp, Vh, r):
        seen["Vh"], seen["r"] = Vh, r
        return dict(support)
    monkeypatch.setattr(W, "base_point", lambda system, tab, t0, q0, v0, hf, d, newton: (hf, None, None))
    monkeypatch.setattr(W, "DiscreteBVP", BVP)
    monkeypatch.setattr(W, "_rank_info", rank_info)
    monkeypatch.setattr(W, "_svd", svd)
    monkeypatch.setattr(W, "_null_support", null_support)
    return seen


def _classify(**kw):
    return W.classify_wellposedness("skate", "gauss-1", None, None, None, 0.1, **kw)


GOOD = {"V": 0.0, "Lambda": 0.7, "v1": 0.0, "v0": 0.7}


def test_wellposed_when_no_sigma_follows_the_precision(monkeypatch):
    # a genuine small sigma ~ h^2 (the same at both precisions): not structural
    seen = _fake_wellposed(monkeypatch, lambda d, h: [1, 0.5, 3 * h * h], GOOD)
    out = _classify()
    assert out["class"] == W.WELLPOSED and out["rank_deficiency"] == 0
    assert out["structural"] == {"1": 0, "1/2": 0}
    assert out["sigma_min_power_of_h"] == pytest.approx(2, abs=1e-9)
    assert out["sigma_min_nonzero_rel"] == pytest.approx(0.03, rel=1e-9)
    assert out["sigma_stable_across_dps"] is True and out["floor_tracks_precision"] is False
    assert seen["r"] == 0 and seen["Vh"] == "Vh-float"
    assert out["deficiency"] == {"dps=30,h=0.1": 0, "dps=30,h=0.05": 0, "dps=50,h=0.1": 0, "dps=50,h=0.05": 0}
    # a finite float factor is accepted like the string "1/2"
    out2 = _classify(h_factors=(1, 0.5))
    assert out2["sigma_min_power_of_h"] == pytest.approx(2, abs=1e-9) and out2["structural"] == {"1": 0, "0.5": 0}


def test_structural_zero_is_a_gauge_or_singular_by_the_null_support(monkeypatch):
    # the last sigma sits at the precision floor 10^-d: it moves with dps (1e20 apart, more than the 1e10 of half the gap)
    sig = lambda d, h: [1, 2 * h, 10.0 ** -d]
    _fake_wellposed(monkeypatch, sig, GOOD)
    out = _classify()
    assert out["class"] == W.GAUGE and out["rank_deficiency"] == 1
    assert out["structural"] == {"1": 1, "1/2": 1} and out["floor_tracks_precision"] is True
    assert out["sigma_min_power_of_h"] == pytest.approx(1, abs=1e-9)          # 2 h: the genuine one
    for bad in ({"V": 1e-3}, {"v1": 1e-3}, {"V": 2e-8}):
        _fake_wellposed(monkeypatch, sig, {**GOOD, **bad})
        assert _classify()["class"] == W.SINGULAR
    _fake_wellposed(monkeypatch, sig, {**GOOD, "V": 1e-8, "v1": 1e-8})        # the bound is inclusive
    assert _classify()["class"] == W.GAUGE


def test_structural_rank_changing_with_h_is_singular(monkeypatch):
    # at h = 0.1 the last sigma is at the floor, at h = 0.05 it is genuine (1e-3): no clean property
    _fake_wellposed(monkeypatch, lambda d, h: [1, 0.5, 10.0 ** -d if h > 0.07 else 1e-3], GOOD)
    out = _classify()
    assert out["structural"] == {"1": 1, "1/2": 0} and out["class"] == W.SINGULAR
    # a drop of 10^-(gap/2) = 1e-10 between 30 and 50 digits is not enough (strict): 1e-20 vs 1e-30
    _fake_wellposed(monkeypatch, lambda d, h: [1, 0.5, 1e-20 if d == 30 else 1e-30], GOOD)
    assert _classify()["structural"] == {"1": 0, "1/2": 0}
    _fake_wellposed(monkeypatch, lambda d, h: [1, 0.5, 1e-20 if d == 30 else 0.99e-30], GOOD)
    assert _classify()["structural"] == {"1": 1, "1/2": 1}


def test_genuine_sigma_below_float64_resolution_takes_the_full_svd(monkeypatch):
    calls = []
    seen = _fake_wellposed(monkeypatch, lambda d, h: [1, 1e-13, 10.0 ** -d], GOOD, calls)
    out = _classify()
    assert out["rank_deficiency"] == 1 and seen["Vh"] == "Vh-full" and len(calls) == 1
    assert calls[0][1] == 50 and float(calls[0][2]) == pytest.approx(0.1)     # the last dps, the first h
    calls.clear()
    seen = _fake_wellposed(monkeypatch, lambda d, h: [1, 1e-11, 10.0 ** -d], GOOD, calls)
    _classify()
    assert seen["Vh"] == "Vh-float" and not calls
    # the stability flag compares the smallest genuine sigma at the two precisions
    _fake_wellposed(monkeypatch, lambda d, h: [1, 0.5, 1e-3 * (1 + 1e-9 * (d == 50))], GOOD)
    assert _classify()["sigma_stable_across_dps"] is False


def test_wellposedness_argument_checks():
    for dps in ((30,), (30, 30), 30):
        with pytest.raises(InputError, match="dps must be two or more"):
            _classify(dps=dps)
    for hf in ((1,), (1, "1")):
        with pytest.raises(InputError, match="h_factors must be two or more"):
            _classify(h_factors=hf)
    for bad in (0, -1, "x", True, float("inf"), float("nan"), "1/0", "10000000"):
        with pytest.raises(InputError, match="positive rationals"):
            _classify(h_factors=(1, bad))


def test_a_step_factor_with_a_huge_exponent_is_refused_without_building_it():
    """Fraction("1e999999999") builds 10^999999999 before any bound is checked: the argument check
    ran for minutes (killed at 600 s). The text is parsed within bounds (at most 3 exponent digits):
    refused at once. Controls: the same forms with small exponents and "p/q" are read exactly."""
    from fractions import Fraction
    from ldaspark.analysis.wellposedness import _step_factor
    for bad in ("1e999999999", "1e-999999999", "1" * 30, "1/" + "7" * 30, "1e1000"):
        assert _step_factor(bad) is None
        with pytest.raises(InputError, match="positive rationals"):
            _classify(h_factors=(1, bad))
    assert _step_factor("5e-1") == Fraction(1, 2) and _step_factor(" 1 / 4 ") == Fraction(1, 4)
    assert _step_factor(0.1) == Fraction(1, 10) and _step_factor(Fraction(2, 3)) == Fraction(2, 3)


def test_the_null_vectors_and_their_recomputation_are_those_of_the_highest_precision(monkeypatch):
    """With three precisions the null space is read at the last (highest) one, and whether a
    genuine sigma is below float64 resolution is decided there too."""
    from ldaspark.analysis import wellposedness as W
    _fake_wellposed(monkeypatch, lambda d, h: [1, 2 * h, 10.0 ** -d], GOOD)
    got = {}
    monkeypatch.setattr(W, "_null_support", lambda bvp, Vh, r: got.update(d=bvp.d) or dict(GOOD))
    assert _classify(dps=(30, 40, 50))["rank_deficiency"] == 1 and got["d"] == 50
    calls = []
    seen = _fake_wellposed(monkeypatch, lambda d, h: [1, 1e-14 if d == 30 else 1e-11, 10.0 ** -d], GOOD,
                           svd_calls=calls)
    assert _classify()["rank_deficiency"] == 1 and seen["Vh"] == "Vh-float" and calls == []


def test_the_null_vectors_are_recomputed_only_under_a_genuine_sigma_below_float64(monkeypatch):
    """With one structural zero (at the precision floor), the float64 null vectors serve unless
    the smallest *genuine* sigma (the one above the structural zeros) is below 1e-12; the
    structural zero itself always is, and must not decide."""
    calls = []
    seen = _fake_wellposed(monkeypatch, lambda d, h: [1, 2 * h, 10.0 ** -d], GOOD, svd_calls=calls)
    assert _classify()["rank_deficiency"] == 1 and seen["Vh"] == "Vh-float" and calls == []
    seen = _fake_wellposed(monkeypatch, lambda d, h: [1, 1e-14 * h, 10.0 ** -d], GOOD, svd_calls=calls)
    assert _classify()["rank_deficiency"] == 1 and seen["Vh"] == "Vh-full" and len(calls) == 1


def test_a_structural_zero_is_told_by_the_precisions_given(monkeypatch):
    """A sigma at the precision floor 10^-d drops by 10^-(d_hi - d_lo) between the lowest and the
    highest precision given, whatever their order and gap; the threshold is derived from that gap
    (half of it: 10^-3 for 30 and 36 digits, 10^-10 for 30 and 50). Before, a fixed 1e-8 missed a
    6-digit gap and precisions given in decreasing order: the gauge-deficient Lobatto IIIA-B 2 on
    the particle (sigma 9.9e-32 at 30 digits, 9.4e-38 at 36) was classified well-posed."""
    sig = lambda d, h: [1, 2 * h, 10.0 ** -d]
    _fake_wellposed(monkeypatch, sig, GOOD)
    for dps in ((30, 36), (50, 30), (50, 30, 40)):
        out = _classify(dps=dps)
        assert out["class"] == W.GAUGE and out["rank_deficiency"] == 1, (dps, out)
    # a genuine sigma (the same at every precision) stays genuine at a small gap
    _fake_wellposed(monkeypatch, lambda d, h: [1, 0.5, 3 * h * h], GOOD)
    assert _classify(dps=(30, 36))["rank_deficiency"] == 0
    monkeypatch.undo()
    from ldaspark.core.families import get_method
    from ldaspark.models.scenes import get_scene
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial(60)
    tab = get_method("lobatto-iiia-iiib-2", exact=True)
    for dps in ((30, 36), (50, 30)):
        out = W.classify_wellposedness(sc.system, tab, t0, q0, v0, "0.1", dps=dps)
        assert out["class"] == W.GAUGE and out["rank_deficiency"] == 1, (dps, out["sigma"])
