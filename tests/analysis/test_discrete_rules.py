"""Rules of ``ldaspark.analysis.discrete`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import mpmath
import numpy as np
import pytest
import sympy
import ldaspark
from ldaspark.core.backend import Backend
from ldaspark.core.errors import InputError, NonFiniteError
from ldaspark.analysis import discrete as D
import json
from ldaspark.core.families import get_method
from ldaspark.core.numbers import JsonNumber
from ldaspark.core.tableau_file import from_json_dict


class _FakeBVP:
    """G(x) of a scalar / small problem for ``_Solver`` (float64)."""

    def __init__(self, G, J, size):
        self.bk, self.size, self._G, self._J, self.calls = Backend(None), size, G, J, 0

    def evaluate(self, t0, q0, t1, q1, x, jacobian=True):
        self.calls += 1
        return self._G(x), (self._J(x) if jacobian else None), None, None


# ---------------------------------------------------------------------------------------------
# discrete: the pure rules
def test_deficiency_threshold_is_inclusive_and_relative():
    # dps = 20: threshold 10^-10 relative to sigma_max = 2
    sig = [2.0, 2e-9, 2e-10, 1e-10]
    assert D._deficiency(sig, 20) == 2          # 1e-10 <= 1e-10 (2e-10/2 too); 2e-9/2 = 1e-9 is not
    assert D._deficiency(sig, None) == 3        # float64: 1e-9
    assert D._deficiency([1.0, 1e-15], 30) == 1   # exactly at 10^-15: zero
    assert D._deficiency([1.0, 1.1e-15], 30) == 0
    assert D._deficiency([1.0, 0.5, 0.0], 40) == 1


def test_sqrt_and_svd_on_both_number_types():
    assert D._sqrt(4.0) == 2.0 and isinstance(D._sqrt(4.0), float)
    with mpmath.workdps(30):
        r = D._sqrt(mpmath.mpf(10) ** -400)
        assert isinstance(r, mpmath.mpf) and abs(r / mpmath.mpf(10) ** -200 - 1) < 1e-25
    J = np.array([[0.0, 3.0], [1.0, 0.0], [0.0, 0.0]])
    for bk in (Backend(None), Backend(30)):
        with bk.context():
            U, S, Vh = D._svd(bk, bk.array(J) if bk.is_mp else J)
            s = [float(x) for x in S]
            assert s[0] == pytest.approx(3.0, abs=1e-14) and s[1] == pytest.approx(1.0, abs=1e-14)
            # U[:, :2] diag(S) Vh reproduces J
            rec = np.array([[float(sum(U[i][k] * S[k] * Vh[k][j] for k in range(2))) for j in range(2)]
                            for i in range(3)])
            assert np.max(np.abs(rec - J)) < 1e-14


def test_rank_info_paths(monkeypatch):
    with pytest.raises(D.DiscreteSolveError, match="non-finite"):
        D._rank_info(Backend(None), np.array([[1.0, np.inf], [0.0, 1.0]]), None)
    bk = Backend(30)
    with bk.context():
        J = bk.array([[2, 0, 0], [0, 1, 0], [0, 0, 0]])
        sig, r, U, Vh = D._rank_info(bk, J, 30)
        assert r == 1 and float(sig[0]) == pytest.approx(2) and float(sig[-1]) < 1e-20
        from ldaspark.core import backend as BKM
        if BKM.USE_FLINT:
            # the exact zero is reported at the precision floor sigma_max 2^-prec (not 0, not
            # relative to another sigma): the floor tracks dps
            assert sig[-1] == sig[0] * mpmath.mpf(2) ** -mpmath.mp.prec
        monkeypatch.setattr(D, "RANK_BY_SCHUR", False)        # the full-precision SVD instead
        sig2, r2, _, _ = D._rank_info(bk, J, 30)
        assert r2 == 1 and float(sig2[1]) == pytest.approx(1) and float(sig2[-1]) < 1e-20
        # a small but genuine sigma (1e-12 relative, above the 1e-15 floor of 30 digits): full rank
        J3 = bk.array([[1, 0], [0, mpmath.mpf("1e-12")]])
        sig3, r3, _, _ = D._rank_info(bk, J3, 30)
        assert r3 == 0 and abs(float(sig3[-1]) / 1e-12 - 1) < 1e-6
    Jf = np.diag([1.0, 1e-8, 1e-10])
    sigf, rf, _, _ = D._rank_info(Backend(None), Jf, None)
    assert rf == 1 and list(sigf) == sorted(sigf, reverse=True)


def test_null_support_blocks():
    bvp = type("B", (), {"size": 6, "c_lam": 2, "c_v1": 3, "c_v0": 4})()
    Vh = np.array([[1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0],
                   [0.1, -0.7, 0.2, 0, 0, 0], [0, 0, 0, 0.3, -0.5, 0.4]], dtype=float)
    Vh = np.vstack([Vh, [0, 0, -0.6, 0, 0.1, 0]])
    out = D._null_support(bvp, Vh, 2)           # the last two rows
    assert out == {"V": pytest.approx(0.0), "Lambda": pytest.approx(0.6), "v1": pytest.approx(0.3),
                   "v0": pytest.approx(0.5)}
    out1 = D._null_support(bvp, Vh, 1)
    assert out1 == {"V": 0.0, "Lambda": pytest.approx(0.6), "v1": 0.0, "v0": pytest.approx(0.1)}
    assert D._null_support(bvp, Vh, 0) == {"V": 0.0, "Lambda": 0.0, "v1": 0.0, "v0": 0.0}


def test_rel_residual_floor():
    bk = Backend(None)
    assert D._rel_residual(bk, [1.0, 2.0], [1.0, 1.5], 2.0) == 0.25
    assert D._rel_residual(bk, [1.0], [1.0], 0.0) == 0.0
    assert D._rel_residual(bk, [1e-300], [0.0], 0.0) == pytest.approx(1.0)


def test_bvp_newton_converges_stalls_and_refuses():
    A = np.array([[2.0, 1.0], [1.0, 3.0]])
    b = np.array([1.0, 2.0])
    lin = _FakeBVP(lambda x: A.dot(x) - b, lambda x: A, 2)
    x, mu, it, res = D._Solver(lin).newton(0, 0, 1, 0, np.zeros(2))
    assert np.max(np.abs(x - np.linalg.solve(A, b))) < 1e-14 and it <= 2 and res < 1e-14
    assert mu.shape == (0,)
    # simplified Newton with a factorisation of 1.5 A contracts by 1/3 per step: it stays simplified
    fac = lin.bk.factor(1.5 * A)
    x, _, it, res = D._Solver(lin).newton(0, 0, 1, 0, np.zeros(2), fac=fac)
    assert np.max(np.abs(x - np.linalg.solve(A, b))) < 1e-13
    assert 20 <= it <= 40            # |d_k| = (1/3)^k |x*|: down to 100 eps after ~ 30 steps
    # with 5 A it contracts by 0.8 > 0.5: switches to full Newton, which lands in one step
    x, _, it, _ = D._Solver(lin).newton(0, 0, 1, 0, np.zeros(2), fac=lin.bk.factor(5 * A))
    assert np.max(np.abs(x - np.linalg.solve(A, b))) < 1e-14 and it <= 4
    # stencil=True accepts the stall and skips the residual
    x, _, it, res = D._Solver(lin).newton(0, 0, 1, 0, np.zeros(2), fac=lin.bk.factor(1.5 * A), stencil=True)
    assert res is None
    # a triple root: full Newton contracts by 2/3 (> 1/2) and stops at the sqrt(eps) floor
    cube = _FakeBVP(lambda x: x ** 3, lambda x: np.array([[3 * x[0] ** 2]]), 1)
    x, _, it, res = D._Solver(cube).newton(0, 0, 1, 0, np.array([1.0]))
    assert 1e-12 < abs(x[0]) < 1e-7 and it < 60
    with pytest.raises(D.DiscreteSolveError, match="did not converge in 5"):
        D._Solver(cube, max_iter=5).newton(0, 0, 1, 0, np.array([1.0]))
    sing = _FakeBVP(lambda x: x - 1, lambda x: np.zeros((2, 2)), 2)
    with pytest.raises(D.DiscreteSolveError, match="singular"):
        D._Solver(sing).newton(0, 0, 1, 0, np.zeros(2))
    inf = _FakeBVP(lambda x: np.array([np.inf, 0.0]), lambda x: np.eye(2), 2)
    with pytest.raises(D.DiscreteSolveError, match="non-finite"):
        D._Solver(inf).newton(0, 0, 1, 0, np.zeros(2))
    # ``first`` is used for the first full iteration (no evaluation with the Jacobian there)
    lin.calls = 0
    x0 = np.zeros(2)
    D._Solver(lin).newton(0, 0, 1, 0, x0, first=(A.dot(x0) - b, A, None))
    assert lin.calls == 2       # the second iteration and the final residual, not the first


def test_bordered_solve_with_a_gauge():
    """G(x) = [x0 + x1 - 2, x0 + x1 - 2] (rank 1): pin x1 = 0.5 with C, border with W = e_1."""
    J = np.array([[1.0, 1.0], [1.0, 1.0]])
    f = _FakeBVP(lambda x: J.dot(x) - 2, lambda x: J, 2)
    g = D.Gauge(C=np.array([[0.0, 1.0]]), c0=np.array([0.5]), W=np.array([[0.0], [1.0]]))
    sol = D._Solver(f)
    B = sol.bordered(J, g)
    assert B.shape == (3, 3) and B[2, 1] == 1 and B[1, 2] == 1 and B[0, 2] == 0
    assert sol.bordered(J, None) is J
    x, mu, it, res = sol.newton(0, 0, 1, 0, np.zeros(2), gauge=g)
    assert np.max(np.abs(x - [1.5, 0.5])) < 1e-14 and abs(mu[0]) < 1e-14 and res < 1e-14
    fr = sol.full_residual(np.array([1.0, 2.0]), np.array([0.0, 3.0]), np.array([4.0]), g)
    assert fr.tolist() == [1.0, 6.0, 2.5]


def test_theorem1_refinement_loop(monkeypatch):
    """The refine loop of ``theorem1_residuals``: a DiscreteSolveError or an FD error above the
    target refines (15 more digits, delta / 10^5); the first good attempt stops; all failing:
    the last error; a non-finite value is refused."""
    calls = []

    def fake(plan):
        def once(system, tableau, t0, q0, v0, h, dps, q1s, q0s, dps_fd, delta, entries_rank=False):
            a = len(calls)
            calls.append((dps_fd, delta, entries_rank))
            kind = plan[a]
            if kind == "raise":
                raise D.DiscreteSolveError("nearly singular")
            return {"fd_error": kind, "theorem1-q0": 1e-30, "theorem1-q1": 2e-30}
        return once
    args = ("skate", "gauss-1", None, None, None, 0.1)
    monkeypatch.setattr(D, "_theorem1_once", fake(["raise", 1e-20, 1e-30, 1e-40]))
    out = D.theorem1_residuals(*args, dps=40, fd_target=1e-26, max_refine=4)
    assert out["fd_refinements"] == 2 and out["fd_error"] == 1e-30 and len(calls) == 3
    assert [c[0] for c in calls] == [60, 75, 90]
    assert [mpmath.nstr(c[1], 5) for c in calls] == ["1.0e-10", "1.0e-15", "1.0e-20"]
    calls.clear()
    monkeypatch.setattr(D, "_theorem1_once", fake([1e-20, 1e-21, 1e-22]))
    out = D.theorem1_residuals(*args, dps=40, fd_target=1e-26, max_refine=2)
    assert out["fd_refinements"] == 2 and out["fd_error"] == 1e-22 and len(calls) == 3
    calls.clear()
    monkeypatch.setattr(D, "_theorem1_once", fake([1e-26]))
    assert D.theorem1_residuals(*args, dps=40, fd_target=1e-26)["fd_refinements"] == 0   # <= target
    assert not any(c[2] for c in calls)          # exact entries: no retry at their precision
    # entries known to a few digits: a failed solve is retried at the same digits with the zeros
    # decided at the entries' precision, before any refinement
    calls.clear()
    monkeypatch.setattr(D, "entries_floor", lambda tab: 1e-16)
    monkeypatch.setattr(D, "_theorem1_once", fake(["raise", 1e-30]))
    out = D.theorem1_residuals(*args, dps=40, fd_target=1e-26, max_refine=4)
    assert [c[0] for c in calls] == [60, 60] and [c[2] for c in calls] == [False, True]
    assert out["fd_refinements"] == 0 and out["rank_at_entries_precision"] is True
    monkeypatch.setattr(D, "entries_floor", lambda tab: 0.0)
    calls.clear()
    monkeypatch.setattr(D, "_theorem1_once", fake(["raise", "raise"]))
    with pytest.raises(D.DiscreteSolveError, match="nearly singular"):
        D.theorem1_residuals(*args, dps=40, max_refine=1)
    calls.clear()
    monkeypatch.setattr(D, "_theorem1_once", fake([float("nan")]))
    with pytest.raises(NonFiniteError, match="fd_error"):
        D.theorem1_residuals(*args, dps=40, fd_target=1e-26, max_refine=0)
    with pytest.raises(InputError, match="q1_shift must have n"):
        D.theorem1_residuals(*args, dps=40, q1_shift=[0, 0])
    with pytest.raises(InputError, match="q0_shift must have n"):
        D.theorem1_residuals(*args, dps=40, q0_shift=[[0, 0, 0]])


def test_discrete_lagrangian_input_errors():
    sk = ldaspark.get_scene("skate").system
    g = ldaspark.gauss(1)
    with pytest.raises(InputError, match="t1 must differ"):
        D.discrete_lagrangian(sk, g, 0.5, [0, 0, 0], 0.5, [0.1, 0, 0.1], dps=20)
    with pytest.raises(InputError, match="x_guess must be a vector"):
        D.discrete_lagrangian(sk, g, 0, [0, 0, 0], 0.1, [0.1, 0, 0.1], dps=20, x_guess=[[0.0] * 10])
    with pytest.raises(InputError, match="gauge_ref must have the BVP"):
        D.discrete_lagrangian(sk, g, 0, [0, 0, 0], 0.1, [0.1, 0, 0.1], dps=20, gauge_ref=[0.0] * 3)
    with pytest.raises(InputError, match="v0_guess must have n"):
        D.discrete_lagrangian(sk, g, 0, [0, 0, 0], 0.1, [0.1, 0, 0.1], dps=20, v0_guess=[0.0] * 2)
    # q1 is named q1 (it was checked in v0's place and called v0: "v0[0] must be finite")
    with pytest.raises(InputError, match=r"discrete_lagrangian: q1\[0\] must be finite"):
        D.discrete_lagrangian(sk, g, 0, [0, 0, 0], 0.1, [float("nan"), 0, 0.1], dps=20)
    with pytest.raises(InputError, match="discrete_lagrangian: q1 must have n = 3"):
        D.discrete_lagrangian(sk, g, 0, [0, 0, 0], 0.1, [0.1, 0], dps=20)


def test_theorem1_with_a_shifted_q0_solves_at_the_shifted_point():
    """q0_shift moves the left end point: L_d reported equals the BVP's L_d at (q0 + shift, q1)
    solved on its own, and differs from the unshifted L_d by ~ |p0| |shift| (Theorem 1 holds at both)."""
    sc = ldaspark.get_scene("skate")
    shift = [1e-3, 0, 2e-3]
    out = D.theorem1_residuals(sc, "gauss-1", None, None, None, 0.1, dps=20, q0_shift=shift)
    base = D.theorem1_residuals(sc, "gauss-1", None, None, None, 0.1, dps=20)
    assert out["theorem1-q0"] < 1e-25 and out["theorem1-q1"] < 1e-25
    assert base["theorem1-q0"] < 1e-25 and out["without_forces_q0"] > 1e-4
    with mpmath.workdps(40):
        t0, q0, v0 = sc.initial(40)
        t1, q1, xg = D.base_point(sc.system, ldaspark.gauss(1), t0, q0, v0, mpmath.mpf("0.1"), 40)
        qs = [mpmath.mpf(a) + mpmath.mpf(b) for a, b in zip(q0, shift)]
        ref = D.discrete_lagrangian(sc.system, ldaspark.gauss(1), t0, qs, t1, q1, dps=40, x_guess=xg)
        ref0 = D.discrete_lagrangian(sc.system, ldaspark.gauss(1), t0, q0, t1, q1, dps=40, x_guess=xg)
    assert abs(out["L_d"] - float(ref.L_d)) < 1e-12 * max(1.0, abs(out["L_d"]))
    assert abs(out["L_d"] - base["L_d"]) > 1e-6 and abs(base["L_d"] - float(ref0.L_d)) < 1e-12 * max(1.0, abs(base["L_d"]))


def test_discrete_lagrangian_is_the_stage_quadrature_of_L():
    """L_d = h sum_i b_i L(T_i, Q_i, V_i) (13), recomputed from the returned stages with sympy,
    and Q_i = q0 + h sum_j a_ij V_j."""
    sc = ldaspark.get_scene("skate")
    sysm, g = sc.system, ldaspark.gauss(2)
    with mpmath.workdps(30):
        h = mpmath.mpf("0.1")
        q0, q1 = [mpmath.mpf(0)] * 3, [mpmath.mpf("0.1"), mpmath.mpf("0.02"), mpmath.mpf("0.1")]
        r = D.discrete_lagrangian(sysm, g, 0, q0, h, q1, dps=30)
        tab = g.arrays(30)
        Lf = sympy.lambdify([sysm.t] + list(sysm.q) + list(sysm.v), sysm.L, "mpmath")
        ref = h * sum(tab.b[i] * Lf(tab.c[i] * h, *r.Q[i], *r.V[i]) for i in range(2))
        assert abs(r.L_d - ref) < mpmath.mpf(10) ** -25 * max(1, abs(ref))
        assert abs(ref) > 1e-4
        for i in range(2):
            Qi = [q0[a] + h * sum(tab.A[i, j] * r.V[j][a] for j in range(2)) for a in range(3)]
            assert max(abs(x - y) for x, y in zip(Qi, r.Q[i])) < mpmath.mpf(10) ** -25


def test_bvp_newton_tolerance_is_100_eps_relative():
    """Scripted increments (simplified Newton with J = 1, so d_k = -G_k): an increment of
    100.5 eps (1 + |x|) is not yet converged (tol = 100 eps), the next one (0) is."""
    eps = 2.0 ** -52
    x3 = 1.4
    script = [-1.0, -0.4, -100.5 * eps * (1 + x3), 0.0, 0.0]

    class Scripted:
        bk, size = Backend(None), 1

        def __init__(self):
            self.k = 0

        def evaluate(self, t0, q0, t1, q1, x, jacobian=True):
            g = script[min(self.k, len(script) - 1)]
            self.k += 1
            return np.array([g]), (np.eye(1) if jacobian else None), None, None
    s = Scripted()
    x, _, it, res = D._Solver(s).newton(0, 0, 1, 0, np.zeros(1), fac=s.bk.factor(np.eye(1)))
    assert it == 4 and x[0] == pytest.approx(x3, abs=1e-12)
    # a tolerance given explicitly is used instead: 101 eps accepts the third increment
    s = Scripted()
    _, _, it, _ = D._Solver(s).newton(0, 0, 1, 0, np.zeros(1), fac=s.bk.factor(np.eye(1)), tol=101 * eps)
    assert it == 3

    # simplified Newton stalling below sqrt(eps) without ``stencil``: not accepted, it switches to
    # full Newton (which lands: the next increment is 0); with ``stencil`` the stall is accepted
    script[:] = [-1e-9, -0.9e-9, 0.0, 0.0]
    s = Scripted()
    _, _, it, res = D._Solver(s).newton(0, 0, 1, 0, np.zeros(1), fac=s.bk.factor(np.eye(1)))
    assert it == 3 and res == 0.0
    s = Scripted()
    _, _, it, res = D._Solver(s).newton(0, 0, 1, 0, np.zeros(1), fac=s.bk.factor(np.eye(1)), stencil=True)
    assert it == 2 and res is None


def _float64_tableau(name, tmp_path):
    """A built-in written as a user's file with its entries rounded to float64 (repr digits)."""
    import json
    d = ldaspark.get_method(name).to_json_dict()
    for k in ("c", "A", "A_hat", "A_tilde", "b", "b_hat", "b_tilde", "omega"):
        if k in d:
            d[k] = _as_floats(d[k])
    p = tmp_path / f"{name}-float64.json"
    p.write_text(json.dumps(d))
    return ldaspark.load_tableau(str(p))


