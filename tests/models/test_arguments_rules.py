"""Rules of ``ldaspark.models.arguments`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import types
import numpy as np
import pytest
from types import SimpleNamespace
import mpmath
from tableau_fakes import approx


# ==== symmetry: the identities' arithmetic on synthetic BVP results ===========================
def _symmetry_with(monkeypatch, d):
    """check_symmetry with the BVP solves, projectors and steps replaced by the records in d."""
    from ldaspark.models import arguments
    from ldaspark.analysis import symmetry as sy
    seen = {"dl": [], "steps": []}
    mk = lambda **kw: types.SimpleNamespace(**kw)
    fwd = mk(L_d=d["L"][0], f_d_minus=np.array(d["fm"][0]), f_d_plus=np.array(d["fp"][0]), p0=np.array(d["p0"]),
             p1=np.array(d["p1"]), x="XF", wellposed="regular", rank_deficiency=0)
    rev = mk(L_d=d["L"][1], f_d_minus=np.array(d["fm"][1]), f_d_plus=np.array(d["fp"][1]), p0=None, p1=None,
             x="XR", wellposed="?", rank_deficiency=7)
    monkeypatch.setattr(arguments, "theory_args", lambda *a, **k: a[:5])
    monkeypatch.setattr(sy, "base_point", lambda S, T, t0, q0, v0, h, dps: (t0 + h, "Q1", "XG"))

    def dl(S, T, ta, qa, tb, qb, dps=None, x_guess=None, gauge_ref=None):
        seen["dl"].append((ta, qa, tb, qb, x_guess, gauge_ref))
        return fwd if len(seen["dl"]) == 1 else rev
    monkeypatch.setattr(sy, "discrete_lagrangian", dl)

    class BVP:
        def __init__(self, S, T, dps):
            pass

        def unpack(self, x):
            assert x == "XF"
            return np.array([1, 2]), np.array([3, 4]), "v1", "v0"

        def pack(self, V, Lam, va, vb):
            seen["pack"] = (list(V), list(Lam), va, vb)
            return "XR0"
    monkeypatch.setattr(sy, "DiscreteBVP", BVP)
    P = {id(fwd): (np.diag([1.0, 0.0]), 1), id(rev): (np.diag([0.0, 1.0]), 2)}
    monkeypatch.setattr(sy, "_tangent_projector", lambda res, which: P[id(res)])
    q0, v0 = np.array(d["q0"]), np.array(d["v0"])

    class Meth:
        def __init__(self, S, T, dps=None, newton=None):
            pass

        def step(self, t, q, v, h):
            seen["steps"].append((t, h))
            return mk(t1=t + h, q1=q0 + np.array(d["dq"]), v1=v0 + np.array(d["dv"]))
    monkeypatch.setattr(sy, "SparkMethod", Meth)
    monkeypatch.setattr(sy, "ivp_step", lambda meth, t, q, v, h: mk(t1=t + h, q1=q + 1, v1=v + 1))
    r = sy.check_symmetry("S", "T", 0.0, q0, v0, 0.25, dps=None)
    return r, seen


SYM_DATA = [
    dict(L=(2.0, -1.5), fm=([1.0, 2.0], [5.0, -4.25]), fp=([3.0, 4.0], [-0.5, 7.0]), p0=[0.1, -0.2], p1=[0.3, 0.4],
         q0=[3.0, 0.0], v0=[0.0, 0.5], dq=[1e-3, 0.0], dv=[0.0, -2e-3]),
    dict(L=(-0.5, 0.25), fm=([-6.0, 0.5], [0.1, 0.2]), fp=([0.0, 0.3], [5.0, 9.0]), p0=[0.05, 0.1], p1=[20.0, 0.0],
         q0=[0.5, 0.0], v0=[0.0, -0.25], dq=[0.0, 3e-3], dv=[-1e-3, 0.0]),
    # a scene at rest: every covector zero, the scales fall back to 1e-300 (and 1 for the state)
    dict(L=(0.0, 0.0), fm=([0.0, 0.0], [0.0, 0.0]), fp=([0.0, 0.0], [0.0, 0.0]), p0=[0.0, 0.0], p1=[0.0, 0.0],
         q0=[0.0, 0.0], v0=[0.0, 0.0], dq=[0.0, 3e-3], dv=[-1e-3, 0.0]),
]


@pytest.mark.parametrize("d", SYM_DATA)
def test_check_symmetry_identities_and_scales(monkeypatch, d):
    r, seen = _symmetry_with(monkeypatch, d)
    n = lambda x: float(np.max(np.abs(np.asarray(x, dtype=float))))
    P0, P1 = np.diag([1.0, 0.0]), np.diag([0.0, 1.0])
    fmF, fmR, fpF, fpR = (np.array(x) for x in (d["fm"][0], d["fm"][1], d["fp"][0], d["fp"][1]))
    assert r["symmetry-Ld"] == approx(abs(d["L"][0] + d["L"][1]) / max(abs(d["L"][0]), 1e-300), rel=1e-12)
    norms_p = (n(P0 @ fmF), n(P0 @ fpR))
    norms_m = (n(P1 @ fpF), n(P1 @ fmR))
    sc = max(*norms_p, *norms_m, n(d["p0"]), n(d["p1"]), n(fmF), n(fpF), 1e-300)
    assert r["symmetry-fd-plus"] == approx(n(P0 @ (fmF + fpR)) / sc, rel=1e-12)
    assert r["symmetry-fd-minus"] == approx(n(P1 @ (fpF + fmR)) / sc, rel=1e-12)
    sc_full = max(n(fmF), n(fpF), n(d["p0"]), 1e-300)
    assert r["symmetry-fd-unrestricted"] == (approx(n(fmF + fpR) / sc_full, rel=1e-12),
                                             approx(n(fpF + fmR) / sc_full, rel=1e-12))
    sc_y = max(n(d["q0"]), n(d["v0"]), 1.0)
    assert r["symmetry-Phi"] == approx(max(n(d["dq"]), n(d["dv"])) / sc_y, rel=1e-12)
    assert r["fd_plus_identity_norms"] == norms_p and r["fd_minus_identity_norms"] == norms_m
    assert r["fd_restricted_norm"] == (n(P0 @ fmF), n(P1 @ fpF)) and r["tangent_dim"] == (1, 2)
    assert r["wellposed"] == "regular" and r["rank_deficiency"] == 0
    # the reversed BVP: endpoints exchanged, stages reversed, multipliers reversed and negated
    assert seen["pack"] == ([2, 1], [-4, -3], "v0", "v1")
    assert seen["dl"][0][0] == 0.0 and seen["dl"][0][2:4] == (0.25, "Q1")
    assert seen["dl"][0][4] == "XG" and seen["dl"][1][4] == "XR0" and seen["dl"][1][5] == "XR0"
    assert seen["dl"][1][0] == 0.25 and seen["dl"][1][1] == "Q1" and seen["dl"][1][2] == 0.0
    assert seen["steps"] == [(0.25, -0.25)]          # Phi_{-h} from the end of Phi_h


def _close(x, rel=1e-9):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny numbers."""
    return pytest.approx(x, rel=rel, abs=0.0)


