"""The SPARK discrete Lagrangian of Theorem 1 as a function of the endpoints (t0, q0, t1, q1).

Theorem 1 treats the quantities of (21) as implicit functions of (t0, q0, t1, q1): with (21c)
imposed, q1 is data and v0 becomes an unknown. This module owns that boundary-value solve.

Unknowns (packed)   x = [V (s*n) | Lambda = h*Psi (s*m) | v1 (n) | v0 (n)]
Residual rows       G = [(21b) s*n | (21d) n | (21e) (s-1)*m | (21f) m | (21c)/h n]

with p0 = grad_v L(t0, q0, v0); the (21c) row is b.V - (q1 - q0)/h so every block is O(1).
The count is square: s n + s m + 2 n unknowns and equations.

Public API (used by ``ldaspark audit`` too):

* ``discrete_lagrangian(system, tableau, t0, q0, t1, q1, dps=40, v0_guess=None, x_guess=None)``
  -> ``DiscreteResult`` with L_d, p0, p1, v0, v1, V, Q, Psi, f_d_minus, f_d_plus, dV_dq0,
  dV_dq1 ((s, n, n): dV_i/dq0 from one linear solve with the Jacobian, implicit
  differentiation, no finite differences), sigma (singular values of the Jacobian, largest
  first), rank_deficiency, wellposed ('well-posed' | 'gauge-deficient' | 'singular'), ...
* ``base_point(system, tableau, t0, q0, v0, h, dps)`` -> (t1, q1, x_guess): one IVP step from
  consistent data, the natural place to check Theorem 1.
* ``theorem1_residuals(system, tableau, t0, q0, v0, h, dps=40)`` -> dict: dL_d/dq0 and
  dL_d/dq1 by Richardson-extrapolated central differences at dps + 20 digits, compared with
  -p0 - f_d^- and p1 - f_d^+ (Theorem 1), relative residuals and the FD error estimate.
* ``check_symmetry`` and ``classify_wellposedness`` / ``gauge_invariance`` live in
  ``ldaspark.analysis.symmetry`` and ``ldaspark.analysis.wellposedness``, on top of this solve.

Well-posedness. The Jacobian J = dG/dx can be rank deficient. Example: A_tilde with constant
first column equal to b_tilde_1 (Lobatto IIIA-IIIB, Euler I): p0 and Lambda_1 enter (21b) and
(21d) only through p0 - b_tilde_1 K_1^T Lambda_1, so p0 -> p0 + K_1^T d, Lambda_1 -> Lambda_1 +
d / b_tilde_1 is a gauge (m null directions in (Lambda, v0)). Then the BVP is also solvable only
on a submanifold of (q0, q1) (the discrete constraint c = 0 of (14b)): J has left null vectors W
with W^T dG/dq != 0. We gauge-fix by a bordered system

    [[J, W], [N^T, 0]] [dx; mu] = [-G; -(N^T x - N^T x_ref)]

(N: right null vectors at the base point, pinned at the IVP solution, i.e. at consistent v0;
W: left null vectors with their (21c) rows zeroed, so (21c) holds exactly and the proof's
algebra applies). mu measures the distance from solvability (0 on the solvable set).
A deficient direction is one with sigma / sigma_max below 10^(-dps/2); it is a *gauge* if the
null vectors do not move V and v1 (then L_d is gauge-invariant), *singular* otherwise.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import mpmath
import numpy as np
import scipy.linalg

from ..core.backend import Backend, SingularMatrixError
from ..core.errors import InputError, LdasparkError
from ..core.spark import SparkMethod
from ..core.system import LagrangianSystem
from ..core.tableau import SparkTableau
from .memo import cached
from ..models import arguments

WELLPOSED = "well-posed"
GAUGE = "gauge-deficient"
SINGULAR = "singular"
#: the class of a J whose rank the tableau's entries cannot decide (float64, short decimals)
UNDECIDED = "not decided"


class DiscreteSolveError(LdasparkError):
    """The boundary-value solve of (21) for given (t0, q0, t1, q1) failed."""


@dataclass
class DiscreteResult:
    """Quantities of Theorem 1 at one (t0, q0, t1, q1). Vectors are numpy arrays (float or
    mpf objects); f_d_minus, f_d_plus are the column vectors whose transposes Theorem 1 prints."""

    L_d: object
    p0: np.ndarray
    p1: np.ndarray
    v0: np.ndarray
    v1: np.ndarray
    V: np.ndarray             # (s, n)
    Q: np.ndarray             # (s, n)
    Psi: np.ndarray           # (s, m)
    f_d_minus: np.ndarray
    f_d_plus: np.ndarray
    dV_dq0: np.ndarray        # (s, n, n): dV_i / dq0
    dV_dq1: np.ndarray
    sigma: np.ndarray         # singular values of J, largest first
    rank_deficiency: int
    wellposed: str
    mu_norm: float            # solvability defect (0 when G(x) = 0 is solvable exactly)
    residual: float           # |G|_inf at the solution (incl. the absorbed part W mu)
    iterations: int
    x: np.ndarray
    dps: int | None
    extra: dict = field(default_factory=dict)


class DiscreteBVP:
    """Assembly of the boundary-value system (21b-f) in the unknowns x = [V|Lambda|v1|v0]."""

    def __init__(self, system: LagrangianSystem, tableau: SparkTableau, dps: int | None = 40):
        if getattr(system, "N", None) is not None:   # the BVP stages below carry no h N term
            raise DiscreteSolveError("Theorem 1 is stated for ideal constraints; this system has a nonideal term (3.3)")
        self.system = system
        self.tableau = tableau
        self.method = SparkMethod(system, tableau, dps=dps)
        self.bk = self.method.backend
        self.tab = self.method.tab
        self.dps = dps
        s, n, m = tableau.s, system.n, system.m
        self.s, self.n, self.m = s, n, m
        self.size = s * n + s * m + 2 * n
        self.c_lam, self.c_v1, self.c_v0 = s * n, s * n + s * m, s * n + s * m + n
        self.r_d, self.r_e = s * n, s * n + n
        self.r_f, self.r_c = s * n + n + (s - 1) * m, s * n + n + s * m

    # --- packing -----------------------------------------------------------------------
    def unpack(self, x):
        s, n, m = self.s, self.n, self.m
        return (x[:self.c_lam].reshape(s, n), x[self.c_lam:self.c_v1].reshape(s, m),
                x[self.c_v1:self.c_v0], x[self.c_v0:])

    def pack(self, V, Lam, v1, v0):
        return np.concatenate([np.asarray(V).reshape(-1), np.asarray(Lam).reshape(-1),
                               np.asarray(v1), np.asarray(v0)])

    # --- residual ----------------------------------------------------------------------
    def evaluate(self, t0, q0, t1, q1, x, jacobian=True):
        """G(x; q0, q1) and, if asked, J = dG/dx, dG/dq0, dG/dq1 (each N x n)."""
        sysm, tab, bk = self.system, self.tab, self.bk
        s, n, m = self.s, self.n, self.m
        h = t1 - t0
        V, Lam, v1, v0 = self.unpack(x)
        T = [t0 + tab.c[i] * h for i in range(s)]
        Q = q0 + tab.A.dot(V) * h
        q1i = q0 + tab.b.dot(V) * h           # = q1 once (21c) holds
        st = [sysm.stage(bk, T[i], Q[i], V[i], Lam[i], jacobian) for i in range(s)]
        fin = sysm.stage(bk, t1, q1i, v1, bk.zeros(m), jacobian)
        st0 = sysm.stage(bk, t0, q0, v0, bk.zeros(m), jacobian)
        p0 = st0.L_v
        F = np.array([e.L_q for e in st])
        Rl = np.array([e.R_lam for e in st])
        Kst = np.array([e.k for e in st])
        G = bk.zeros(self.size)
        G[:self.r_d] = (np.array([e.L_v for e in st]) - p0 - tab.A_hat.dot(F) * h
                        - tab.A_tilde.dot(Rl)).reshape(-1)
        G[self.r_d:self.r_e] = fin.L_v - p0 - tab.b_hat.dot(F) * h - tab.b_tilde.dot(Rl)
        if s > 1:
            G[self.r_e:self.r_f] = tab.omega.dot(Kst).reshape(-1)
        G[self.r_f:self.r_c] = fin.k
        G[self.r_c:] = tab.b.dot(V) - (q1 - q0) / h
        if not jacobian:
            return G, None, None, None
        N = self.size
        J = bk.zeros((N, N))
        J[:self.r_c, :self.c_v0] = self.method._jacobian(h, st, fin)
        for i in range(s):
            J[i * n:(i + 1) * n, self.c_v0:] = -st0.L_vv
        J[self.r_d:self.r_e, self.c_v0:] = -st0.L_vv
        for j in range(s):
            for a in range(n):
                J[self.r_c + a, j * n + a] = tab.b[j]
        # dG/dq0: Q_i, q1i and q0 all move with q0 (x fixed)
        Lqq = np.array([e.L_qq for e in st]); Rq = np.array([e.R_q for e in st])
        dq0 = bk.zeros((N, n))
        for i in range(s):
            dq0[i * n:(i + 1) * n] = (st[i].L_vq - st0.L_vq - np.einsum("j,jab->ab", tab.A_hat[i], Lqq) * h
                                      - np.einsum("j,jab->ab", tab.A_tilde[i], Rq))
        dq0[self.r_d:self.r_e] = (fin.L_vq - st0.L_vq - np.einsum("j,jab->ab", tab.b_hat, Lqq) * h
                                  - np.einsum("j,jab->ab", tab.b_tilde, Rq))
        if s > 1:
            kq = np.array([e.k_q for e in st])
            dq0[self.r_e:self.r_f] = np.einsum("lj,jab->lab", tab.omega, kq).reshape((s - 1) * m, n)
        dq0[self.r_f:self.r_c] = fin.k_q
        dq1 = bk.zeros((N, n))
        for a in range(n):
            dq0[self.r_c + a, a] = 1 / h
            dq1[self.r_c + a, a] = -1 / h
        return G, J, dq0, dq1

    def lagrangian_and_forces(self, t0, q0, t1, q1, x, dV_dq0, dV_dq1):
        """L_d, p0, p1, f_d^-, f_d^+ of Theorem 1 at a solution x (Lambda = h Psi)."""
        sysm, tab, bk = self.system, self.tab, self.bk
        s, n = self.s, self.n
        h = t1 - t0
        V, Lam, v1, v0 = self.unpack(x)
        T = [t0 + tab.c[i] * h for i in range(s)]
        Q = q0 + tab.A.dot(V) * h
        Lfn = sysm._fn("L", [sysm.L], bk)
        Kfn = sysm._fn("K", [sysm.k_v], bk)
        L_d = h * sum(tab.b[i] * Lfn(T[i], *Q[i], *V[i])[0] for i in range(s))
        K = [np.array(Kfn(T[j], *Q[j], *V[j])[0], dtype=object if bk.is_mp else float) for j in range(s)]
        LK = [Lam[j].dot(K[j]) for j in range(s)]          # h Psi_j^T K_j, row n-vectors
        fm = bk.zeros(n)
        fp = bk.zeros(n)
        for i in range(s):
            wm = sum(LK[j] * tab.A_tilde[i, j] for j in range(s))
            wp = sum(LK[j] * (tab.b_tilde[j] - tab.A_tilde[i, j]) for j in range(s))
            fm = fm + wm.dot(dV_dq0[i]) * (h * tab.b[i])
            fp = fp - wp.dot(dV_dq1[i]) * (h * tab.b[i])
        p0 = sysm.momentum(bk, t0, q0, v0)
        p1 = sysm.momentum(bk, t1, q1, v1)
        return L_d, p0, p1, fm, fp, Q

    def L_d_only(self, t0, q0, t1, q1, x):
        sysm, tab, bk = self.system, self.tab, self.bk
        h = t1 - t0
        V = x[:self.c_lam].reshape(self.s, self.n)
        Q = q0 + tab.A.dot(V) * h
        Lfn = sysm._fn("L", [sysm.L], bk)
        return h * sum(tab.b[i] * Lfn(t0 + tab.c[i] * h, *Q[i], *V[i])[0] for i in range(self.s))


# --- linear algebra helpers (float64 and mpf) ------------------------------------------------
def _sqrt(x):
    """sqrt of a unit round-off: a float, or an mpf below float64's range (``Backend.eps``)."""
    return mpmath.sqrt(x) if isinstance(x, mpmath.mpf) else math.sqrt(x)