def _as_floats(v):
    if isinstance(v, list):
        return [_as_floats(x) for x in v]
    return float(mpmath.mpf(str(v)))


def test_entries_floor_is_the_entries_uncertainty():
    """0 for exact and built-in entries; for float64 entries at least half an ulp of the largest
    entry relative to it (the balls also carry the ulps of the entries' own computation)."""
    import tempfile
    import pathlib
    assert D.entries_floor(ldaspark.get_method("gauss-6")) == 0.0
    with tempfile.TemporaryDirectory() as d:
        f = D.entries_floor(_float64_tableau("gauss-2", pathlib.Path(d)))
    assert 1.1e-16 <= f <= 1e-12


def test_theorem1_on_a_float64_tableau_decides_the_gauge_at_the_entries_precision(tmp_path):
    """gauss-6 written in float64 on mp-particles (h = 1/10): the exact method's BVP has one zero
    singular value (gauge), which the rounded entries move to 5e-25 sigma_max at every dps; without
    the gauge border the finite-difference solves crept along it and stopped after 60 iterations
    (DiscreteSolveError, the audit's "not decided"). After that failure theorem1_residuals decides
    the zeros at the entries' precision: one zero, Theorem 1 holds to 8.5e-17 (the entries carry
    ~1e-16; tolerance 1e-12, three orders above it, seven below the 1.0 without the forces).
    Control: the exact gauss-6 needs no retry (rank_at_entries_precision False, residual 8e-44)."""
    from ldaspark.models.scenes import get_scene
    sc = get_scene("mp-particles")
    t0, q0, v0 = sc.initial(75)
    tab = _float64_tableau("gauss-6", tmp_path)
    r = D.theorem1_residuals(sc.system, tab, t0, q0, v0, "1/10", dps=30)
    assert r["rank_at_entries_precision"] is True and r["rank_deficiency"] == 1
    assert max(r["theorem1-q0"], r["theorem1-q1"]) <= 1e-12
    exact = D.theorem1_residuals(sc.system, ldaspark.get_method("gauss-6"), t0, q0, v0, "1/10", dps=30)
    assert exact["rank_at_entries_precision"] is False and exact["rank_deficiency"] == 1
    assert max(exact["theorem1-q0"], exact["theorem1-q1"]) <= 1e-40