# --- section 4.1, the symmetry identities under (23): the scales of the relative residuals --------
def _mpv(*xs):
    return np.array([mpmath.mpf(x) for x in xs], dtype=object)


def _fake_symmetry(monkeypatch, rev_fp, rev_fm):
    """check_symmetry on constructed forward / reversed BVP results (n = 2): the projector of the
    forward BVP keeps direction 1 (k depends on q_2 only), that of the reversed one direction 2;
    the round trip Phi_-h(Phi_h(y)) misses q0 by 1e-6 and v0 by 1e-9."""
    from ldaspark.models import arguments
    from ldaspark.analysis import symmetry
    dps = 20

    def res(fm, fp, M):
        return SimpleNamespace(L_d=mpmath.mpf(2), f_d_minus=_mpv(*fm), f_d_plus=_mpv(*fp), p0=_mpv(0, 0),
                               p1=_mpv(0, 0), x=None, wellposed="well-posed", rank_deficiency=0, dps=dps,
                               extra={"gauge": None, "dk0_dq": [np.array([[mpmath.mpf(x) for x in M]], dtype=object)] * 2})
    fwd = res((1, 0), (0, 2), (0, 1))
    rev = res(rev_fm, rev_fp, (1, 0))
    bvps = [fwd, rev]
    q0, v0 = _mpv("0.5", 0), _mpv("0.25", 0)
    monkeypatch.setattr(arguments, "theory_args", lambda *a, **k: a[:5])
    monkeypatch.setattr(symmetry, "base_point", lambda system, tab, t0, q0, v0, h, dps: (t0 + mpmath.mpf(h), q0, None))
    monkeypatch.setattr(symmetry, "discrete_lagrangian", lambda *a, **k: bvps.pop(0))
    monkeypatch.setattr(symmetry, "DiscreteBVP", lambda *a: SimpleNamespace(
        unpack=lambda x: (np.zeros(1), np.zeros(1), None, None), pack=lambda *a: None))
    r1 = SimpleNamespace(t1=1, q1=q0, v1=v0)
    r2 = SimpleNamespace(q1=q0 + _mpv("1e-6", 0), v1=v0 + _mpv("1e-9", 0))
    monkeypatch.setattr(symmetry, "ivp_step", lambda meth, t0, q0, v0, h: r1)
    monkeypatch.setattr(symmetry, "SparkMethod", lambda *a, **k: SimpleNamespace(step=lambda *a: r2))
    return symmetry.check_symmetry(None, None, 0, q0, v0, "0.1", dps=dps)


def test_symmetry_fd_plus_is_relative_to_the_larger_of_its_two_covectors(monkeypatch):
    # P0 f_d^+(rev) = 100 dominates P0 f_d^-(fwd) = 1: the scale is 100, |P0 (f^- + f^+(rev))| = 101
    r = _fake_symmetry(monkeypatch, rev_fp=(100, 0), rev_fm=(0, 0))
    assert r["fd_plus_identity_norms"] == (1.0, 100.0)
    assert r["symmetry-fd-plus"] == _close(101 / 100)
    # the unrestricted comparison is relative to max(|f_d^-|, |f_d^+|, |p0|) of the forward BVP = 2
    assert r["symmetry-fd-unrestricted"] == (_close(101 / 2), _close(2 / 2))
    # Phi_-h(Phi_h(y)) - y: the worse of q (1e-6) and v (1e-9), relative to max(|y|, 1) = 1
    assert r["symmetry-Phi"] == _close(1e-6)
    assert r["tangent_dim"] == (1, 1)


def test_symmetry_fd_minus_is_relative_to_the_larger_of_its_two_covectors(monkeypatch):
    # P1 f_d^-(rev) = 200 dominates P1 f_d^+(fwd) = 2: the scale is 200, |P1 (f^+ + f^-(rev))| = 202
    r = _fake_symmetry(monkeypatch, rev_fp=(0, 0), rev_fm=(0, 200))
    assert r["fd_minus_identity_norms"] == (2.0, 200.0)
    assert r["symmetry-fd-minus"] == _close(202 / 200)
    assert r["symmetry-fd-plus"] == _close(1 / 200)