def _svd(bk, J):
    """(U, sigma, Vt) full SVD, sigma descending."""
    if bk.is_mp:
        U, S, Vh = mpmath.svd_r(mpmath.matrix(J.tolist()))
        U = np.array(U.tolist(), dtype=object)
        Vh = np.array(Vh.tolist(), dtype=object)
        S = np.array([S[i] for i in range(S.rows)], dtype=object)
        order = sorted(range(len(S)), key=lambda i: -S[i])
        return U[:, order], S[order], Vh[order, :]
    U, S, Vh = np.linalg.svd(J)
    return U, S, Vh


RANK_BY_SCHUR = True     # False: the full-precision SVD of all of J (benchmarks/rank_decisions.py compares the two)


#: in ``theorem1_residuals``' retry after a failed solve, a singular value of the BVP Jacobian
#: below this factor times the tableau entries' relative uncertainty (``entries_floor``) is zero to
#: the precision of the entries: rounding an exactly gauge-deficient method's coefficients to
#: float64 moves its zero singular value to 5e-25 sigma_max (gauss-6 written in float64,
#: mp-particles, h = 1/10; entries' floor 1.3e-12 with the ulps of their computation; next value
#: 6.1e-5), where the finite-difference solves without the gauge border crept along it and stopped
#: at 60 iterations (the audit's Theorem 1 check "not decided"); 1e3: three orders above the floor.
#: Not the rule for every solve: a genuine small value can lie below it (gauss-6, skate: 8.5e-14)
ENTRY_RANK_FACTOR = 1e3

