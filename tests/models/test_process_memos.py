"""``get_scene`` builds a named scene once per process and shares it (sympy derivations of the
closed-form solutions are the cost); a builder replaced in ``SCENES`` is used, not the shared
scene of the old one."""
import pytest

from ldaspark.models import scenes
from ldaspark.core.errors import InputError


def test_named_scene_is_built_once(monkeypatch):
    calls = []
    real = scenes.SCENES["robot"]

    def counting():
        calls.append(1)
        return real()
    monkeypatch.setitem(scenes.SCENES, "robot", counting)
    a = scenes.get_scene("robot")
    b = scenes.get_scene("robot")
    assert a is b and calls == [1]
    # the initial condition of mp-particles is part of the key
    assert scenes.get_scene("mp-particles", ic=1) is not scenes.get_scene("mp-particles", ic=2)
    assert scenes.get_scene("mp-particles", ic=0) is scenes.get_scene("mp-particles")
    assert scenes.get_scene("mp-particles", ic=1).v0 != scenes.get_scene("mp-particles", ic=2).v0


def test_replaced_builder_is_used(monkeypatch):
    shared = scenes.get_scene("skate")

    def other():
        sc = scenes.skate()
        sc.description = "replaced"
        return sc
    monkeypatch.setitem(scenes.SCENES, "skate", other)
    assert scenes.get_scene("skate").description == "replaced"
    monkeypatch.undo()
    assert scenes.get_scene("skate") is shared


@pytest.mark.parametrize("name, ic", [("no-such-scene", None), ("skate", 2)])
def test_bad_names_and_ic_still_say_why(name, ic):
    with pytest.raises(InputError):
        scenes.get_scene(name, ic)


def test_mp_tableau_entries_are_built_once_and_never_shared_mutably(monkeypatch):
    import mpmath
    from ldaspark.core import families
    calls = []
    real = families.guard_digits

    def counting(s):
        calls.append(s)
        return real(s)
    monkeypatch.setattr(families, "guard_digits", counting)
    monkeypatch.setattr(families, "_MP_BUILT", {})      # this process's memo, empty: the count is order-free
    a = families.get_method("lobatto-iiia-iiib-iiid-3").mp_entries(37)
    b = families.get_method("lobatto-iiia-iiib-iiid-3").mp_entries(37)
    assert len(calls) == 1 and a == b and a is not b       # one build, two tableaux' own copies
    a["A"][0][0] += 1                                     # a caller's edit stays its own
    assert families.get_method("lobatto-iiia-iiib-iiid-3").mp_entries(37)["A"][0][0] == b["A"][0][0]
    # a perturbed copy (negative controls) changes its entry only
    base = families.get_method("gauss-2")
    pert = base.with_entry("A_hat", 0, 1, "0.1").mp_entries(37)
    with mpmath.workdps(37):
        assert pert["A_hat"][0][1] - base.mp_entries(37)["A_hat"][0][1] == mpmath.mpf("0.1")
    assert families.get_method("gauss-2").mp_entries(37)["A_hat"] == base.mp_entries(37)["A_hat"]
    # gauss-2 at 16 digits (with_entry's check of the change) and at 37 digits, each built once
    assert calls == [3, 2, 2]


def test_the_mp_tableau_memo_is_bounded(monkeypatch):
    # a sweep over dps kept every table for the life of the process
    from ldaspark.core import families
    monkeypatch.setattr(families, "_MP_BUILT", {})
    monkeypatch.setattr(families, "_MP_BUILT_MAX", 4)
    tab = families.get_method("gauss-2")
    for dps in range(20, 30):
        tab.mp_entries(dps)
    assert 1 <= len(families._MP_BUILT) <= 4
    assert ("gauss", 2, 29) in families._MP_BUILT        # the newest kept, the oldest dropped
    assert ("gauss", 2, 20) not in families._MP_BUILT


def test_stage_arrays_equal_the_plain_conversion_entry_by_entry():
    """LagrangianSystem._arrays converts only the entries that may not come back as mpf; on a
    system with integer, huge-integer, pi and Piecewise entries it gives the arrays (values and
    types) of the plain per-entry conversion ``_arr``."""
    import mpmath
    import numpy as np
    import sympy
    from ldaspark.core.backend import Backend
    from ldaspark.core.system import LagrangianSystem, _arr
    q = list(sympy.symbols("q1:3"))
    v = list(sympy.symbols("v1:3"))
    L = (v[0] ** 2 + 3 * v[1] ** 2) / 2 + sympy.pi * q[0] + 10 ** 30 * q[1] \
        - sympy.Piecewise((q[0] ** 3, q[0] > 0), (0, True)) * (1 + v[0])
    k = [v[0] + q[1] * v[1]]
    sysm = LagrangianSystem(L, k, q, v, name="odd-entries")
    bk = Backend(40)
    exprs = [sysm.L_v, sysm.L_q, sysm.k, sysm.R_lam, sysm.L_vv, sysm.L_vq, sysm.L_qq, sysm.k_q, sysm.k_v,
             sysm.R_q, sysm.R_v]
    with bk.context():
        f = sysm._fn("stage_jac", exprs, bk, True)
        for qa, qb in (("0.3", "-0.2"), ("-0.3", "0.2")):    # both branches of Piecewise
            args = [mpmath.mpf("0.1"), mpmath.mpf(qa), mpmath.mpf(qb), mpmath.mpf("0.5"), mpmath.mpf("-0.4"),
                    mpmath.mpf("0.7")]
            raw = f(*args)
            plain = [_arr(x, bk) for x in raw]
            fast = sysm._arrays("stage_jac", raw, bk)
            for a, b in zip(plain, fast):
                assert a.shape == b.shape
                for x, y in zip(a.reshape(-1), b.reshape(-1)):
                    assert type(x) is type(y) is mpmath.mpf and x == y
    # control: without the plan's call-time conversion the Piecewise entries stay ints
    assert any(type(x) is not mpmath.mpf for r in raw for x in np.asarray(r, dtype=object).reshape(-1))
