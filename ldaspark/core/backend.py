"""One code path for float64 and mpmath numbers.

Vectors and matrices are numpy arrays: dtype float64, or dtype object holding mpf. Only the
few operations that differ (linear solves, conversion, unit round-off) live here; the
integrator is written once against this interface.
"""
from __future__ import annotations

import contextlib
import warnings

import mpmath
import numpy as np
import scipy.linalg

from .errors import LdasparkError


class SingularMatrixError(LdasparkError):
    """A linear system of the Newton iteration is (numerically) singular."""


class Backend:
    """Arithmetic context. ``dps`` None is float64; an int is mpmath at that many digits."""

    def __init__(self, dps: int | None = None):
        if dps is not None and (not isinstance(dps, int) or dps < 5):
            raise LdasparkError(f"dps must be an integer >= 5, got {dps!r}")
        self.dps = dps

    @property
    def is_mp(self) -> bool:
        return self.dps is not None

    @property
    def eps(self) -> float:
        """Unit round-off of the working precision."""
        return 2.0 ** -52 if self.dps is None else float(mpmath.mpf(10) ** (-self.dps))

    def context(self):
        """Context manager setting the mpmath precision locally (never a global mp.dps)."""
        return mpmath.workdps(self.dps) if self.is_mp else contextlib.nullcontext()

    @property
    def lambdify_module(self) -> str:
        return "mpmath" if self.is_mp else "math"

    def array(self, x) -> np.ndarray:
        """Convert a nested list / array / sympy numbers to the working number type."""
        if self.is_mp:
            arr = np.array(x, dtype=object)
            flat = arr.reshape(-1)
            for i, v in enumerate(flat):
                flat[i] = mpmath.mpf(str(v)) if not isinstance(v, (mpmath.mpf, int, float)) else mpmath.mpf(v)
            return arr
        return np.array(x, dtype=float)

    def scalar(self, x):
        if self.is_mp:
            return mpmath.mpf(x) if isinstance(x, (int, float, mpmath.mpf)) else mpmath.mpf(str(x))
        return float(x)

    def zeros(self, shape) -> np.ndarray:
        if self.is_mp:
            out = np.empty(shape, dtype=object)
            out.fill(mpmath.mpf(0))
            return out
        return np.zeros(shape)

    def norm_inf(self, x) -> float:
        if x.size == 0:
            return 0.0
        if self.is_mp:
            return float(max(abs(v) for v in x.reshape(-1)))
        return float(np.max(np.abs(x)))

    def isfinite(self, x) -> bool:
        if self.is_mp:
            return all(mpmath.isfinite(v) for v in np.asarray(x).reshape(-1))
        return bool(np.all(np.isfinite(x)))

    # --- linear algebra --------------------------------------------------------------------
    def factor(self, J):
        """LU factorisation of J with partial pivoting, reusable by ``solve_factored``
        (simplified Newton). The mpmath branch works on plain lists of mpf: mpmath.matrix
        indexing costs more than the arithmetic at these sizes."""
        if self.is_mp:
            return ("mp",) + _mp_lu(J)
        if not np.all(np.isfinite(J)):
            raise SingularMatrixError("Newton matrix has non-finite entries")
        with warnings.catch_warnings():  # exact singularity is reported below as one error, not a LinAlgWarning
            warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
            lu, piv = scipy.linalg.lu_factor(J, check_finite=False)
        d = np.abs(np.diag(lu))
        if d.min() <= 1e-300 or d.min() <= 64 * np.finfo(float).eps * d.max() * 1e-3:
            raise SingularMatrixError(
                f"Newton matrix is numerically singular (pivot ratio {d.min() / max(d.max(), 1e-300):.1e})")
        return ("np", lu, piv)

    def solve_factored(self, fac, r) -> np.ndarray:
        if fac[0] == "mp":
            return _mp_lu_solve(fac[1], fac[2], r)
        return scipy.linalg.lu_solve(fac[1:], r, check_finite=False)

    def solve(self, J, r) -> np.ndarray:
        return self.solve_factored(self.factor(J), r)

    def singular_values(self, J) -> np.ndarray:
        """Singular values, largest first (float64 or mpf)."""
        if self.is_mp:
            S = mpmath.svd_r(mpmath.matrix(J.tolist()), compute_uv=False)
            return np.array(sorted((S[i] for i in range(S.rows)), reverse=True), dtype=object)
        return scipy.linalg.svdvals(J)

    def to_str(self, x) -> str:
        return mpmath.nstr(x, self.dps, strip_zeros=False) if self.is_mp else repr(float(x))


def _mp_lu(J):
    """Doolittle LU with partial pivoting on lists of mpf; singular when a pivot falls below
    the working precision relative to the largest entry."""
    n = J.shape[0]
    a = [list(row) for row in J.tolist()]
    perm = list(range(n))
    scale = max((abs(x) for row in a for x in row), default=mpmath.mpf(0))
    tiny = scale * mpmath.mpf(2) ** (-mpmath.mp.prec + 4)
    if not scale or not mpmath.isfinite(scale):
        raise SingularMatrixError("Newton matrix is zero or has non-finite entries")
    for k in range(n):
        p = max(range(k, n), key=lambda i: abs(a[i][k]))
        if abs(a[p][k]) <= tiny:
            raise SingularMatrixError(f"Newton matrix is numerically singular (pivot {mpmath.nstr(abs(a[p][k]), 3)} "
                                      f"at column {k})")
        if p != k:
            a[k], a[p] = a[p], a[k]
            perm[k], perm[p] = perm[p], perm[k]
        piv = a[k][k]
        rowk = a[k]
        for i in range(k + 1, n):
            rowi = a[i]
            f = rowi[k] / piv
            if f:
                rowi[k] = f
                for j in range(k + 1, n):
                    rowi[j] -= f * rowk[j]
            else:
                rowi[k] = f
    return a, perm


def _mp_lu_solve(a, perm, r):
    n = len(a)
    y = [r[perm[i]] for i in range(n)]
    for i in range(n):
        row = a[i]
        acc = y[i]
        for j in range(i):
            acc -= row[j] * y[j]
        y[i] = acc
    for i in range(n - 1, -1, -1):
        row = a[i]
        acc = y[i]
        for j in range(i + 1, n):
            acc -= row[j] * y[j]
        y[i] = acc / row[i]
    return np.array(y, dtype=object)
