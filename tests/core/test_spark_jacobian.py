"""The Newton matrix of (21b, d, e, f) (``SparkMethod.residual(..., jacobian=True)``) is the
Jacobian of the residual: compared with central differences of the residual at 40 digits, on a
system with every term the matrix has (L_vq and L_qv != 0, L not quadratic in v, explicit t,
k nonlinear in v), for the float64 assembly (einsum) and the mpmath one (blocks)."""
import mpmath
import numpy as np
import pytest

from ldaspark.core.families import get_method
from ldaspark.core.spark import SparkMethod
from verification.general_fixtures import general_tableau, rheonomic_initial, rheonomic_system

DPS = 40
EPS = mpmath.mpf("1e-12")


def _fd_jacobian(method, t0, q0, p0, h, x):
    """Central differences of the residual at DPS digits: truncation ~ EPS^2 |G'''| ~ 1e-24,
    rounding ~ 10^-DPS / EPS = 1e-28, far below the tolerances below."""
    cols = []
    for j in range(len(x)):
        xp, xm = x.copy(), x.copy()
        xp[j] += EPS
        xm[j] -= EPS
        gp = method.residual(t0, q0, p0, h, xp, jacobian=False)[0]
        gm = method.residual(t0, q0, p0, h, xm, jacobian=False)[0]
        cols.append((gp - gm) / (2 * EPS))
    return np.array(cols, dtype=object).T


@pytest.mark.parametrize("tableau", ["gauss-2", "general"])
def test_newton_matrix_is_the_jacobian_of_21(tableau):
    sysm = rheonomic_system()
    tab = general_tableau() if tableau == "general" else get_method(tableau)
    rng = np.random.default_rng(7)
    with mpmath.workdps(DPS):
        mp = SparkMethod(sysm, tab, dps=DPS)
        t0, q0, v0 = rheonomic_initial(DPS)
        h = mpmath.mpf("0.1")
        q0, p0 = np.array(q0, dtype=object), np.array([mpmath.mpf(0)] * sysm.n, dtype=object)
        # a point near the start, not on the solution (the matrix is exact everywhere)
        s, n, m = mp.s, mp.n, mp.m
        x = np.array([mpmath.mpf(float(r)) for r in rng.uniform(-0.3, 0.3, mp.size)], dtype=object)
        x[:s * n] += np.tile(np.array(v0, dtype=object), s)
        x[s * n + s * m:] += np.array(v0, dtype=object)
        fd = _fd_jacobian(mp, t0, q0, p0, h, x)
        J_mp = mp.residual(t0, q0, p0, h, x)[1]
        scale = max(abs(e) for e in fd.ravel())
        err_mp = max(abs(a - b) for a, b in zip(np.asarray(J_mp, dtype=object).ravel(), fd.ravel())) / scale
    f64 = SparkMethod(sysm, tab)
    J64 = f64.residual(float(t0), np.array(q0, float), np.zeros(sysm.n), 0.1, np.array(x, float))[1]
    err_64 = float(np.max(np.abs(J64 - np.array(fd, float)))) / float(scale)
    # float64: entries from float64 expressions of size <= scale, ~1e3 ulps of slack; mpmath: exact
    # to far below 1e-20 (the differences' own error)
    assert err_64 < 1e-12, err_64
    assert err_mp < 1e-20, err_mp