# --- the rank of Theorem 1's J for a tableau known to its digits ------------------------------
# The rank of Theorem 1's boundary-value Jacobian J for a tableau whose entries are known only to
# their digits (float64, as users publish them): rounding moves an exact zero singular value of J off
# zero by the same amount at every dps, so the working precision alone cannot call it zero.
#
# Gauss-2 on mp-particles (h = 1/10) is singular for the exact method (one zero sigma, at the
# precision floor 10^-dps); written in float64 that sigma sits at 4.8e-22 sigma_max at dps 30 and 50
# (not a floor: it does not move with dps), inside what the entries' uncertainty (6.8e-16) can move it
# (a response of 6.8e-2 per unit change, measured, times 10 sqrt(20): 2.1e-15). Before the fix
# ``classify_wellposedness`` called it "well-posed", and ``check_symmetry`` at dps 50 (threshold
# 10^-25) solved the reversed BVP without the gauge border along that direction: L_d(t1,q1,t0,q0) +
# L_d missed by 1.3e-3 (the exact method: 0), and ``ldaspark audit --dps 50`` failed the float64
# Gauss-2's symmetry (exit 1).

def _float64(name):
    """The built-in as its users publish it in float64: a JSON file, every entry a JSON number (the
    float's shortest repr, read back as the decimal text it is)."""
    d = get_method(name, exact=True).to_json_dict()
    f = lambda x: float(sympy.N(sympy.sympify(x), 30))
    text = json.dumps({k: (v if k == "name" else [[f(x) for x in r] if isinstance(r, list) else f(r) for r in v])
                       for k, v in d.items()})
    return from_json_dict(json.loads(text, parse_float=JsonNumber))


