"""The python-flint (arb) linear algebra of the mpmath backend against the pure-mpmath LU and
SVD it replaces (they are the reference), and its singularity decision."""
import mpmath
import numpy as np
import pytest

from ldaspark.core import backend as B
from ldaspark.core.backend import Backend, SingularMatrixError

pytestmark = pytest.mark.skipif(B._flint is None, reason="python-flint not installed")


def _pair(dps, N=12, seed=3):
    rng = np.random.default_rng(seed)
    bk = Backend(dps)
    with bk.context():
        return bk, bk.array(rng.standard_normal((N, N)).tolist()), bk.array(rng.standard_normal((N, 2)).tolist())


@pytest.fixture
def mp_only(monkeypatch):
    def solve(bk, J, r):
        monkeypatch.setattr(B, "USE_FLINT", False)
        try:
            return bk.solve(J, r)
        finally:
            monkeypatch.setattr(B, "USE_FLINT", True)
    return solve


@pytest.mark.parametrize("dps", [30, 60])
def test_flint_solve_matches_mpmath_lu(dps, mp_only):
    bk, J, R = _pair(dps)
    with bk.context():
        fac = bk.factor(J)
        assert fac[0] == "flint"
        x = bk.solve_factored(fac, R)                 # several right-hand sides at once
        ref = mp_only(bk, J, R)
        assert x.shape == ref.shape == (12, 2)
        assert bk.norm_inf(x - ref) <= 1e3 * bk.eps * bk.norm_inf(ref)
        # control: a different matrix gives a visibly different solution
        J2 = J.copy()
        J2[0, 0] += mpmath.mpf("1e-10")
        assert bk.norm_inf(bk.solve(J2, R) - ref) > 1e-14


def test_flint_singular_matrix_is_rejected_as_before():
    bk, J, _ = _pair(40)
    with bk.context():
        J[:, 3] = J[:, 5] * 2                          # exactly rank deficient
        with pytest.raises(SingularMatrixError):
            bk.factor(J)
        J[0, 3] += mpmath.mpf(10) ** -30               # nonsingular at 40 digits: accepted
        assert bk.factor(J)[0] in ("flint", "mp")


def test_flint_singular_values_match_mpmath():
    bk, J, _ = _pair(50, N=10)
    with bk.context():
        J[:, 9] = J[:, 0] - J[:, 1]                    # one structural zero
        sv = bk.singular_values(J)
        ref = sorted(mpmath.svd_r(mpmath.matrix(J.tolist()), compute_uv=False), reverse=True)
        assert all(abs(a - b) <= 1e-40 * ref[0] for a, b in zip(sv[:-1], ref[:-1]))
        assert sv[-1] < 1e-45 * sv[0] and ref[-1] < 1e-45 * ref[0]    # both at the precision floor
        assert sv[-2] > 1e-3 * sv[0]                   # control: the others are far from it


def _matrix_with_sigmas(sig, dps, seed=3):
    """U diag(sig) V^T at dps digits, U and V exactly orthogonal (mpmath QR of random matrices)."""
    rng = np.random.default_rng(seed)
    N = len(sig)
    with mpmath.workdps(dps + 20):
        Q1 = mpmath.qr(mpmath.matrix(rng.standard_normal((N, N)).tolist()))[0]
        Q2 = mpmath.qr(mpmath.matrix(rng.standard_normal((N, N)).tolist()))[0]
        M = Q1 * mpmath.diag([mpmath.mpf(s) for s in sig]) * Q2.T
    with mpmath.workdps(dps):
        return np.array([[+M[i, j] for j in range(N)] for i in range(N)], dtype=object)


@pytest.mark.parametrize("dps", [30, 60])
def test_small_singular_values_by_schur_complement(dps):
    """Backend.small_singular_values against mpmath's SVD: the genuinely small values to many
    digits, a structural zero at the precision floor, the deficiency decided as before."""
    from ldaspark.analysis.discrete import _deficiency, _rank_info
    bk = B.Backend(dps)
    sig = ["3", "1", "0.5", "0.02", "1e-11", "3e-13", "0"]
    J = _matrix_with_sigmas(sig, dps)
    with bk.context():
        ref = mpmath.svd_r(mpmath.matrix(J.tolist()), compute_uv=False)
        ref = sorted((ref[i] for i in range(ref.rows)), reverse=True)
        U, s64, Vh = np.linalg.svd(np.array([[float(x) for x in r] for r in J]))
        k = int(np.sum(s64 > 1e-9 * s64[0]))
        assert k == 4
        small = bk.small_singular_values(J, U, Vh, k)
        assert len(small) == 3
        for got, want in zip(small[:2], ref[4:6]):          # 1e-11, 3e-13: genuine, to 1e-12
            assert abs(got / want - 1) < 1e-12
        assert small[2] < mpmath.mpf(10) ** (-dps + 5)     # the zero: at the precision floor
        sig_full, r, _, _ = _rank_info(bk, J, dps)
        assert r == 1 == _deficiency(np.array(ref, dtype=object), dps)
        assert float(sig_full[-1]) > 0                     # reported at the floor, never 0
        # control: the decision is taken on J at full precision, not on its float64 image: a
        # perturbation 1.7 x 10^(5 - dps/2) (at 60 digits far below float64 resolution) leaves
        # no zero singular value
        J2 = J.copy()
        J2[0, 0] += mpmath.mpf(10) ** (-dps // 2 + 5) * mpmath.mpf("1.7")
        sig2, r2, _, _ = _rank_info(bk, J2, dps)
        assert r2 == 0 and float(sig2[-1]) > 10.0 ** (-dps / 2)
