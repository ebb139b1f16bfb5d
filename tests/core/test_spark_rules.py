"""Rules of ``ldaspark.core.spark`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import numpy as np
import ldaspark
from ldaspark.lab.theory import energy_balance as EB
from ldaspark.analysis import flow_jacobian as FJ
import ldaspark.core.spark as spark_mod
from ldaspark.core.families import get_method
from verification import systems_checks as SC
import types
import mpmath
import pytest
# --- lab/reports/stability_stiff.py -----------------------------------------------------------------
from ldaspark.lab.reports import stability_stiff as SS  # noqa: E402
import sympy
from system_fakes import two_constraints


def test_flow_jacobian_uses_the_given_t0_without_a_scene():
    """A time-dependent L (energy_balance's time-L): the step from t0 = 1 differs from the step
    from 0, and flow_jacobian's end point is the one from the t0 it was given."""
    from ldaspark.core.spark import SparkMethod
    sysm, q0, v0 = EB.energy_system("time-L")
    q0, v0 = [float(x) for x in q0], [float(x) for x in v0]
    fj = FJ.flow_jacobian(sysm, "gauss-1", q0, v0, 0.1, t0=1.0)
    meth = SparkMethod(sysm, ldaspark.gauss(1))
    at1 = meth.step(1.0, np.array(q0), np.array(v0), 0.1)
    at0 = meth.step(0.0, np.array(q0), np.array(v0), 0.1)
    assert np.max(np.abs(at1.v1 - at0.v1)) > 1e-3            # t0 matters on this system
    assert np.max(np.abs(fj.v1 - at1.v1)) < 1e-12 and np.max(np.abs(fj.q1 - at1.q1)) < 1e-12


def test_observed_orders_of_q_v_and_of_a_quantity(monkeypatch):
    seen = []

    def fake_measure(meth, sc, reference, t_end, nl):
        seen.append((meth, sc.system, reference, t_end, list(nl)))
        p = get_method(meth).claimed_order
        h = [1.0 / N for N in nl]
        return {"h": h, "q": [x ** p for x in h], "v": [3 * x ** (p - 1) for x in h], "scale": {"q": 1.0, "v": 1.0}}
    monkeypatch.setattr(SC, "measure_errors", fake_measure)
    plan = (("gauss-1", [8, 16, 32, 64]), ("gauss-2", [4, 8, 16, 32]))
    sc = type("Sc", (), {})()
    sc.system = "own"
    ref = object()
    out = SC.observed_orders(sc, ref, plan=plan)
    assert set(out) == {"gauss-1", "gauss-2"}
    for meth, p in (("gauss-1", 2), ("gauss-2", 4)):
        claimed, obs, errs = out[meth]
        assert claimed == p and abs(obs["q"] - p) < 1e-9 and abs(obs["v"] - (p - 1)) < 1e-9, out
        assert errs["q"][0] == (1.0 / plan[[m for m, _ in plan].index(meth)][1][0]) ** p
    assert seen[0] == ("gauss-1", "own", ref, 1.0, [8, 16, 32, 64])
    out = SC.observed_orders(sc, ref, t_end=2.0, plan=plan[:1], system="wrong")
    assert seen[-1][1] == "wrong" and seen[-1][3] == 2.0 and sc.system == "own"

    # a derived quantity: integrate faked, error 0.5 h^p from an exact quantity 1
    calls = []

    def fake_integrate(S, tab, t0, q0, v0, h, n_steps=None, newton=None):
        calls.append((S, tab.name, t0, h, n_steps))
        e = 0.5 * h ** tab.claimed_order
        # the last step is the one measured: earlier rows are far off
        return type("Sol", (), {"q": [np.array([9.0]), np.array([7.0]), np.array([1.0 + e])],
                                "v": [None, np.array([5.0]), np.array([-e])]})()
    monkeypatch.setattr(spark_mod, "integrate", fake_integrate)
    hs_seen, real_estimate = [], SC.estimate_order
    monkeypatch.setattr(SC, "estimate_order", lambda hs, errs, floor: hs_seen.append(list(hs)) or real_estimate(hs, errs, floor))
    sc2 = type("Sc", (), {"system": "own", "initial": lambda self: (0.25, [0.0], [0.0])})()
    refq = lambda t: np.array([1.0, 0.0]) if t == 1.0 else np.array([np.nan, np.nan])
    out = SC.observed_orders(sc2, refq, plan=plan, quantity=lambda q, v: np.array([q[0], v[0]]))
    for meth, p in (("gauss-1", 2), ("gauss-2", 4)):
        claimed, obs, errs = out[meth]
        assert claimed == p and abs(obs["quantity"] - p) < 1e-9, out
    assert all(S == "own" and abs(h * N - 0.75) < 1e-15 for S, _, _, h, N in calls)
    assert [N for *_, N in calls] == [8, 16, 32, 64, 4, 8, 16, 32]
    # the step sizes the order is fitted on are those of the runs, (t_end - t0) / N
    assert hs_seen == [[0.75 / N for N in nl] for _, nl in plan], hs_seen
    SC.observed_orders(sc2, refq, plan=plan[:1], quantity=lambda q, v: np.array([q[0], v[0]]), system="wrong")
    assert calls[-1][0] == "wrong"


def test_dps_extreme_reports_the_largest_component_difference(monkeypatch):
    import ldaspark.core.spark as spark
    import ldaspark.models.scenes as scenes

    class Scene:
        system = None

        @staticmethod
        def initial(dps):
            return 0, [0, 0], [0, 0]

    def fake_integrate(system, tab, t0, q0, v0, h, n_steps, dps):
        with mpmath.workdps(dps):
            eps = mpmath.mpf(0) if dps == 30 else mpmath.mpf(1)
            q = [mpmath.mpf(1), mpmath.mpf(2) + eps * mpmath.mpf("1e-12")]
            v = [mpmath.mpf(3) + eps * mpmath.mpf("1e-20"), mpmath.mpf(4)]
        return types.SimpleNamespace(q=[q], v=[v], stats={"mean_iterations": 2.0})

    monkeypatch.setattr(scenes, "get_scene", lambda name: Scene)
    monkeypatch.setattr(spark, "integrate", fake_integrate)
    (row,) = SS.dps_extreme((30,), n=1)
    assert row["ref_dps"] == 70
    assert row["log10_diff"] == pytest.approx(-12.0, abs=1e-9)


# --- the flow Jacobian's dependent velocities ---------------------------------------------------------


def _consistent_v(kfun, q, vfree, dps):
    """v3, v4 with k(q, v) = 0 (k linear in v3, v4: one exact 2x2 solve at dps digits)."""
    with mpmath.workdps(dps):
        a = kfun(q, [vfree[0], vfree[1], 0, 0])
        c3 = [kfun(q, [vfree[0], vfree[1], 1, 0])[i] - a[i] for i in range(2)]
        c4 = [kfun(q, [vfree[0], vfree[1], 0, 1])[i] - a[i] for i in range(2)]
        M = mpmath.matrix([[c3[0], c4[0]], [c3[1], c4[1]]])
        x = mpmath.lu_solve(M, mpmath.matrix([-a[0], -a[1]]))
        return [vfree[0], vfree[1], x[0], x[1]]


def test_dependent_velocities_against_a_40_digit_difference_on_the_manifold():
    import ldaspark
    sysm, qs, vs, k = two_constraints()
    kl = sympy.lambdify((qs, vs), k, modules="mpmath")

    def kfun(q, v):
        return [mpmath.mpf(x) for x in kl(q, v)]
    dps = 40
    with mpmath.workdps(dps):
        q0 = [mpmath.mpf(x) for x in ("0.3", "-0.2", "0.4", "0.1")]
        v0 = _consistent_v(kfun, q0, [mpmath.mpf("0.5"), mpmath.mpf("-0.7")], dps)
        fj = ldaspark.flow_jacobian(sysm, "gauss-2", q0, v0, "0.1", dps=dps, coords=["q1", "q2"],
                                    rates=["v1", "v2"])
        B = fj.tangent
        # the tangent basis satisfies the linearised constraint k_q dq + k_v dv = 0 (to 40 digits)
        Kq = sympy.Matrix(k).jacobian(qs)
        Kv = sympy.Matrix(k).jacobian(vs)
        sub = dict(zip(qs + vs, q0 + v0))
        Kq_ = np.array([[mpmath.mpf(sympy.N(Kq[i, j].subs(sub), 50)) for j in range(4)] for i in range(2)], dtype=object)
        Kv_ = np.array([[mpmath.mpf(sympy.N(Kv[i, j].subs(sub), 50)) for j in range(4)] for i in range(2)], dtype=object)
        lin = Kq_.dot(B[:4, :]) + Kv_.dot(B[4:, :])
        assert max(abs(x) for x in lin.reshape(-1)) < mpmath.mpf(10) ** -35
        # each column of J against a central difference of the step along a curve on the
        # manifold: q_i (or v_j) moves by +-d, the dependent v3, v4 solved from k = 0 exactly
        from ldaspark.core.spark import SparkMethod
        sm = SparkMethod(sysm, get_method("gauss-2"), dps=dps, newton="full")
        d = mpmath.mpf(10) ** -13
        S = fj.select
        worst = 0
        for col, (kind, idx) in enumerate([("q", 0), ("q", 1), ("v", 0), ("v", 1)]):
            outs = []
            for sgn in (1, -1):
                q = list(q0)
                vf = [v0[0], v0[1]]
                if kind == "q":
                    q[idx] += sgn * d
                else:
                    vf[idx] += sgn * d
                v = _consistent_v(kfun, q, vf, dps)
                r = sm.step(mpmath.mpf(0), np.array(q, dtype=object), np.array(v, dtype=object), mpmath.mpf("0.1"))
                outs.append(np.concatenate([r.q1, r.v1]))
            fd = (outs[0] - outs[1]) / (2 * d)
            for row, s_ in enumerate(S):
                worst = max(worst, abs(fj.J[row, col] - fd[s_]))
        # truncation d^2 ~ 1e-26, round-off 1e-40 / d = 1e-27; a float64 solve or a dropped
        # coupling of the dependent block is off by >= 1e-17
        assert worst < mpmath.mpf(10) ** -22, worst
        # negative control: the naive basis (dependent velocities left fixed) is far off
        naive = fj.full[S, :][:, [0, 1, 4, 5]]
        assert max(abs(naive[r_, c_] - fj.J[r_, c_]) for r_ in range(4) for c_ in range(4)) > 1e-3
