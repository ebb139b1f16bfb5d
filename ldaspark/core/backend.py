"""One code path for float64 and mpmath numbers.

Vectors and matrices are numpy arrays: dtype float64, or dtype object holding mpf. Only the
few operations that differ (linear solves, conversion, unit round-off) live here; the
integrator is written once against this interface.
"""
from __future__ import annotations

import contextlib
import math
import warnings

import mpmath
import numpy as np
import scipy.linalg

from .errors import LdasparkError

try:  # arb (via python-flint) for the high-precision LU: 10-40x faster than pure-Python mpmath
    import flint as _flint
except ImportError:  # pragma: no cover - the pure-mpmath path below is complete on its own
    _flint = None

#: use python-flint for mpmath-precision linear solves when it is installed (set False to force
#: the pure-mpmath LU, e.g. to compare the two; ``benchmarks/ledger_speed.py`` does)
USE_FLINT = _flint is not None
GUARD_BITS = 32
#: floats below this may be underflowed or subnormal roundings of an mpf (float64's smallest normal number)
FLOAT_TINY = 2.2250738585072014e-308
#: up to this many digits ``Backend.eps`` (and tolerances of 1e3 eps) are normal float64 numbers
EPS_FLOAT_DPS = 290


def fmt(x, digits=4) -> str:
    """A norm for a message: '1.234e-05' for a float, mpmath's digits for an mpf (which may lie
    outside float64's range and has no format spec)."""
    if isinstance(x, mpmath.mpf):
        return mpmath.nstr(x, digits)
    return f"{float(x):.{digits - 1}e}"


class SingularMatrixError(LdasparkError):
    """A linear system of the Newton iteration is (numerically) singular."""


def _mpf(x) -> mpmath.mpf:
    """x at the working precision: int, float and mpf as they are; a NumPy float (float16, float32,
    longdouble; a 0-d array too) by the binary number it holds, as the float64 engines read it
    (its shortest decimal repr, str(np.float32(0.1)) = "0.1", is another number: the run stepped
    with another h); an exact sympy number evaluated at this precision; anything else (decimal
    strings, Decimal, Fraction) by its text, which keeps its digits."""
    if isinstance(x, np.ndarray) and x.shape == ():
        x = x[()]
    if isinstance(x, (mpmath.mpf, int, float)):
        return mpmath.mpf(x)
    if isinstance(x, np.integer):
        return mpmath.mpf(int(x))
    if isinstance(x, np.floating):
        num, den = x.as_integer_ratio()       # den is a power of 2: the division is exact
        return mpmath.mpf(num) / den
    if hasattr(x, "evalf") and getattr(x, "is_number", False):
        # an exact sympy number (sqrt(2)/2 in q0, a parsed parameter string): its value at this
        # precision (mpmath does not parse the text "sqrt(2)/2")
        return mpmath.mpf(str(x.evalf(mpmath.mp.dps + 10)))
    try:
        text = str(x)
    except ValueError:
        # a Fraction of integers beyond 4300 digits cannot be printed: its value rounded once,
        # as mpmath reads the text "p/q" of a smaller one
        p, q = getattr(x, "numerator", None), getattr(x, "denominator", None)
        if not (isinstance(p, int) and isinstance(q, int) and q):
            raise
        from mpmath.libmp import from_rational, round_nearest
        return mpmath.mpf(from_rational(p, q, mpmath.mp.prec, round_nearest))
    return mpmath.mpf(text)