#: entries known only to their digits move an exact zero singular value off zero, by the same amount
#: at every dps (float64 gauss-2 on mp-particles: 4.8e-22 sigma_max, classified "well-posed" where
#: the exact method is "singular"). A genuine small sigma is told from such a one as the audit's
#: allowances are (``lab.theory.audit_checks.entry_effect``): J's sigma for the tableau moved by
#: ENTRY_PROBE in the shape of the entries' radii (far above the working precision's noise, far
#: below 1: linear), ENTRY_PROBES directions; a sigma within ENTRY_SAFETY sqrt(n) x that response,
#: rescaled to the largest radius, can be zero for a tableau the entries stand for
ENTRY_PROBE = 1e-10
ENTRY_PROBES = 2
ENTRY_SAFETY = 10.0
#: only sigma below this multiple of the entries' relative uncertainty are probed (a response above
#: 1e7 per unit change of the entries, beyond ENTRY_SAFETY sqrt(n), is not met: 4.5e3 on mp-particles)
ENTRY_GATE = 1e7
_PROBED = ("c", "A", "A_hat", "A_tilde", "b", "b_hat", "b_tilde")


def entries_floor(tableau) -> float:
    """The largest radius of the tableau's entries (``SparkTableau.ball_entries``: decimals to the
    digits given, float64 to half an ulp) over the largest entry: 0.0 for exact entries and
    built-ins computed to any precision."""
    if getattr(tableau, "exact", None) is None or tableau.known_exactly:
        return 0.0
    balls = list(_flat_balls(_entry_balls(tableau)))
    mag = max(abs(float(x.mid())) for x in balls)
    return max(float(x.rad()) for x in balls) / mag if mag > 0 else 0.0


def _entry_balls(tableau) -> dict:
    """The balls of the coefficients the rank decisions look at (omega left out), by key."""
    from .order_conditions import ball_digits
    balls = tableau.ball_entries(ball_digits(tableau, 30))
    return {key: balls[key] for key in _PROBED}


def entry_radii_of(tableau) -> dict:
    """The radius of every probed entry's ball (``_entry_balls``) as a float, nested as
    ``SparkTableau.ball_entries`` (vectors flat, matrices as lists of rows), omega left out: the
    one reading of the entries' uncertainty, the audit's too (``audit_checks.entry_radii``)."""
    return {k: [[float(x.rad()) for x in r] if isinstance(r, list) else float(r.rad()) for r in v]
            for k, v in _entry_balls(tableau).items()}


def _flat_balls(radii: dict):
    for v in radii.values():
        for row in v:
            yield from (row if isinstance(row, list) else [row])


def moved_tableau(tableau, dirs: dict, eps, label: str = "moved") -> SparkTableau:
    """``tableau`` with every entry of the keys of ``dirs`` moved by eps * dirs[key] (nested as
    ``SparkTableau.ball_entries``: vectors flat, matrices as lists of rows), built at any digits from
    the entries at 10 more: the audit's perturbed tableaux (``audit_checks.perturbed_tableau``) and
    the rank probe below."""
    def builder(dps):
        ent = tableau.mp_entries(dps + 10)
        out = {}
        with mpmath.workdps(dps + 10):
            for k, v in ent.items():
                if k not in dirs:
                    out[k] = [list(r) if isinstance(r, list) else r for r in v]
                    continue
                flat = [x[0] if isinstance(x, list) and k in ("c", "b", "b_hat", "b_tilde") else x for x in v]
                out[k] = [[y + eps * dd for y, dd in zip(r, dr)] if isinstance(r, list) else r + eps * dr
                          for r, dr in zip(flat, dirs[k])]
        return out
    return SparkTableau(f"{tableau.name} {label}", tableau.s, builder=builder, family="perturbed")


def _moved_tableau(tableau, radii, umax, eps, seed):
    """``tableau`` with every entry moved by eps * (its radius / umax), pseudo-random signs (``seed``)."""
    import random
    rng = random.Random(seed)
    dirs = {k: [[rng.choice((-1, 1)) * float(x.rad()) / umax for x in r] if isinstance(r, list)
                else rng.choice((-1, 1)) * float(r.rad()) / umax for r in v] for k, v in radii.items()}
    return moved_tableau(tableau, dirs, eps)


def entries_undecided(system, tableau, t0, q0, v0, h, d, rel, r):
    """None, or how many of J's smallest genuine singular values (``rel``: sigma / sigma_max at dps
    d and step h at the base point from (t0, q0, v0), largest first; the last r are zero at working
    precision) the uncertainty of the tableau's entries can move to zero (see ENTRY_PROBE), with
    the numbers: ``bound`` (relative to sigma_max; measured on the smallest) and the ``reason``."""
    floor = entries_floor(tableau)
    k = len(rel) - 1 - r                      # the smallest genuine sigma
    if floor <= 0 or k < 0 or rel[k] > ENTRY_GATE * floor:
        return None
    radii = _entry_balls(tableau)
    rads = [float(x.rad()) for x in _flat_balls(radii)]
    umax = max(rads)
    if umax <= 0:
        return None
    resp = mpmath.mpf(0)
    for seed in range(ENTRY_PROBES):
        T = _moved_tableau(tableau, radii, umax, ENTRY_PROBE, seed)
        bk = Backend(d)
        with bk.context():
            try:
                t1, q1, xg = base_point(system, T, t0, q0, v0, bk.scalar(h), d, newton="mixed")
                J = DiscreteBVP(system, T, d).evaluate(bk.scalar(t0), bk.array(q0), t1, q1, xg)[1]
                sig = _rank_info(bk, J, d)[0]
            except LdasparkError:      # the moved tableau's step failed: nothing measured, rank as before
                return None
            resp = max(resp, abs(mpmath.mpf(sig[k]) / sig[0] - rel[k]))
    bound = ENTRY_SAFETY * math.sqrt(len(rads)) * resp / ENTRY_PROBE * umax
    count = 0
    while k - count >= 0 and rel[k - count] <= bound:
        count += 1
    if not count:
        return None
    return {"count": count, "sigma_rel": float(rel[k]), "bound": float(bound),
            "response": float(resp / ENTRY_PROBE), "entries_radius": umax,
            "reason": (f"sigma_min/sigma_max = {float(rel[k]):.1e} is within {float(bound):.1e}, what the entries' "
                       f"uncertainty ({umax:.1e}) can move it (a response of {float(resp / ENTRY_PROBE):.1e} per unit "
                       "change of the entries, measured): zero for some tableau the entries stand for")}