def _scene(name, dps):
    sc = ldaspark.get_scene(name)
    t0, q0, v0 = sc.initial(dps + 45)
    return sc.system, t0, q0, v0


def test_float64_gauss2_rank_is_not_decided_where_the_exact_method_is_singular():
    f64, exact = _float64("gauss-2"), get_method("gauss-2", exact=True)
    system, t0, q0, v0 = _scene("mp-particles", 50)
    r = ldaspark.classify_wellposedness(system, f64, t0, q0, v0, 0.1, dps=(30, 50))
    # before the fix: "well-posed" (rank deficiency 0)
    assert r["class"] == "not decided", r["class"]
    u = r["entries_undecided"]
    assert u["class_if_zero"] == "singular" and u["count"] == 1
    assert u["sigma_rel"] <= u["bound"]
    # the exact method: singular, decided by the precision floor (no entries' uncertainty)
    re = ldaspark.classify_wellposedness(system, exact, t0, q0, v0, 0.1, dps=(30, 50))
    assert re["class"] == "singular" and "entries_undecided" not in re
    # control: a genuine small sigma above the entries' reach stays decided (skate: 4.4e-5 sigma_max)
    system, t0, q0, v0 = _scene("skate", 50)
    rs = ldaspark.classify_wellposedness(system, f64, t0, q0, v0, 0.1, dps=(30, 50))
    assert rs["class"] == "well-posed" and "entries_undecided" not in rs


