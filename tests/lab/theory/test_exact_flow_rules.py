"""Rules of ``ldaspark.lab.theory.exact_flow`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import mpmath
import numpy as np
import pytest
import sympy
from ldaspark.core.system import LagrangianSystem
from ldaspark.lab.theory import energy_balance as EB
from ldaspark.lab.theory import exact_flow as EF


# ---------------------------------------------------------------------------------------------
# exact_flow
def _ef(stages=3, dps=25):
    sysm, q0, v0 = EB.energy_system("particle")
    return EF.ExactFlow(sysm, dps=dps, stages=stages), q0, v0


def test_exact_flow_failures_are_reported():
    fl, q0, v0 = _ef()
    with pytest.raises(EF.ExactFlowError, match="did not converge in 1"):
        fl.ivp(0, q0, v0, "0.1", max_iter=1)
    # a saddle matrix (4) singular where L_vv degenerates: L = q1 v1^2 / 2 + v2^2 / 2, k = v2
    q, v = sympy.symbols("q1:3"), sympy.symbols("v1:3")
    deg = LagrangianSystem(q[0] * v[0] ** 2 / 2 + v[1] ** 2 / 2, [v[1]], q, v, name="degenerate")
    fd = EF.ExactFlow(deg, dps=20, stages=1)
    with mpmath.workdps(20):
        with pytest.raises(EF.ExactFlowError, match="saddle matrix"):
            fd.rhs(mpmath.mpf(0), [mpmath.mpf(0), mpmath.mpf(0)], [mpmath.mpf(1), mpmath.mpf(0)])
        a, psi, _, _ = fd.rhs(mpmath.mpf(0), [mpmath.mpf(2), mpmath.mpf(0)], [mpmath.mpf(1), mpmath.mpf(0)],
                              jacobian=False)
        # q1 v1' + v1^2/2 ... d/dt(q1 v1) - v1^2/2 = 0: a1 = -(v1^2 - v1^2/2)/q1 = -1/4; v2' = 0
        assert abs(a[0] + mpmath.mpf(1) / 4) < 1e-18 and abs(a[1]) < 1e-18


def test_exact_bvp_without_sensitivities_and_resolve():
    fl, q0, v0 = _ef()
    with mpmath.workdps(25):
        q1, _, _ = fl.ivp(0, q0, v0, "0.1")
        full = fl.bvp(0, q0, mpmath.mpf("0.1"), q1)
        bare = fl.bvp(0, q0, mpmath.mpf("0.1"), q1, sensitivities=False)
        assert bare.dQ_dq0 is None and bare.f_d_minus is None and "dx_dq" not in bare.extra
        assert full.dQ_dq0 is not None and "dx_dq" in full.extra
        assert abs(bare.L_d - full.L_d) <= 10 * abs(full.L_d) * mpmath.mpf(10) ** -25
        # the consistent v0 is recovered (the flow came from it)
        assert max(abs(x - mpmath.mpf(y)) for x, y in zip(full.v0, v0)) < 1e-20
        # resolve from the solution: the action; from a far predictor with one iteration: refused
        La = fl.resolve(mpmath.mpf(0), np.array([mpmath.mpf(x) for x in q0], dtype=object),
                        mpmath.mpf("0.1"), q1, full.x, full.extra["fac"])
        assert abs(La - full.L_d) <= 10 * abs(full.L_d) * mpmath.mpf(10) ** -25
        with pytest.raises(EF.ExactFlowError, match="did not converge"):
            fl.resolve(mpmath.mpf(0), np.array([mpmath.mpf(x) for x in q0], dtype=object), mpmath.mpf("0.1"), q1,
                       full.x + 1, full.extra["fac"], max_iter=1)


def test_quadrature_and_cumulative_are_exact_on_polynomials():
    fl, _, _ = _ef(stages=3, dps=30)
    with mpmath.workdps(30):
        h = mpmath.mpf(2)
        # g(t) = t^2 on [0, 2] at the nodes t = c_i h: int = 8/3; int_0^{T_i} = T_i^3/3 (degree < s)
        vals = [(c * h) ** 2 for c in fl.c]
        assert abs(fl.quad(vals, h) - mpmath.mpf(8) / 3) < 1e-25
        cum = fl.cumulative(vals, h)
        for c, x in zip(fl.c, cum):
            assert abs(x - (c * h) ** 3 / 3) < 1e-25
        # (17), (19) and the printed (20b) from synthetic data: PsiK = 1 (n = 1), dV/dq0 = dV/dq1 = 1
        r = type("R", (), {})()
        r.PsiK = np.array([[mpmath.mpf(1)] for _ in range(3)], dtype=object)
        r.dV_dq0 = r.dV_dq1 = np.array([[[mpmath.mpf(1)]] for _ in range(3)], dtype=object)
        # (17): int_0^h s ds = h^2/2; (19): -int_0^h (h - s) ds = -h^2/2; printed (20b): -(17)
        assert abs(EF.f_minus_17(fl, r, h)[0] - 2) < 1e-25
        assert abs(EF.f_plus_19(fl, r, h)[0] + 2) < 1e-25
        assert abs(EF.f_minus_20b_printed(fl, r, h)[0] + 2) < 1e-25


def test_exact_flow_newton_refreshes_a_stale_matrix(monkeypatch):
    """Simplified Newton keeps the first LU while the increments shrink by <= 0.3 per step and
    refactors when they do not: on G(x) = x^3 - 1 from x = 3 (J = 27 there, 3 at the root) the
    stale matrix alone contracts by ~8/9 and would need hundreds of steps."""
    fl, _, _ = _ef(stages=1, dps=25)
    jac = []

    def residual(t0, q0, t1, q1, x, h, shooting, jacobian):
        if jacobian:
            jac.append(x[0])
        return (np.array([x[0] ** 3 - 1], dtype=object),
                np.array([[3 * x[0] ** 2]], dtype=object) if jacobian else None, None)
    monkeypatch.setattr(fl, "_residual", residual)
    with mpmath.workdps(25):
        x, it = fl._newton(0, None, None, None, np.array([mpmath.mpf(3)], dtype=object), 1, False, 60)
        assert abs(x[0] - 1) < 1e-22 and it < 30 and len(jac) >= 2
        with pytest.raises(EF.ExactFlowError, match="singular"):
            zero = lambda *a: (np.array([mpmath.mpf(1)], dtype=object), np.array([[mpmath.mpf(0)]], dtype=object), None)
            monkeypatch.setattr(fl, "_residual", zero)
            fl._newton(0, None, None, None, np.array([mpmath.mpf(3)], dtype=object), 1, False, 60)


def test_exact_fd_gradient_is_richardson_exact_on_quartics(monkeypatch):
    """Central differences Richardson-extrapolated over delta, delta/2 are exact for L of degree
    <= 4 in each coordinate; the default delta is 10^-(dps // 4), every coordinate of q0 then q1
    is perturbed alone, by +-delta and +-delta/2."""
    fl, _, _ = _ef(stages=1, dps=40)             # n = 3
    seen = []
    with mpmath.workdps(40):
        coef = [mpmath.mpf(k + 1) / 7 for k in range(6)]

        def L(qa, qb):
            z = list(qa) + list(qb)
            return sum(c * (x ** 4 + 3 * x ** 3 - x) for c, x in zip(coef, z))

        def resolve(t0, qa, t1, qb, x_pred, fac, max_iter=60):
            seen.append((list(qa), list(qb), x_pred))
            return L(qa, qb)
        monkeypatch.setattr(fl, "resolve", resolve)
        r = type("R", (), {})()
        r.x = np.array([mpmath.mpf(0)] * 4, dtype=object)
        r.extra = {"fac": None, "dx_dq": np.array([[mpmath.mpf(j) for j in range(6)]] * 4, dtype=object)}
        q0 = [mpmath.mpf("0.3"), mpmath.mpf("-0.2"), mpmath.mpf("0.7")]
        q1 = [mpmath.mpf("1.1"), mpmath.mpf("0.4"), mpmath.mpf("-0.6")]
        g0, g1 = EF.fd_gradient(fl, r, 0, q0, 1, q1)
        exact = [c * (4 * x ** 3 + 9 * x ** 2 - 1) for c, x in zip(coef, q0 + q1)]
        err = max(abs(a - b) for a, b in zip(list(g0) + list(g1), exact))
        assert err < mpmath.mpf(10) ** -25          # delta^2 alone would leave ~1e-20
        delta = mpmath.mpf(10) ** -10
        assert len(seen) == 4 * 6
        for k in range(6):
            for j, e in enumerate((delta, -delta, delta / 2, -delta / 2)):
                qa, qb, xp = seen[4 * k + j]
                moved = [a - b for a, b in zip(qa + qb, q0 + q1)]
                assert [i for i, m in enumerate(moved) if m != 0] == [k]
                assert abs(moved[k] - e) < mpmath.mpf(10) ** -35
                assert abs(xp[0] - k * e) < mpmath.mpf(10) ** -45        # first-order predictor