def _rank_info(bk, J, dps, entries=0.0):
    """(sigma, r, U, Vh): singular values (the candidates for zero at working precision, from
    the Schur complement of ``Backend.small_singular_values``; the others from float64),
    the deficiency r decided relative to the precision (and, ``entries`` > 0, to the relative
    uncertainty of the tableau's entries: ``entries_floor``), and float64 singular vectors, which
    are ample for pinning/bordering (any transversal choice works) and for the null support."""
    Jf = np.array([[float(v) for v in row] for row in J]) if bk.is_mp else J
    if not np.all(np.isfinite(Jf)):     # a step far too large for the system: no rank to decide
        raise DiscreteSolveError("the BVP Jacobian J has entries beyond float64 range or non-finite ones "
                                 "(the step h is far too large for this system)")
    U, s64, Vh = np.linalg.svd(Jf)
    if bk.is_mp and s64[-1] <= 1e-9 * s64[0]:
        # candidate deficiency: decide at full precision, on the small block only
        k = int(np.sum(s64 > 1e-9 * s64[0]))
        small = bk.small_singular_values(J, U, Vh, k) if RANK_BY_SCHUR else None
        if small is None:
            sig = bk.singular_values(J)
        else:
            # below the precision floor a value is zero to working precision: reported at the
            # floor (the full SVD reports noise of that size; S, built exactly from exact
            # zeros, can give far less, or 0, which would hide that the floor tracks dps)
            floor = mpmath.mpf(float(s64[0])) * mpmath.mpf(2) ** (-mpmath.mp.prec)
            sig = np.array([mpmath.mpf(float(v)) for v in s64[:k]] + [max(x, floor) for x in small], dtype=object)
    elif bk.is_mp:
        sig = np.array([mpmath.mpf(float(v)) for v in s64], dtype=object)
    else:
        sig = s64
    return sig, _deficiency(sig, dps, entries), U, Vh


@dataclass
class Gauge:
    """Bordering data for a rank-deficient J: pin rows C (r x N), targets c0, border W (N x r)."""

    C: np.ndarray
    c0: np.ndarray
    W: np.ndarray
    W_left: np.ndarray | None = None     # the true left null vectors (solvability directions)
    fac: object = None                   # factorisation of the bordered J it was checked with


def _deficiency(sig, dps, entries=0.0):
    """Number of singular values that are zero to working precision: sigma/sigma_max below
    10^(-dps/2) (mpmath) or 1e-9 (float64), or below ENTRY_RANK_FACTOR times ``entries`` (the
    tableau entries' relative uncertainty). Genuine small values scale like h^k >> these."""
    smax = float(sig[0])
    thr = max(10.0 ** (-dps / 2) if dps is not None else 1e-9, ENTRY_RANK_FACTOR * entries)
    return sum(1 for x in sig if float(x) <= thr * smax)


class _Solver:
    """Bordered Newton for the BVP at one precision."""

    def __init__(self, bvp: DiscreteBVP, max_iter=60):
        self.bvp = bvp
        self.bk = bvp.bk
        self.max_iter = max_iter

    def bordered(self, J, gauge):
        if gauge is None:
            return J
        bk = self.bk
        N, r = J.shape[0], gauge.W.shape[1]
        B = bk.zeros((N + r, N + r))
        B[:N, :N] = J
        B[:N, N:] = gauge.W
        B[N:, :N] = gauge.C
        return B

    def full_residual(self, G, x, mu, gauge):
        if gauge is None:
            return G
        return np.concatenate([G + gauge.W.dot(mu), gauge.C.dot(x) - gauge.c0])

    def newton(self, t0, q0, t1, q1, x, gauge=None, fac=None, tol=None, stencil=False, first=None):
        """Solve G(x) + W mu = 0, C x = c0. With ``fac`` (LU of the bordered matrix at a
        nearby point) runs simplified Newton first, falling back to full Newton.

        ``stencil=True`` (the finite-difference solves of ``_theorem1_once``, started from an
        accurate predictor): a simplified iteration whose increments stall below sqrt(eps)
        is accepted as full Newton's is (the round-off floor of an ill-conditioned J: the
        full Newton step the plain rule would add costs a Jacobian and an LU and only adds
        noise of the same size), and the final residual evaluation is skipped (res None).
        (A contraction-rate stopping test, theta/(1-theta)|d_k| <= tol, was tried and
        rejected: on the singular robot BVP the first simplified step contracts much faster
        than the later ones, the test stopped early and the Theorem 1 residual grew 24x.)

        ``first``: (G, J, factorisation of the bordered J or None) already evaluated at x, used
        by the first full-Newton iteration instead of evaluating and factoring them again."""
        bk, bvp = self.bk, self.bvp
        tol = tol if tol is not None else 100 * bk.eps
        r = 0 if gauge is None else gauge.W.shape[1]
        mu = bk.zeros(r)
        x = x.copy()
        prev = None
        simplified = fac is not None
        it = 0

        def done(x, mu, it):
            if stencil:
                return x, mu, it, None
            G, _, _, _ = bvp.evaluate(t0, q0, t1, q1, x, jacobian=False)
            return x, mu, it, bk.norm_inf(self.full_residual(G, x, mu, gauge))
        for it in range(1, self.max_iter + 1):
            if it == 1 and first is not None and not simplified:
                G, J, fac = first
            else:
                G, J, _, _ = bvp.evaluate(t0, q0, t1, q1, x, jacobian=not simplified)
                fac = None if not simplified else fac
            R = self.full_residual(G, x, mu, gauge)
            if not simplified and fac is None:
                try:
                    fac = bk.factor(self.bordered(J, gauge))
                except SingularMatrixError as exc:
                    raise DiscreteSolveError(f"BVP Jacobian singular: {exc}") from None
            d = bk.solve_factored(fac, -R)
            x = x + d[:bvp.size]
            mu = mu + d[bvp.size:]
            dn = bk.norm_inf(d)
            if not math.isfinite(dn):
                raise DiscreteSolveError("BVP Newton diverged (non-finite increment)")
            tol_abs = tol * (1 + bk.norm_inf(x))
            if dn <= tol_abs:
                return done(x, mu, it)
            if prev is not None and dn > 0.5 * prev:
                if simplified and stencil and dn <= _sqrt(bk.eps) * (1 + bk.norm_inf(x)):
                    return done(x, mu, it)    # stalled at the round-off floor (as full Newton below)
                if simplified:
                    simplified = False        # contraction too slow: switch to full Newton
                elif dn <= _sqrt(bk.eps) * (1 + bk.norm_inf(x)):
                    # increments stopped shrinking at the round-off floor of an ill-conditioned J
                    return done(x, mu, it)
            prev = dn
        raise DiscreteSolveError(f"BVP Newton did not converge in {self.max_iter} iterations "
                                 f"(last increment {dn:.2e})")