class Backend:
    """Arithmetic context. ``dps`` None is float64; an int is mpmath at that many digits."""

    def __init__(self, dps: int | None = None):
        if isinstance(dps, np.integer) and not isinstance(dps, np.bool_):
            dps = int(dps)          # numpy's integers are integers (dps=np.int64(30) from an array)
        if dps is not None and (not isinstance(dps, int) or isinstance(dps, bool) or dps < 5):
            raise LdasparkError(f"dps must be an integer >= 5, got {dps!r}")
        self.dps = dps

    @property
    def is_mp(self) -> bool:
        return self.dps is not None

    @property
    def eps(self):
        """Unit round-off of the working precision: float64's, or 10^-dps from mpmath: a float
        where float64 holds it as a normal number (dps <= EPS_FLOAT_DPS: the same value to 16
        digits, and the type the reports and JSON files expect), the mpf beyond (a float
        underflowed to 0 at dps >= 324 and zeroed every tolerance derived from it)."""
        if self.dps is None:
            return 2.0 ** -52
        e = mpmath.mpf(10) ** (-self.dps)
        return float(e) if self.dps <= EPS_FLOAT_DPS else e

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
                flat[i] = _mpf(v)
            return arr
        return np.array(x, dtype=float)

    def scalar(self, x):
        if self.is_mp:
            return _mpf(x)
        return float(x)

    def zeros(self, shape) -> np.ndarray:
        if self.is_mp:
            out = np.empty(shape, dtype=object)
            out.fill(mpmath.mpf(0))
            return out
        return np.zeros(shape)

    def norm_inf(self, x):
        """max |x_i|: a float, or at mpmath precision an mpf where float64 would round it to 0
        or inf (format it with ``fmt``)."""
        if x.size == 0:
            return 0.0
        if self.is_mp:
            flat = x.reshape(-1)
            try:    # rounding to float is monotonic: the same number, 1.7x faster than max over mpf
                r = max(map(abs, map(float, flat)))
            except TypeError:                   # mpc entries (L or k outside its domain)
                return float(max(abs(v) for v in flat))
            if FLOAT_TINY <= r < math.inf or r != r:
                return r
            # below (or above) float64's range the float rounding loses the number (an increment
            # of 1e-350 at 400 digits is 0.0 in float): the mpf itself, so that tolerances of
            # order eps = 10^-dps still compare right
            big = max(abs(mpmath.mpf(v)) for v in flat)
            return big if big else 0.0
        return float(np.max(np.abs(x)))

    def isfinite(self, x) -> bool:
        if self.is_mp:
            return all(mpmath.isfinite(v) for v in np.asarray(x).reshape(-1))
        return bool(np.isfinite(x).all())

    # --- linear algebra --------------------------------------------------------------------
    def factor(self, J):
        """LU factorisation of J with partial pivoting, reusable by ``solve_factored``
        (simplified Newton). The mpmath branch works on plain lists of mpf: mpmath.matrix
        indexing costs more than the arithmetic at these sizes."""
        if self.is_mp:
            if USE_FLINT:
                fac = _flint_factor(J)
                if fac is not None:
                    return fac
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

    def factor_float64(self, J):
        """LU of a float64 approximation of J, for Newton at mpmath precision with the
        residual at full precision (mixed-precision iterative refinement): the iterates converge
        to the same fixed point, linearly with rate ~ eps_64 cond(J), i.e. as fast as full
        Newton in 3-4 iterations at 30-60 digits, and the LU costs microseconds instead of the
        arb inverse plus an object-array assembly."""
        J = np.asarray(J, dtype=float)
        return ("f64",) + Backend(None).factor(J)[1:]

    def solve_factored(self, fac, r) -> np.ndarray:
        """Solve with a factorisation from ``factor``; ``r`` a vector or an (N, k) matrix."""
        if fac[0] == "f64":
            if not self.is_mp:
                return scipy.linalg.lu_solve(fac[1:], np.asarray(r, dtype=float), check_finite=False)
            with self.context():
                # the residual scaled to 1 before it is rounded to float64 (and the solution scaled
                # back): a residual below float64's range (1e-330 at 400 digits) would round to 0
                # and stall the refinement there
                r = np.asarray(r)
                sc = max((abs(mpmath.mpf(v)) for v in r.reshape(-1)), default=mpmath.mpf(0))
                if not sc:
                    sc = mpmath.mpf(1)
                rs = np.array([float(mpmath.mpf(v) / sc) for v in r.reshape(-1)]).reshape(r.shape)
                x = scipy.linalg.lu_solve(fac[1:], rs, check_finite=False)
                return np.array([mpmath.mpf(float(v)) * sc for v in x.reshape(-1)], dtype=object).reshape(x.shape)
        if fac[0] == "flint":
            return _flint_solve(fac, r)
        if fac[0] == "mp":
            r = np.asarray(r)
            if r.ndim == 2:
                return np.array([_mp_lu_solve(fac[1], fac[2], r[:, k]) for k in range(r.shape[1])]).T
            return _mp_lu_solve(fac[1], fac[2], r)
        return scipy.linalg.lu_solve(fac[1:], r, check_finite=False)

    def solve(self, J, r) -> np.ndarray:
        return self.solve_factored(self.factor(J), r)

    def singular_values(self, J) -> np.ndarray:
        """Singular values, largest first (float64 or mpf)."""
        if self.is_mp:
            if USE_FLINT:
                sv = _flint_singular_values(J)
                if sv is not None:
                    return sv
            S = mpmath.svd_r(mpmath.matrix(J.tolist()), compute_uv=False)
            return np.array(sorted((S[i] for i in range(S.rows)), reverse=True), dtype=object)
        return scipy.linalg.svdvals(J)

    def small_singular_values(self, J, U, Vh, k):
        """The min(m, N) - k smallest singular values of the m x N matrix J at this precision,
        descending, given float64 singular vectors U, Vh of J whose k largest singular values
        are well separated (sigma_k > 1e-9 sigma_1). None when it cannot tell (no flint,
        A singular): the caller then takes ``singular_values``.

        With P = U^T and Q = V (exact binary numbers, orthogonal to 1e-16), J' = P J Q =
        [[A, B], [C, D]] has A (k x k) holding the large values and B, C of size ~1e-16 |J|;
        rank J = k + rank S for the Schur complement S = D - C A^-1 B, and the singular values
        of S are J's small ones to a relative ~1e-16 (P, Q are orthogonal to that accuracy; the
        coupling through B, C is of second order, ~1e-32 |J|^2 / sigma_k). A structurally zero
        value comes out at the precision floor (~2^-p |J|), as from a full SVD. Only the small
        (N - k) x (N - k) problem is diagonalised: 9x cheaper than ``singular_values`` on the
        Theorem 1 BVP matrices of the claims ledger (the ledger's CPU 110 -> 85 s, the same
        records: benchmarks/ledger_compare.py)."""
        if not (self.is_mp and USE_FLINT) or k < 1:
            return None
        prec = mpmath.mp.prec
        J = np.asarray(J)
        m, N = J.shape
        if min(m, N) <= k:
            return np.array([], dtype=object)
        with _flint.ctx.workprec(prec + GUARD_BITS):
            Jp = _arb_mat(np.asarray(U).T) * _arb_mat(J) * _arb_mat(np.asarray(Vh).T)
            Jp = Jp.mid()
            blk = lambda r0, r1, c0, c1: _flint.arb_mat([[Jp[i, j] for j in range(c0, c1)] for i in range(r0, r1)])
            A, B, C, D = blk(0, k, 0, k), blk(0, k, k, N), blk(k, m, 0, k), blk(k, m, k, N)
            try:
                X = A.solve(B, algorithm="approx")
            except (ZeroDivisionError, ValueError):
                return None
            S = (D - C * X).mid()
        Sm = mpmath.matrix([[_from_arb(S[i, j]) for j in range(N - k)] for i in range(m - k)])
        sv = mpmath.svd_r(Sm, compute_uv=False)
        return np.array(sorted((sv[i] for i in range(sv.rows)), reverse=True), dtype=object)

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
            # the ratio to the largest entry, as float64's message gives it: "pivot 1.0" alone read as
            # a contradiction (h = 1e150 at 30 digits: the largest entry 1.5e299)
            raise SingularMatrixError(f"Newton matrix is numerically singular (pivot ratio "
                                      f"{mpmath.nstr(abs(a[p][k]) / scale, 2)} at column {k}: pivot "
                                      f"{mpmath.nstr(abs(a[p][k]), 3)}, largest entry {mpmath.nstr(scale, 3)})")
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