def test_float64_gauss2_is_symmetric_at_dps_50_on_mp_particles():
    f64, exact = _float64("gauss-2"), get_method("gauss-2", exact=True)
    system, t0, q0, v0 = _scene("mp-particles", 50)
    r = ldaspark.check_symmetry(system, f64, t0, q0, v0, 0.1, dps=50)
    # before the fix: symmetry-Ld 1.3e-3, "well-posed". The float64 entries are ~1e-16 off (23);
    # the identities respond with O(1) per unit change on this scene (the audit measures 8.8e4 at
    # most, with the f_d parts): 1e-10 is above anything the entries can explain and far below 1.3e-3
    assert r["symmetry-Ld"] < 1e-10 and r["symmetry-Phi"] < 1e-10, r
    assert r["wellposed"] == "singular" and r["rank_at_entries_precision"]
    # the exact method, for comparison: the same class, L_d symmetric to the working precision
    re = ldaspark.check_symmetry(system, exact, t0, q0, v0, 0.1, dps=50)
    assert re["wellposed"] == "singular" and re["symmetry-Ld"] < 1e-40 and not re["rank_at_entries_precision"]


def test_theorem1_residuals_does_not_call_a_float64_rank_the_exact_method_lacks_well_posed():
    """Lobatto IIIA-IIIB-IIID 3 on the particle: singular for the exact method; in float64 the zero
    sigma sits at 9.6e-24 sigma_max, above the working precision's 10^-25 at dps_fd = 50, and the
    solve (which succeeds: no retry at the entries' precision) called J "well-posed"."""
    f64, exact = _float64("lobatto-iiia-iiib-iiid-3"), get_method("lobatto-iiia-iiib-iiid-3", exact=True)
    system, t0, q0, v0 = _scene("particle", 30)
    r = ldaspark.theorem1_residuals(system, f64, t0, q0, v0, 0.1, dps=30)
    assert r["wellposed"] == "not decided", r["wellposed"]       # before the fix: "well-posed"
    assert r["entries_undecided"]["count"] == 1 and r["rank_deficiency"] == 0
    # Theorem 1 itself holds: relative residual 2.1e-32 (the entries' effect on this scene is below
    # the dps-30 tolerance 1e-15 of the audit)
    assert max(r["theorem1-q0"], r["theorem1-q1"]) < 1e-15
    re = ldaspark.theorem1_residuals(system, exact, t0, q0, v0, 0.1, dps=30)
    assert re["wellposed"] == "singular" and "entries_undecided" not in re
    # control: a well-posed J stays so in float64 (Gauss-2 on the skate, sigma_min 4.4e-5 sigma_max)
    system, t0, q0, v0 = _scene("skate", 30)
    rs = ldaspark.theorem1_residuals(system, _float64("gauss-2"), t0, q0, v0, 0.1, dps=30)
    assert rs["wellposed"] == "well-posed" and "entries_undecided" not in rs


def test_a_failed_probe_leaves_the_rank_as_the_working_precision_decides_it(monkeypatch):
    """When the step of a moved tableau fails nothing is measured: the class stays the one the
    working precision gives (no error, no 'not decided' without a measurement)."""
    from ldaspark.analysis import discrete as D
    f64 = _float64("gauss-2")
    system, t0, q0, v0 = _scene("mp-particles", 50)
    real = D.base_point

    def failing(system, tab, *a, **k):
        if tab.name.endswith(" moved"):
            raise D.DiscreteSolveError("probe step failed (test)")
        return real(system, tab, *a, **k)
    monkeypatch.setattr(D, "base_point", failing)
    r = ldaspark.classify_wellposedness(system, f64, t0, q0, v0, 0.1, dps=(30, 50))
    assert r["class"] == "well-posed" and "entries_undecided" not in r
    monkeypatch.setattr(D, "base_point", real)           # control: measured, not decided
    assert ldaspark.classify_wellposedness(system, f64, t0, q0, v0, 0.1, dps=(30, 50))["class"] == "not decided"