def _make_gauge(bvp, J, x_ref, sig, U, Vh, r):
    """Gauge from the SVD at the base point, made canonical and exact: pin the r unknowns that
    carry most of the right null space (QR with column pivoting) at x_ref, and border with the
    r residual rows that carry most of the left null space, (21c) rows excluded so (21c) stays
    exact. Only the spans matter, so coordinate vectors are as good as singular vectors and do
    not change with round-off from one solve to the next."""
    bk = bvp.bk
    N = bvp.size
    Nv = np.asarray(Vh[N - r:, :], dtype=float)
    Wn = np.asarray(U[:, N - r:], dtype=float).copy()
    Wn[bvp.r_c:, :] = 0
    cols = scipy.linalg.qr(Nv, pivoting=True, mode="r")[1][:r]
    rows = scipy.linalg.qr(Wn.T, pivoting=True, mode="r")[1][:r]
    C = bk.zeros((r, N))
    W = bk.zeros((N, r))
    for k in range(r):
        C[k, cols[k]] = 1
        W[rows[k], k] = 1
    g = Gauge(C=C, c0=C.dot(x_ref), W=W, W_left=np.asarray(U[:, N - r:]))
    try:
        g.fac = bk.factor(_Solver(bvp).bordered(J, g))
    except SingularMatrixError:
        raise DiscreteSolveError("gauge-fixing failed: bordered matrix singular") from None
    return g


def _null_support(bvp, Vh, r):  # noqa: D401
    """Max |component| of the right null vectors in the V, Lambda, v1, v0 blocks."""
    N = bvp.size
    Nv = Vh[N - r:, :]
    blocks = {"V": (0, bvp.c_lam), "Lambda": (bvp.c_lam, bvp.c_v1), "v1": (bvp.c_v1, bvp.c_v0),
              "v0": (bvp.c_v0, N)}
    out = {}
    for k, (a, b) in blocks.items():
        out[k] = max((float(abs(v)) for v in Nv[:, a:b].reshape(-1)), default=0.0) if r else 0.0
    return out


def _as_backend(bk, v):
    return bk.array(v) if bk.is_mp else np.array([float(x) for x in np.asarray(v).reshape(-1)]).reshape(np.shape(v))


# --- public API -------------------------------------------------------------------------------
def base_point(system, tableau, t0, q0, v0, h, dps=40, newton="full"):
    """One IVP step of (21) from (t0, q0, v0): returns (t1, q1, x_guess) in the BVP layout
    (the BVP solution at (t0, q0, t1, q1) up to the Newton tolerance). ``newton``: full Newton
    (the reference step of the checks) or ``SparkMethod``'s "mixed"."""
    meth = SparkMethod(system, tableau, dps=dps, newton=newton)
    bk = meth.backend
    with bk.context():
        t0 = bk.scalar(t0)
        h = bk.scalar(h)
        q0 = bk.array(q0)
        v0 = bk.array(v0)

        r = ivp_step(meth, t0, q0, v0, h)
        x = np.concatenate([r.V.reshape(-1), (r.Psi * h).reshape(-1), r.v1, v0])
        return r.t1, r.q1.copy(), x


def perturbed_initial(scene, dps, scale="1/20"):
    """Consistent data near the scene's initial data: q0 + scale * pattern, v0 projected onto
    k = 0 (a generic point, away from symmetric initial data)."""
    bk = Backend(dps)
    with bk.context():
        t0, q0, v0 = scene.initial(dps)
        n = len(q0)
        sc = mpmath.mpf(1) / 20 if scale == "1/20" else mpmath.mpf(scale)
        q0 = [q + sc * (k + 1) / n for k, q in enumerate(q0)]
        v0 = [v + sc * (-1) ** k * (k + 2) / n for k, v in enumerate(v0)]
        v0 = list(scene.system.project_velocity(bk, t0, q0, v0))
    return t0, q0, v0


def ivp_step(meth, t0, q0, v0, h):
    """``meth.step(t0, q0, v0, h)`` (a ``SparkMethod``), memoized within ``memoized()``: the
    base point and the forward step of Phi_{-h} o Phi_h in ``check_symmetry`` are the same step.
    Arguments in the method's number type; the result is shared, not to be modified."""
    return cached("ivp_step", meth.system, meth.tableau, (meth.dps, meth.newton, meth.tol, meth.max_iter),
                 (t0, q0, v0, h), lambda: meth.step(t0, q0, v0, h))