# --- python-flint (arb) path --------------------------------------------------------------------
def _to_arb(v):
    """Exact conversion mpf -> arb (midpoint man * 2^exp, radius 0)."""
    if not isinstance(v, mpmath.mpf):
        v = mpmath.mpf(v)
    sign, man, exp, _ = v._mpf_
    if not man and exp:          # inf / nan have zero mantissa and a nonzero exponent code
        raise SingularMatrixError("Newton matrix has non-finite entries")
    man = int(man)               # an mpz when mpmath runs on gmpy2: python-flint takes ints
    return _flint.arb((-man if sign else man, int(exp)))


def _arb_mat(M):
    """The matrix M (mpf or float entries) as an exact arb matrix."""
    return _flint.arb_mat([[_to_arb(v) for v in row] for row in np.asarray(M).tolist()])


def _from_arb(a):
    """Midpoint of an arb ball as an mpf (rounded to the current mpmath precision)."""
    m, e = a.mid().man_exp()
    return mpmath.mpf((int(m), int(e)))


def _flint_factor(J):
    """Inverse of J at the working precision with arb's rigorous solver; its midpoint is the
    factorisation reused by ``_flint_solve`` (simplified Newton applies it many times). None
    when arb cannot certify J nonsingular at this precision: then the pure-mpmath LU decides
    (it raises SingularMatrixError on a pivot below the precision, as before), so flint never
    accepts a matrix the mpmath path would reject."""
    prec = mpmath.mp.prec
    with _flint.ctx.workprec(prec):
        A = _arb_mat(J)
        try:
            A.inv()                  # the decision: certified nonsingular at the working precision
        except (ZeroDivisionError, ValueError):
            return None
    with _flint.ctx.workprec(prec + GUARD_BITS):
        # the inverse used by the solves, 32 bits more accurate than an LU at the working
        # precision would be: the solutions' round-off is then that of the rounded right-hand side
        inv = A.solve(_flint.arb_mat(A.nrows(), A.nrows(), [int(i == j) for i in range(A.nrows())
                                                            for j in range(A.nrows())]), algorithm="approx")
    return ("flint", inv, prec)


