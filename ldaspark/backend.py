"""One code path for float64 and mpmath numbers.

Vectors and matrices are numpy arrays: dtype float64, or dtype object holding mpf. Only the
few operations that differ (linear solves, conversion, unit round-off) live here; the
integrator is written once against this interface.
"""
from __future__ import annotations

import contextlib

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
        """LU factorisation of J, reusable by ``solve`` (simplified Newton)."""
        if self.is_mp:
            M = mpmath.matrix(J.tolist())
            try:
                LU, p = mpmath.mp.LU_decomp(M)
            except ZeroDivisionError:
                raise SingularMatrixError("Newton matrix is numerically singular") from None
            return ("mp", LU, p)
        if not np.all(np.isfinite(J)):
            raise SingularMatrixError("Newton matrix has non-finite entries")
        lu, piv = scipy.linalg.lu_factor(J, check_finite=False)
        d = np.abs(np.diag(lu))
        if d.min() <= 1e-300 or d.min() <= 64 * np.finfo(float).eps * d.max() * 1e-3:
            raise SingularMatrixError(
                f"Newton matrix is numerically singular (pivot ratio {d.min() / max(d.max(), 1e-300):.1e})")
        return ("np", lu, piv)

    def solve_factored(self, fac, r) -> np.ndarray:
        if fac[0] == "mp":
            _, LU, p = fac
            b = mpmath.matrix(list(r))
            b = mpmath.mp.L_solve(LU, b, p)
            x = mpmath.mp.U_solve(LU, b)
            return np.array([x[i] for i in range(x.rows)], dtype=object)
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