def discrete_lagrangian(system, tableau, t0, q0, t1, q1, dps=40, v0_guess=None, x_guess=None,
                        gauge_ref=None) -> DiscreteResult:
    """The discrete Lagrangian (13) and the quantities of Theorem 1 at (t0, q0, t1, q1).

    Solves (21b-f) with (21c) imposed (q1 is data, v0 unknown) by Newton and returns
    L_d = h sum b_i L(T_i, Q_i, V_i), p0, p1, f_d^- and f_d^+ exactly as printed in Theorem 1,
    and dV/dq0, dV/dq1 by implicit differentiation dx/dq = -J^{-1} dG/dq (bordered when J is
    rank deficient).

    Parameters
    ----------
    system : LagrangianSystem
        The system (1).
    tableau : SparkTableau
        The SPARK method (21).
    t0, t1 : float
        The endpoint times (h = t1 - t0).
    q0, q1 : array_like
        The endpoint positions.
    dps : int, optional
        Working digits (default 40; None: float64).
    v0_guess : array_like, optional
        Seed of Newton for v0.
    x_guess : array_like, optional
        Seed of Newton in the BVP layout (V, Lambda, v1, v0).
    gauge_ref : array_like, optional
        A packed x that pins the gauge of a rank-deficient J (default: the converged solution
        of a first unpinned pass, or ``x_guess``).

    Returns
    -------
    DiscreteResult
        L_d, p0, p1, v0, v1, the stages V, Q, Psi, f_d_minus, f_d_plus, dV_dq0, dV_dq1, the
        singular values of J, ``wellposed`` and the Newton residual.

    Raises
    ------
    NewtonError
        When the BVP does not converge.

    Examples
    --------
    >>> import ldaspark
    >>> sk = ldaspark.get_scene("skate").system
    >>> d = ldaspark.discrete_lagrangian(sk, ldaspark.gauss(2), 0, [0, 0, 0], 0.1, [0.1, 0, 0.1], dps=30)
    >>> d.wellposed, d.p0.shape
    ('well-posed', (3,))
    """
    from ..core import validate
    system, _ = arguments.as_system(system, "discrete_lagrangian: system")
    tableau = arguments.as_tableau(tableau, "discrete_lagrangian: tableau")
    dps = validate.check_dps(dps)      # None: the float64 path of the same code
    validate.point(system, t0, q0, q1, "discrete_lagrangian: ", names=("q0", "q1"))     # q1 checked like v0
    validate.real_number(t1, "discrete_lagrangian: t1")
    if v0_guess is not None:
        validate.real_vector(v0_guess, "discrete_lagrangian: v0_guess")
        if np.ndim(np.asarray(v0_guess, dtype=object)) != 1 or len(v0_guess) != system.n:
            raise InputError(f"discrete_lagrangian: v0_guess must have n = {system.n} entries, got "
                             f"{validate._describe(v0_guess)}")
    for nm, g in (("x_guess", x_guess), ("gauge_ref", gauge_ref)):
        if g is not None:
            validate.real_vector(g, f"discrete_lagrangian: {nm}")
            if np.ndim(np.asarray(g, dtype=object)) != 1:
                raise InputError(f"discrete_lagrangian: {nm} must be a vector, got {validate._describe(g)}")
    bvp = DiscreteBVP(system, tableau, dps)
    for nm, g in (("x_guess", x_guess), ("gauge_ref", gauge_ref)):
        if g is not None and len(g) != bvp.size:
            raise InputError(f"discrete_lagrangian: {nm} must have the BVP's {bvp.size} unknowns, got {len(g)}")
    bk = bvp.bk
    with bk.context():
        t0, t1 = bk.scalar(t0), bk.scalar(t1)
        q0, q1 = bk.array(q0), bk.array(q1)
        h = t1 - t0
        if h == 0:
            raise InputError("discrete_lagrangian: t1 must differ from t0")
        if x_guess is None:
            v0g = bk.array(v0_guess) if v0_guess is not None else (q1 - q0) / h
            _, _, x_guess = base_point(system, tableau, t0, q0, v0g, h, dps)
        x = _as_backend(bk, x_guess)
        gr = None if gauge_ref is None else _as_backend(bk, gauge_ref)
        return cached("discrete_lagrangian", system, tableau, dps, (t0, q0, t1, q1, x, gr),
                     lambda: _solve_and_differentiate(bvp, t0, q0, t1, q1, x, gauge_ref))


def _solve_and_differentiate(bvp, t0, q0, t1, q1, x, gauge_ref=None, gauge=None, entries=0.0):
    """The BVP solved from x and differentiated (``discrete_lagrangian``). entries > 0: singular
    values below ENTRY_RANK_FACTOR times it count as zero (``_rank_info``; the tableau entries'
    relative uncertainty, ``entries_floor``, in ``theorem1_residuals``' retry)."""
    bk = bvp.bk
    sol = _Solver(bvp)
    x_in = x
    # rank at the guess decides whether Newton needs the gauge-fixing border
    G, J, _, _ = bvp.evaluate(t0, q0, t1, q1, x)
    sig, r, U, Vh = _rank_info(bk, J, bvp.dps, entries)
    first_fac = None
    x_ref = x if gauge_ref is None else _as_backend(bk, gauge_ref)
    if r and gauge is None:
        gauge = _make_gauge(bvp, J, x_ref, sig, U, Vh, r)
        first_fac = gauge.fac          # the bordered J at x, factored once for the check
    # Newton's first iteration is at x too: G, J (and the bordered factorisation) are reused
    x, mu, it, res = sol.newton(t0, q0, t1, q1, x, gauge, first=(G, J, first_fac))
    G, J, dq0, dq1 = bvp.evaluate(t0, q0, t1, q1, x)
    if bk.norm_inf(x - x_in) > 1e-8:
        sig, r, U, Vh = _rank_info(bk, J, bvp.dps, entries)
    support = _null_support(bvp, Vh, r)
    if r == 0:
        cls = WELLPOSED
        gauge_used = None
    else:
        cls = GAUGE if support["V"] <= 1e-8 and support["v1"] <= 1e-8 else SINGULAR
        gauge_used = gauge if gauge is not None else _make_gauge(bvp, J, x, sig, U, Vh, r)
    B = sol.bordered(J, gauge_used)
    rb = 0 if gauge_used is None else gauge_used.W.shape[1]
    rhs = bk.zeros((bvp.size + rb, 2 * bvp.n))
    rhs[:bvp.size, :bvp.n] = -dq0
    rhs[:bvp.size, bvp.n:] = -dq1
    try:
        fac = bk.factor(B)
    except SingularMatrixError as exc:
        raise DiscreteSolveError(f"sensitivity system singular ({cls}): {exc}") from None
    dx = bk.solve_factored(fac, rhs)                  # (N+r, 2n)
    if gauge_used is not None and bk.is_mp:
        # exact left null vectors at working precision: B^T [w; 0] = [0; e_k] (J^T w = 0)
        BT = bk.factor(np.ascontiguousarray(B.T))
        Wl = bk.zeros((bvp.size, rb))
        for k in range(rb):
            e = bk.zeros(bvp.size + rb)
            e[bvp.size + k] = 1
            Wl[:, k] = bk.solve_factored(BT, e)[:bvp.size]
        gauge_used = Gauge(C=gauge_used.C, c0=gauge_used.c0, W=gauge_used.W, W_left=Wl)
    s, n = bvp.s, bvp.n
    dV = dx[:bvp.c_lam].reshape(s, n, 2 * n)
    dV_dq0, dV_dq1 = dV[:, :, :n], dV[:, :, n:]
    L_d, p0, p1, fm, fp, Q = bvp.lagrangian_and_forces(t0, q0, t1, q1, x, dV_dq0, dV_dq1)
    V, Lam, v1, v0 = bvp.unpack(x)
    st0 = bvp.system.stage(bk, t0, q0, v0, bk.zeros(bvp.m), True)
    dv0 = dx[bvp.c_v0:bvp.size]                       # (n, 2n)
    dk0_dq = (st0.k_q + st0.k_v.dot(dv0[:, :n]), st0.k_v.dot(dv0[:, n:]))
    h = t1 - t0
    return DiscreteResult(L_d=L_d, p0=p0, p1=p1, v0=v0.copy(), v1=v1.copy(), V=V.copy(), Q=Q,
                          Psi=Lam / h, f_d_minus=fm, f_d_plus=fp, dV_dq0=dV_dq0, dV_dq1=dV_dq1,
                          sigma=sig, rank_deficiency=r, wellposed=cls,
                          mu_norm=bk.norm_inf(mu), residual=res, iterations=it, x=x, dps=bvp.dps,
                          extra={"null_support": support, "gauge": gauge_used, "fac": fac,
                                 "dx_dq": dx, "dG_dq": (dq0, dq1), "J": J,
                                 "dk0_dq": dk0_dq, "k0": st0.k})