def _flint_solve(fac, r):
    """x = J^-1 r with the stored inverse, the product in arb at GUARD_BITS more bits."""
    _, inv, prec = fac
    r = np.asarray(r)
    cols = r.reshape(r.shape[0], -1)
    with _flint.ctx.workprec(prec + GUARD_BITS):
        R = _arb_mat(cols)
        X = inv * R
    out = np.empty(cols.shape, dtype=object)
    for i in range(cols.shape[0]):
        for k in range(cols.shape[1]):
            out[i, k] = _from_arb(X[i, k])
    return out.reshape(r.shape)


def _flint_singular_values(J):
    """Singular values of J (largest first) as square roots of the eigenvalues of G = J^T J,
    formed exactly from the rounded J and diagonalised by arb's approximate QR at twice the
    working precision plus 64 bits, so that the eigenvalues' absolute error (~2^-2p
    sigma_max^2) resolves sigma down to ~2^-p sigma_max, as the mpmath SVD at precision p does;
    about 10x faster than ``mpmath.svd_r``. Values at the precision floor (structural zeros)
    are noise of that size, as with mpmath.

    The QR has no error bound and can fail silently on clustered eigenvalues, so the result is
    accepted only if every eigenpair has a small residual |G r - lambda r| (then each lambda
    lies within it of an eigenvalue of the symmetric G) and the eigenvalues reproduce trace(G)
    and |G|_F^2 (no eigenvalue lost or duplicated); otherwise None and the caller uses mpmath."""
    prec = mpmath.mp.prec
    N = J.shape[1]
    with _flint.ctx.workprec(2 * prec + 64):
        A = _arb_mat(J)
        G = (A.transpose() * A).mid()
        try:
            E, R = _flint.acb_mat(G).eig(right=True, algorithm="approx")
        except (ValueError, ZeroDivisionError, NotImplementedError):
            return None
        Gc = _flint.acb_mat(G)
        GR = Gc * R
        gmax = max(abs(G[i, j]).mid() for i in range(N) for j in range(N))
        tol = gmax * N * _flint.arb(2) ** (-2 * prec)
        for k in range(N):
            rn = max(abs(R[i, k]).mid() for i in range(N))
            res = max(abs(GR[i, k] - E[k] * R[i, k]).mid() for i in range(N))
            if not (rn > 0 and res <= tol * rn):
                return None
        ev = [e.real.mid() for e in E]
        tr = sum((G[i, i] for i in range(N)), _flint.arb(0))
        fro = sum((G[i, j] ** 2 for i in range(N) for j in range(N)), _flint.arb(0))
        if not (abs(sum(ev, _flint.arb(0)) - tr).mid() <= N * tol
                and abs(sum((x * x for x in ev), _flint.arb(0)) - fro).mid() <= N * tol * gmax * N):
            return None
        sv = [_from_arb(abs(x).sqrt()) for x in ev]
    return np.array(sorted(sv, reverse=True), dtype=object)