def _rel_residual(bk, a, b, scale):
    d = bk.norm_inf(np.asarray(a) - np.asarray(b))
    return d / max(scale, 1e-300)


def theorem1_residuals(system, tableau, t0, q0, v0, h, dps=40, q1_shift=None, q0_shift=None,
                       fd_target=1e-26, max_refine=4):
    """Theorem 1 checked at the endpoints reached by one IVP step from (t0, q0, v0).

    dL_d/dq0 = -p0^T - f_d^-^T and dL_d/dq1 = p1^T - f_d^+^T, with dL_d/dq measured by
    Richardson-extrapolated central differences on the BVP solution at higher precision.

    Parameters
    ----------
    system : LagrangianSystem, Scene or str
        The system (1); a Scene or a scene name also gives the initial data (q0, v0 None).
    tableau : SparkTableau
        The SPARK method (21).
    t0 : float
        Initial time.
    q0, v0 : array_like or None
        The initial point (consistent: k(t0, q0, v0) = 0); None with a scene.
    h : float
        Step size (nonzero).
    dps : int, optional
        Working digits (default 40); the differences run at more.
    q1_shift, q0_shift : array_like, optional
        Small shifts of the endpoints (points off the IVP solution).
    fd_target : float, optional
        When the finite-difference error estimate exceeds it (an ill-conditioned J), delta
        shrinks by 1e-5 and the precision grows by 15 digits, ...
    max_refine : int, optional
        ... up to ``max_refine`` times; the last attempt is returned.

    Returns
    -------
    dict
        ``theorem1-q0`` and ``theorem1-q1`` (relative residuals of the two identities),
        ``fd_error`` (the difference estimate's error), ``wellposed`` ("not decided" with
        ``entries_undecided`` when a singular value of J is within what the uncertainty of the
        tableau's entries can move to zero), ``rank_deficiency``,
        ``L_d``, singular values of the BVP Jacobian and timings.

    See Also
    --------
    discrete_lagrangian : the discrete Lagrangian (13) and the quantities of Theorem 1.

    Examples
    --------
    >>> import ldaspark
    >>> sc = ldaspark.get_scene("skate")
    >>> r = ldaspark.theorem1_residuals(sc.system, ldaspark.gauss(2), sc.t0, sc.q0, sc.v0, 0.1, dps=30)
    >>> bool(r["theorem1-q0"] < 1e-25 and r["theorem1-q1"] < 1e-25), r["wellposed"]
    (True, 'well-posed')
    """
    from ..core import validate
    system, tableau, t0, q0, v0 = arguments.theory_args(system, tableau, t0, q0, v0, h, dps, "theorem1_residuals")
    for nm, sh in (("q1_shift", q1_shift), ("q0_shift", q0_shift)):
        if sh is not None:
            validate.real_vector(sh, f"theorem1_residuals: {nm}")
            if np.ndim(np.asarray(sh, dtype=object)) != 1 or len(sh) != system.n:
                raise InputError(f"theorem1_residuals: {nm} must have n = {system.n} entries")
    validate.real_number(fd_target, "theorem1_residuals: fd_target", positive=True)
    validate.count(max_refine, "theorem1_residuals: max_refine", 0, 10)
    t_start = time.time()
    err = None
    out = None
    # entries known to a few digits (float64, short decimals) can move an exact zero singular value
    # of the BVP off zero (gauss-6 in float64 on mp-particles: 5e-25 sigma_max at every dps), and the
    # finite-difference solves without the gauge border then creep along it; after a failed solve the
    # zeros are decided at the entries' precision (a genuine small value may lie there too: gauss-6
    # on the skate has 8.5e-14, so this is a retry, not the rule)
    entries_rank = False
    attempt = 0
    while attempt <= max_refine:
        try:
            out = _theorem1_once(system, tableau, t0, q0, v0, h, dps, q1_shift, q0_shift,
                                 dps_fd=dps + 20 + 15 * attempt,
                                 delta=mpmath.mpf(10) ** (-(dps // 4) - 5 * attempt), entries_rank=entries_rank)
        except DiscreteSolveError as exc:   # delta too large for a nearly singular J: refine
            err = exc
            if not entries_rank and entries_floor(tableau) > 0:
                entries_rank = True
            else:
                attempt += 1
            continue
        out["fd_refinements"] = attempt
        out["rank_at_entries_precision"] = entries_rank
        if out["fd_error"] <= fd_target:
            break
        attempt += 1
    if out is None:
        raise err
    sig = out.pop("_sigma_rel", None)
    if sig is not None and out["wellposed"] == WELLPOSED and not entries_rank and entries_floor(tableau) > 0:
        # the rank decided at working precision only: a sigma the entries' uncertainty can move to
        # zero (float64 Lobatto IIIA-IIIB-IIID 3 on the particle: 9.6e-24 sigma_max, where the exact
        # method is singular) leaves the class undecided at their digits
        with Backend(out["dps_fd"]).context():
            u = entries_undecided(system, tableau, t0, q0, v0, h, out["dps_fd"], sig, 0)
        if u is not None:
            out["wellposed"], out["entries_undecided"] = UNDECIDED, u
    bad = [k for k, x in out.items() if isinstance(x, (float, mpmath.mpf)) and not mpmath.isfinite(x)]
    if bad:                             # no NaN or infinity is returned as a residual
        from ..core.errors import NonFiniteError
        raise NonFiniteError(f"theorem1_residuals: {', '.join(bad[:4])} not finite at h = {str(h)[:30]} "
                             "(the step is far too large for this system)")
    out["seconds"] = time.time() - t_start
    return out


def theorem1_residual_bound(r) -> float:
    """What a residual of ``theorem1_residuals`` (``r``, its result) can carry when the identities
    of Theorem 1 hold exactly: the error of the Richardson-extrapolated differences (bounded by
    their estimate ``fd_error`` = |R2 - R1|, which bounds the error of the coarser extrapolant R1;
    factor 10 for the estimate itself) plus the round-off of the printed side at ``dps_fd`` digits,
    amplified by the condition number of the BVP Jacobian (dV/dq = -J^-1 dG/dq; 10^3 units for the
    accumulation). The bound of every Theorem 1 check, the ledger's (``ledger.theorem1_threshold``,
    capped at 1e-20) and the verification suite's. Measured there: residuals 0 .. 1.4e-40 against bounds 6.5e-52 .. 8.4e-26 (at most
    0.22 of the bound). A fixed 1e-20 passed a tableau correct to 20 digits only (residuals
    1.9e-23 .. 9.2e-26 at dps_fd 60); this bound does not."""
    smin, smax = float(r["sigma_min_nonzero"]), float(r["sigma_max"])
    if not (smin > 0 and math.isfinite(smax / smin)):
        return 0.0      # no conditioning to derive a bound from: only an exact zero passes
    return 10 * float(r["fd_error"]) + 1e3 * (smax / smin) * 10.0 ** -int(r["dps_fd"])


def _theorem1_once(system, tableau, t0, q0, v0, h, dps, q1_shift, q0_shift, dps_fd, delta, entries_rank=False):
    """Theorem 1 at the endpoints reached by one IVP step from (t0, q0, v0) (optionally with
    q0, q1 shifted by small vectors): dL_d/dq0 = -p0^T - f_d^-^T, dL_d/dq1 = p1^T - f_d^+^T.

    dL_d/dq is measured by central differences on the BVP solution at ``dps_fd`` (>= dps + 20) digits,
    Richardson-extrapolated over delta, delta/2, delta/4 (first try delta = 10^-(dps/4)); the error
    estimate is the difference of the two extrapolants. Residuals are relative to
    max(|p0|, |p1|, |dL_d/dq|). entries_rank: the BVP's zero singular values decided at the
    precision of the tableau's entries (``entries_floor``), not only the working one."""
    t_start = time.time()
    bk_fd = Backend(dps_fd)
    bvp = DiscreteBVP(system, tableau, dps_fd)
    floor = entries_floor(tableau) if entries_rank else 0.0

    def solve(qa, qb, xg):
        if not entries_rank:
            return discrete_lagrangian(system, tableau, t0_, qa, t1, qb, dps=dps_fd, x_guess=xg)
        return _solve_and_differentiate(bvp, t0_, qa, t1, qb, xg, entries=floor)
    with bk_fd.context():
        t1, q1, xg = base_point(system, tableau, t0, q0, v0, h, dps_fd)
        t0_ = bk_fd.scalar(t0)
        q0_ = bk_fd.array(q0)
        if q0_shift is not None:
            q0_ = q0_ + bk_fd.array(q0_shift)
        if q0_shift is not None or q1_shift is not None:
            # first-order predictor from the unshifted solve: off C_d Newton needs a good start
            r0 = solve(bk_fd.array(q0), q1, xg)
            dq = np.concatenate([bk_fd.array(q0_shift) if q0_shift is not None else bk_fd.zeros(system.n),
                                 bk_fd.array(q1_shift) if q1_shift is not None else bk_fd.zeros(system.n)])
            xg = r0.x + r0.extra["dx_dq"][:len(r0.x)].dot(dq)
        if q1_shift is not None:
            q1 = q1 + bk_fd.array(q1_shift)
        res = solve(q0_, q1, xg)
        sol = _Solver(bvp)
        gauge = res.extra["gauge"]
        fac = res.extra["fac"]
        dxdq = res.extra["dx_dq"][:bvp.size]
        n = system.n
        grads = []
        errs = []
        for k in range(2 * n):
            D = _stencil_differences(sol, bvp, t0_, q0_, t1, q1, res.x, dxdq[:, k], k, gauge, fac, delta)
            R1 = (4 * D[1] - D[0]) / 3
            R2 = (4 * D[2] - D[1]) / 3
            grads.append((16 * R2 - R1) / 15)
            errs.append(abs(R2 - R1))
        g = np.array(grads, dtype=object)
        claim0 = -res.p0 - res.f_d_minus
        claim1 = res.p1 - res.f_d_plus
        scale = max(bk_fd.norm_inf(res.p0), bk_fd.norm_inf(res.p1), bk_fd.norm_inf(g))
        r0 = _rel_residual(bk_fd, g[:n], claim0, scale)
        r1 = _rel_residual(bk_fd, g[n:], claim1, scale)
        fd_err = float(max(errs)) / scale
        # what (22) alone would not give: the bare momenta, to show the forces matter
        r0_nof = _rel_residual(bk_fd, g[:n], -res.p0, scale)
        out = {"theorem1-q0": r0, "theorem1-q1": r1, "fd_error": fd_err,
               "without_forces_q0": r0_nof, "L_d": float(res.L_d),
               "f_d_minus_norm": float(bk_fd.norm_inf(res.f_d_minus)),
               "f_d_plus_norm": float(bk_fd.norm_inf(res.f_d_plus)),
               "wellposed": res.wellposed, "rank_deficiency": res.rank_deficiency,
               "sigma_min": float(res.sigma[-1]), "sigma_max": float(res.sigma[0]),
               "sigma_min_nonzero": float(res.sigma[len(res.sigma) - 1 - res.rank_deficiency]),
               "_sigma_rel": [mpmath.mpf(x) / res.sigma[0] for x in res.sigma],
               "mu_norm": res.mu_norm, "bvp_residual": res.residual, "dps": dps, "dps_fd": dps_fd,
               "fd_delta": float(delta), "seconds": time.time() - t_start,
               "null_support": res.extra["null_support"]}
    return out


def _stencil_differences(sol, bvp, t0, q0, t1, q1, x0, dx0, k, gauge, fac, delta):
    """Central differences (L_d(+dl) - L_d(-dl)) / (2 dl) of L_d along endpoint coordinate k
    (q0[k] for k < n, else q1[k - n]) for dl = delta, delta/2, delta/4.

    Each shifted BVP is solved by simplified Newton with the base factorisation ``fac``,
    started from the polynomial through the solutions found so far along this coordinate:
    p(e) = x0 + dx0 e + e^2 r(e), r interpolating (x_j - x0 - dx0 e_j) / e_j^2 (at the first
    point the first-order predictor x0 + dx0 e). The later stencil points start within the
    interpolation error of the earlier ones, so they need one or two iterations."""
    n = bvp.n
    pts = []                                       # (e_j, (x_j - x0 - dx0 e_j) / e_j^2)

    def predict(e):
        if not pts:
            return x0 + dx0 * e
        r = None
        for i, (ei, ci) in enumerate(pts):         # Lagrange interpolation of r at e
            w = mpmath.mpf(1)
            for j, (ej, _) in enumerate(pts):
                if j != i:
                    w = w * (e - ej) / (ei - ej)
            r = ci * w if r is None else r + ci * w
        return x0 + dx0 * e + r * (e * e)

    def Ld_at(e):
        qa, qb = q0.copy(), q1.copy()
        if k < n:
            qa[k] += e
        else:
            qb[k - n] += e
        xs, _, _, _ = sol.newton(t0, qa, t1, qb, predict(e), gauge, fac=fac, stencil=True)
        pts.append((e, (xs - x0 - dx0 * e) / (e * e)))
        return bvp.L_d_only(t0, qa, t1, qb, xs)
    return [(Ld_at(dl) - Ld_at(-dl)) / (2 * dl) for dl in (delta, delta / 2, delta / 4)]
