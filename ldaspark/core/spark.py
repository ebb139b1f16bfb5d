"""The SPARK step (21a-f) and the integration loop.

One step from consistent (t0, q0, v0) with step h solves, for the unknowns
V_1..V_s (n each), Lambda_1..Lambda_s (m each, Lambda_j = h Psi_j) and v1 (n):

    Q_i  = q0 + h sum_j a_ij V_j                                          (21a)
    0    = P_i - p0 - h sum_j a^_ij F_j + sum_j a~_ij K_j^T Lambda_j      (21b), i = 1..s
    q1   = q0 + h sum_j b_j V_j                                           (21c)
    0    = p1 - p0 - h sum_j b^_j F_j + sum_j b~_j K_j^T Lambda_j         (21d)
    0    = sum_j omega_ij k(T_j, Q_j, V_j),  i = 1..s-1                   (21e)
    0    = k(t1, q1, v1)                                                  (21f)

with P_i = grad_v L(T_i, Q_i, V_i), F_i = grad_q L(T_i, Q_i, V_i), K_i = k_v(T_i, Q_i, V_i),
p_j = grad_v L(t_j, q_j, v_j). Momenta are never inverted explicitly: (21b) and (21d) are solved
for V_i and v1 directly, so general (non-quadratic) L is allowed. The multipliers are scaled
(Lambda = h Psi) so that every block of the Newton matrix is O(1) as h -> 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import mpmath
import numpy as np

from .backend import Backend, SingularMatrixError, fmt
from .blocks import combine as _combine, stage_blocks as _stage_blocks
from .errors import InputError, NewtonError, NonFiniteError, NonFiniteStepError, SingularSaddleError
from .system import LagrangianSystem
from .tableau import SparkTableau


@dataclass
class StepResult:
    t1: object
    q1: np.ndarray
    v1: np.ndarray
    V: np.ndarray          # (s, n) stage velocities
    Q: np.ndarray          # (s, n) stage positions
    Psi: np.ndarray        # (s, m) stage multipliers
    iterations: int
    residual: float        # inf-norm of the residual at the last evaluation
    x: np.ndarray          # packed unknowns (warm start of the next step)
    energy: object = None  # energy (8) at (t1, q1, v1), checked finite and real


@dataclass
class Stats:
    """The counters of a ``SparkMethod``: the work of every step it was asked for, a failed one
    included (nfev, njev, nlu, newton_iterations; ``ldaspark.core.result``), and the steps it
    solved (``steps``)."""

    steps: int = 0
    newton_iterations: int = 0
    nfev: int = 0          # stage-function evaluations (one per stage point)
    njev: int = 0          # Jacobian assemblies
    nlu: int = 0           # LU factorisations
    # the largest |G|_inf over the steps, each G evaluated at the iterate before the step's last
    # increment (the accepted x is not evaluated again: one more residual a step); the accepted
    # stage values are closer to the root than this says (quadratically so for full Newton)
    max_residual: float = 0.0
    iterations_per_step: list = field(default_factory=list)

    def as_dict(self):
        d = dict(self.__dict__)
        d.pop("iterations_per_step")
        d["mean_iterations"] = self.newton_iterations / max(self.steps, 1)
        return d


class SparkMethod:
    """A SPARK method (21) applied to one system at one precision.

    Parameters
    ----------
    system : LagrangianSystem
    tableau : SparkTableau
    dps : None for float64, else mpmath digits.
    tol : Newton increment tolerance (relative); default 10 * unit round-off.
    newton : "full" (Jacobian every iteration; the default of ``SparkMethod``, the reference step
        of the checks), "simplified" (one Jacobian and one LU per step; a new one at the iterate
        only when the contraction rate leaves more increments than max_iter allows,
        ``_budget_short``: high precision) or "auto" (the default of
        ``integrate`` and ``ldaspark.integrate``): simplified Newton, continued as full Newton
        (i) at the first increment that does not contract by 1/4 (discarded) or (ii) when the
        contraction leaves more simplified increments than FULL_COST times the full-Newton ones
        (``_full_newton_cheaper``). Measured by ``benchmarks/newton_variants.py`` (12 named
        scenes, 200 steps of h = 0.05; 6 methods in float64, 2 at 30 digits): "auto" stays
        within 13.3 tol (float64) and 12.5 tol (30 digits) of full Newton's q and v after 200
        steps (the per-step tolerance accumulated; 0-2 tol on most scenes), at a median 1.15x (0.74-1.99x) the
        steps/s of full Newton in float64 and a median 1.31x (0.78-1.75x) at 30 digits; near the
        limit of (4) the det (4) monitor stops it at the same step as full Newton on every
        OpenBLAS kernel (tests/core/test_newton_default.py, tests/core/test_newton_failures.py).
        "simplified" alone diverges there at step 0: the fall-back is what makes "auto" safe.
        "mixed" (mpmath precision; float64: "full"): the Newton matrix at every iterate
        assembled and factorised in float64, the residual at full precision (iterative
        refinement: the same fixed point, reached at a rate ~ 1e-16 cond(J) per iteration, as
        many iterations as full Newton at 30-60 digits, 2-5x cheaper); an increment that does not
        contract by 1/10 switches the rest of the step to the full-precision matrix.
    max_iter : Newton iteration cap before NewtonError.
    energy_jump : optional monitor: stop (NonFiniteError) when one step changes the energy (8) by
        more than energy_jump (1 + |E|); off by default (the energy of a time-dependent or
        non-conservative system may change).
    """

    def __init__(self, system: LagrangianSystem, tableau: SparkTableau, dps: int | None = None,
                 tol: float | None = None, newton: str = "full", max_iter: int = 50, energy_jump=None):
        from .validate import check_dps, check_newton_options, check_system_and_tableau, check_tol_resolvable
        check_dps(dps)          # [DPS_MIN, DPS_MAX] for every entry point
        if newton not in ("auto", "full", "simplified", "mixed"):
            raise InputError(f"newton must be 'auto', 'full', 'simplified' or 'mixed', got {newton!r}")
        check_system_and_tableau(system, tableau)
        check_newton_options(tol, max_iter)
        check_tol_resolvable(tol, dps)
        if energy_jump is not None:
            check_newton_options(energy_jump, 1, what="energy_jump")
        self.system = system
        self.tableau = tableau
        self.backend = Backend(dps)
        self.dps = dps
        self.tol = tol if tol is not None else 10 * self.backend.eps
        self.newton = newton
        self.max_iter = max_iter
        self.energy_jump = None if energy_jump is None else float(energy_jump)
        self.tab = tableau.arrays(dps)
        self.stats = Stats()
        s, n, m = tableau.s, system.n, system.m
        self.s, self.n, self.m = s, n, m
        # unknown layout: V (s*n) | Lambda (s*m) | v1 (n); residual rows: (21b) s*n | (21d) n | (21e) (s-1)*m | (21f) m
        self.size = s * n + s * m + n
        # blocks whose sympy expression vanishes identically (R_v for k affine in v, L_vq for
        # mechanical L, ...) are skipped in the Newton matrix
        # (a nonideal term (3.3) adds N_q, N_v to R_q, R_v at run time: those are never skipped)
        self._structural_zero = {k: bool(getattr(system, k).is_zero_matrix)
                                    and not (k in ("R_q", "R_v") and getattr(system, "N", None) is not None)
                                 for k in ("L_vv", "L_vq", "L_qq", "k_q", "k_v", "R_q", "R_v")}

    # --- packing ---------------------------------------------------------------------------
    def unpack(self, x):
        s, n, m = self.s, self.n, self.m
        V = x[:s * n].reshape(s, n)
        Lam = x[s * n:s * n + s * m].reshape(s, m)
        v1 = x[s * n + s * m:]
        return V, Lam, v1

    def pack(self, V, Lam, v1):
        return np.concatenate([np.asarray(V).reshape(-1), np.asarray(Lam).reshape(-1), np.asarray(v1)])

    # --- residual and Jacobian ---------------------------------------------------------------
    def residual(self, t0, q0, p0, h, x, jacobian=True):
        """Residual of (21b, d, e, f) at packed unknowns x, and its Jacobian if asked."""
        sysm, tab, bk = self.system, self.tab, self.backend
        s, n, m = self.s, self.n, self.m
        V, Lam, v1 = self.unpack(x)
        T = [t0 + tab.c[i] * h for i in range(s)]
        Q = q0 + tab.A.dot(V) * h
        q1 = q0 + tab.b.dot(V) * h
        t1 = t0 + h
        st = [sysm.stage(bk, T[i], Q[i], V[i], Lam[i], jacobian, h=h) for i in range(s)]   # h: nonideal N (3.3)
        fin = sysm.stage(bk, t1, q1, v1, bk.zeros(m), jacobian)
        self.stats.nfev += s + 1
        self._stage_evals = st          # for variants with other constraint rows (comparators.GaussIRK)
        F = np.array([e.L_q for e in st])
        Rl = np.array([e.R_lam for e in st])
        Kst = np.array([e.k for e in st])
        G = bk.zeros(self.size)
        r_b = np.array([e.L_v for e in st]) - p0 - tab.A_hat.dot(F) * h - tab.A_tilde.dot(Rl)
        r_d = fin.L_v - p0 - tab.b_hat.dot(F) * h - tab.b_tilde.dot(Rl)
        r_e = tab.omega.dot(Kst) if s > 1 else bk.zeros((0, m))
        G[:s * n] = r_b.reshape(-1)
        G[s * n:s * n + n] = r_d
        G[s * n + n:s * n + n + (s - 1) * m] = r_e.reshape(-1)
        G[s * n + n + (s - 1) * m:] = fin.k
        if not jacobian:
            return G, None, (T, Q, q1)
        self.stats.njev += 1
        J = self._jacobian(h, st, fin)
        return G, J, (T, Q, q1)

    def _jacobian(self, h, st, fin):
        """Newton matrix of (21b, d, e, f): ``_jacobian_blocks`` in mpmath, ``_jacobian_einsum``
        in float64 (see their docstrings for the measurements behind the choice)."""
        if not self.backend.is_mp:
            return self._jacobian_einsum(h, st, fin)
        return self._jacobian_blocks(h, st, fin)

    def _jacobian_blocks(self, h, st, fin):
        """Newton matrix of (21b, d, e, f) assembled block by block:
        d X_j / d V_k = delta_jk X_v(j) + h a_jk X_q(j) for every stage quantity X, and only
        the nonzero tableau coefficients and the blocks whose expressions are not identically
        zero contribute (einsum over identity blocks on object arrays multiplied by zeros and
        ones: 2-3x the cost at dps 30-50). Works in float64 too (same matrix)."""
        tab, bk = self.tab, self.backend
        s, n, m = self.s, self.n, self.m
        A, Ah, At, b, bh, bt = tab.A, tab.A_hat, tab.A_tilde, tab.b, tab.b_hat, tab.b_tilde
        z = self._structural_zero

        def pick(name, attr):     # the stage blocks, or None where the system's expression is 0
            return [None] * s if z[name] else [getattr(e, attr) for e in st]
        dF = _stage_blocks(pick("L_vq", "L_qv"), pick("L_qq", "L_qq"), A, h)
        dR = _stage_blocks(pick("R_v", "R_v"), pick("R_q", "R_q"), A, h)
        dP = _stage_blocks(pick("L_vv", "L_vv"), pick("L_vq", "L_vq"), A, h)
        KT = [e.k_v.T for e in st]                                       # (n, m) each
        if st[0].R_L is not None:   # nonideal (3.3): d(h R)/dLambda = -K^T + N_psi replaces -K^T
            KT = [-e.R_L for e in st]
        N = self.size
        J = bk.zeros((N, N))
        r_d, r_e, r_f = s * n, s * n + n, s * n + n + (s - 1) * m
        c_lam, c_v1 = s * n, s * n + s * m
        for k in range(s):
            cV, cL = slice(k * n, (k + 1) * n), slice(c_lam + k * m, c_lam + (k + 1) * m)
            for i in range(s):      # (21b) rows
                blk = _combine(dP[i][k], [(Ah[i, j], dF[j][k]) for j in range(s)], h,
                               [(At[i, j], dR[j][k]) for j in range(s)])
                if blk is not None:
                    J[i * n:(i + 1) * n, cV] = blk
                if At[i, k]:
                    J[i * n:(i + 1) * n, cL] = KT[k] * At[i, k]
            # (21d) rows
            blk = _combine(fin.L_vq * (b[k] * h) if b[k] else None, [(bh[j], dF[j][k]) for j in range(s)], h,
                           [(bt[j], dR[j][k]) for j in range(s)])
            if blk is not None:
                J[r_d:r_e, cV] = blk
            if bt[k]:
                J[r_d:r_e, cL] = KT[k] * bt[k]
            # (21e) rows: sum_j omega_lj d k_j / d V_k
            if s > 1:
                dk = _stage_blocks(pick("k_v", "k_v"), pick("k_q", "k_q"), A, h, col=k)
                for l in range(s - 1):
                    blk = None
                    for j in range(s):
                        if tab.omega[l, j] and dk[j] is not None:
                            t = dk[j] * tab.omega[l, j]
                            blk = t if blk is None else blk + t
                    if blk is not None:
                        J[r_e + l * m:r_e + (l + 1) * m, cV] = blk
            # (21f) rows
            if b[k]:
                J[r_f:, cV] = fin.k_q * (b[k] * h)
        J[r_d:r_e, c_v1:] = fin.L_vv
        J[r_f:, c_v1:] = fin.k_v
        return J

    def _jacobian_einsum(self, h, st, fin):
        """The same matrix by einsum over the stacked stage blocks (identity included), the
        float64 assembly: numpy's call count, not flops, is the cost there. Measured against
        ``_jacobian_blocks`` on the same stage values (``benchmarks/newton_variants.py``, median
        CPU us, shared 2-core machine at load ~6): robot 136 vs 199 (gauss-2), 157 vs 310
        (lobatto-iiia-iiib-3); particle 120 vs 161, 147 vs 349; MP particles (n = 7) 143 vs
        187, 153 vs 334: einsum 1.3-2.4x faster, the same matrix (<= 4e-19); a second run at
        load ~4: 69-79 vs 90-168 us (1.3-2.1x). Works at any
        precision too (benchmarks/ledger_speed.py compares it with the block assembly)."""
        tab = self.tab
        s, n, m = self.s, self.n, self.m
        A, Ah, At, b, bh, bt = tab.A, tab.A_hat, tab.A_tilde, tab.b, tab.b_hat, tab.b_tilde
        Lvv = np.array([e.L_vv for e in st]); Lvq = np.array([e.L_vq for e in st])
        Lqv = np.array([e.L_qv for e in st]); Lqq = np.array([e.L_qq for e in st])
        kq = np.array([e.k_q for e in st]); kv = np.array([e.k_v for e in st])
        Rq = np.array([e.R_q for e in st]); Rv = np.array([e.R_v for e in st])
        eye_s = np.eye(s)
        dF = np.einsum("jk,jab->jkab", eye_s, Lqv) + np.einsum("jk,jab->jkab", A, Lqq) * h
        dR = np.einsum("jk,jab->jkab", eye_s, Rv) + np.einsum("jk,jab->jkab", A, Rq) * h
        dP = np.einsum("ik,iab->ikab", eye_s, Lvv) + np.einsum("ik,iab->ikab", A, Lvq) * h
        dk = np.einsum("jk,jab->jkab", eye_s, kv) + np.einsum("jk,jab->jkab", A, kq) * h
        KT = np.transpose(kv, (0, 2, 1))                                 # (s, n, m)
        if st[0].R_L is not None:   # nonideal (3.3): d(h R)/dLambda = -K^T + N_psi replaces -K^T
            KT = -np.array([e.R_L for e in st])
        N = self.size
        J = self.backend.zeros((N, N))
        r_d, r_e, r_f = s * n, s * n + n, s * n + n + (s - 1) * m
        c_lam, c_v1 = s * n, s * n + s * m
        JbV = dP - np.einsum("ij,jkab->ikab", Ah, dF) * h - np.einsum("ij,jkab->ikab", At, dR)
        J[:r_d, :c_lam] = JbV.transpose(0, 2, 1, 3).reshape(s * n, s * n)
        J[:r_d, c_lam:c_v1] = np.einsum("ik,kam->ikam", At, KT).transpose(0, 2, 1, 3).reshape(s * n, s * m)
        JdV = np.einsum("k,ab->kab", b, fin.L_vq) * h - np.einsum("j,jkab->kab", bh, dF) * h \
            - np.einsum("j,jkab->kab", bt, dR)
        J[r_d:r_e, :c_lam] = JdV.transpose(1, 0, 2).reshape(n, s * n)
        J[r_d:r_e, c_lam:c_v1] = np.einsum("k,kam->akm", bt, KT).reshape(n, s * m)
        J[r_d:r_e, c_v1:] = fin.L_vv
        if s > 1:
            JeV = np.einsum("lj,jkab->lkab", tab.omega, dk)
            J[r_e:r_f, :c_lam] = JeV.transpose(0, 2, 1, 3).reshape((s - 1) * m, s * n)
        J[r_f:, :c_lam] = (np.einsum("k,ab->akb", b, fin.k_q) * h).reshape(m, s * n)
        J[r_f:, c_v1:] = fin.k_v
        return J

    # --- one step ----------------------------------------------------------------------------
    def initial_guess(self, v0):
        V = np.array([v0] * self.s)
        return self.pack(V, self.backend.zeros((self.s, self.m)), v0)

    def step(self, t0, q0, v0, h, x0=None, step_index=0) -> StepResult:
        """One step of (21); x0 is the packed starting guess (default V_i = v1 = v0, Psi = 0)."""
        bk = self.backend
        self._step_start = (t0, q0, v0)
        # overflow / invalid operations are detected below (non-finite residual, increment or
        # values), so numpy's RuntimeWarnings would only print noise before the one-line error
        with bk.context(), np.errstate(all="ignore"):
            p0 = self.system.momentum(bk, t0, q0, v0)
            x = (self.initial_guess(v0) if x0 is None else x0).copy()
            # the round-off of the stage values (V_i, Lambda_i, v1 are the unknowns; v0 for a
            # guess of zeros): invariant under the scale of h and of the state
            v_scale = bk.norm_inf(v0)
            tol_abs = self.tol * (bk.norm_inf(x) + v_scale)
            fac = None
            J_last = None
            prev = None
            refresh = False
            res = float("inf")
            why = ""
            renew = False       # "simplified": one new matrix at the iterate (see _budget_short)
            theta_prev = None   # the previous contraction rate |dx_k-1| / |dx_k-2|
            for it in range(1, self.max_iter + 1):
                need_j = fac is None or self.newton in ("full", "mixed") or refresh or renew
                renew = False
                low = need_j and not refresh and self.newton == "mixed" and bk.is_mp
                try:
                    G, J, _ = self.residual(t0, q0, p0, h, x, jacobian=need_j and not low)
                    if low:
                        J = self._float64_jacobian(t0, q0, h, x)
                except (ValueError, ZeroDivisionError, OverflowError, TypeError) as exc:
                    # L or k evaluated outside its domain (math domain error, mpc from mpmath)
                    res, why = float("nan"), f" ({type(exc).__name__}: {exc} evaluating L or k)"
                    break
                res = bk.norm_inf(G)
                if not _finite(res) or not _is_real(bk, G):
                    res, why = float("nan"), why or _nonfinite_why(bk, G)
                    break
                J_last = J if J is not None else J_last
                if need_j:
                    try:
                        fac = bk.factor_float64(J) if low else bk.factor(J)
                    except SingularMatrixError as exc:
                        self.stats.newton_iterations += it      # a failed step's work counts too
                        raise NewtonError(
                            f"step {step_index} at t = {float(t0):.6g}: {exc} (iteration {it}, residual {fmt(res)})",
                            step=step_index, time=float(t0), residual=res, iterations=it) from None
                    self.stats.nlu += 1
                dx = bk.solve_factored(fac, -G)
                dn = bk.norm_inf(dx)
                # "mixed": a float64 matrix contracts at ~1e-16 cond(J), so a rate above 1/10 means
                # it is not good enough here (ill-conditioned J): finish the step at full precision
                if (((self.newton == "auto" and not need_j) or low) and prev is not None
                        and not (dn <= (0.1 if low else 0.25) * prev or dn <= 1e3 * tol_abs)):
                    refresh = True   # slow or diverging simplified step: redo it, and the rest of this step, as full Newton
                    continue
                x_new = x + dx
                # relative to the current iterate, not the starting guess (|Lambda| ~ 1/eps for near-rank-loss K)
                tol_abs = self.tol * (bk.norm_inf(x_new) + v_scale)
                if not _finite(dn):
                    res = float("nan")
                    break
                if dn <= tol_abs:
                    return self._finish(t0, q0, h, x_new, it, res, step_index)
                # RADAU5's rate test (Hairer-Wanner IV.8): a contracting iteration (theta < 1) leaves
                # an error of at most theta / (1 - theta) |dx| after this increment; theta the
                # geometric mean of the last two rates (one sudden drop is no evidence of contraction)
                # at mpmath precision in mpf: with |dx| a float above 1e-308 and theta tiny, a float
                # theta |dx| (or theta_k theta_prev) underflowed to 0.0 and passed against any tol_abs
                # (simplified Newton stopped at 1e-341 at 1000 digits)
                dn_r = mpmath.mpf(dn) if bk.is_mp else dn
                theta_k = dn_r / prev if prev else None
                if theta_k is not None and theta_prev is not None:
                    theta = (theta_k * theta_prev) ** 0.5
                    if theta < 1 and theta / (1 - theta) * dn_r <= RATE_KAPPA * tol_abs:
                        return self._finish(t0, q0, h, x_new, it, res, step_index)
                theta_prev = theta_k
                # round-off floor: increments stopped shrinking at the noise level
                if prev is not None and dn >= 0.5 * prev and dn <= 1e3 * tol_abs:
                    return self._finish(t0, q0, h, x_new, it, res, step_index)
                # the residual itself is at round-off: x solves (21) as well as the working precision
                # can tell; when the Newton matrix is ill-conditioned (near the limit of (4)) the
                # increments are amplified noise and need not fall below the tolerance (BLAS-dependent)
                if self._residual_at_roundoff(G, J_last, x, p0):
                    return self._finish(t0, q0, h, x, it, res, step_index)
                if self.newton == "auto" and not refresh and prev is not None:
                    # contracting, but too slowly for the digits still missing: full Newton from here
                    refresh = _full_newton_cheaper(dn, prev, tol_abs, self.tol)
                if self.newton == "mixed" and bk.is_mp and not refresh and prev is not None:
                    # the float64 matrix gains ~16 digits an increment: at 1000 digits that is more
                    # than max_iter increments; the rest of the step with the full-precision matrix
                    # (quadratic) when the budget left is short
                    refresh = _budget_short(dn, prev, tol_abs, self.max_iter - it)
                if self.newton == "simplified" and prev is not None:
                    # contracting, but too slowly to reach the tolerance within max_iter: a new
                    # matrix at this iterate (at 200-2000 digits simplified Newton gains ~3.6
                    # digits per iteration on the particle, 50 iterations are not enough)
                    renew = _budget_short(dn, prev, tol_abs, self.max_iter - it)
                x = x_new
                prev = dn
            # a NaN, infinite or complex residual or increment: not a slow iteration but a point
            # outside the domain of L or k (or an overflow), status -3 as on the compiled engine
            err = NewtonError if _finite(res) else NonFiniteStepError
            self.stats.newton_iterations += it      # a failed step's work counts too (``Result``)
            raise err(
                f"Newton did not converge at step {step_index}, t = {float(t0):.6g}, h = {float(h):.3g}: "
                f"residual {fmt(res)} after {it} iterations{why}", step=step_index, time=float(t0),
                residual=res, iterations=it)

    def _float64_jacobian(self, t0, q0, h, x):
        """The Newton matrix of (21) at the float64 rounding of the current point ("mixed")."""
        if getattr(self, "_f64", None) is None:
            self._f64 = SparkMethod(self.system, self.tableau, None, newton="full")
        f = lambda a: np.array([float(v) for v in np.asarray(a).reshape(-1)])
        _, J, _ = self._f64.residual(float(t0), f(q0), np.zeros(self.n), float(h), f(x), jacobian=True)
        self.stats.njev += 1
        return J

    #: residual rows within this many units of round-off of their own scale count as converged
    ROUNDOFF_FACTOR = 8

    def _residual_at_roundoff(self, G, J, x, p0) -> bool:
        """|G_i| <= ROUNDOFF_FACTOR * eps * scale_i for every row i of (21b, d, e, f), with
        scale = |J| |x| + |p0| (rows (21b), (21d)): a lower estimate of the magnitude of the terms
        that cancel in G_i (the linear part of each equation plus the momentum p0), so that the
        test is invariant under scaling of the equations and never looser than round-off."""
        bk = self.backend
        if J is None:
            return False
        lim = self.ROUNDOFF_FACTOR * bk.eps
        if bk.is_mp:    # magnitudes only: float64 is exact enough, and 50x cheaper than mpf products
            scale = _magnitudes(J).dot(_magnitudes(x))
            if not np.all(np.isfinite(scale)):
                return False
            mom_rows = (self.s + 1) * self.n
            scale[:mom_rows] += np.tile(_magnitudes(p0), self.s + 1)
            # g and lim are mpf: no float rounding of either (lim = 8 * 10^-dps is below float64's
            # range at dps >= 324, and so are the residuals it must accept)
            return len(scale) == len(G) and all(abs(g) <= lim * sc for g, sc in zip(G, scale))
        scale = np.abs(J).dot(np.abs(x))             # one matrix-vector product: cheap next to the LU
        mom_rows = (self.s + 1) * self.n                # rows (21b), (21d) contain p0
        scale[:mom_rows] = scale[:mom_rows] + np.tile(np.abs(p0), self.s + 1)
        return len(scale) == len(G) and all(abs(g) <= lim * sc for g, sc in zip(G, scale))

    def _finish(self, t0, q0, h, x, it, res, step_index):
        tab = self.tab
        V, Lam, v1 = self.unpack(x)
        q1 = q0 + tab.b.dot(V) * h
        Q = q0 + tab.A.dot(V) * h
        st = self.stats
        st.newton_iterations += it          # before the checks: a step they refuse was worked on too
        energy = self._check_values(t0 + h, q1, v1, x, step_index, t0)
        st.steps += 1
        st.iterations_per_step.append(it)
        st.max_residual = max(st.max_residual, res)
        return StepResult(t0 + h, q1, v1.copy(), V.copy(), Q, Lam / h, it, res, x, energy)

    def _check_values(self, t1, q1, v1, x, step_index, t0):
        """Stop the run (NonFiniteError naming the step and its time) when the step produced NaN,
        infinity or complex (mpc) values, or when the energy (8) at the new point is not a finite
        real number: the step equations use only derivatives of L, so a trajectory that left the
        domain of L (e.g. -log(1 - q1) past q1 = 1) is seen only here. Returns the energy.
        With ``energy_jump`` set, also stops when |E(t1) - E(t0)| > energy_jump (1 + |E(t0)|)."""
        bk = self.backend
        where = f"step {step_index} (t = {float(t0):.6g} -> {float(t1):.6g})"
        if not (_is_real(bk, x) and bk.isfinite(x) and bk.isfinite(q1)):
            raise NonFiniteError(f"{where} produced NaN, infinity or complex values", step=step_index,
                                 time=float(t0))
        try:
            E = self.system.energy(bk, t1, q1, v1)
            ok = _is_real_scalar(E) and (bool(mpmath.isfinite(E)) if bk.is_mp else math.isfinite(float(E)))
        except (ValueError, ZeroDivisionError, OverflowError, TypeError) as exc:
            E, ok = None, False
            why = f"{type(exc).__name__}: {exc}"
        else:
            why = f"E = {E}"
        if not ok:
            raise NonFiniteError(f"{where}: the energy (8) at the new point is not a finite real number ({why}): "
                                 "the solution left the domain of L", step=step_index, time=float(t0))
        if self.energy_jump is not None:
            E0 = self._energy_at(t0, step_index)
            # the change in the step's numbers (mpmath at dps), then a float: a change below
            # float64's resolution of E is seen at the digits of the run
            dE = None if E0 is None else float(abs(E - E0))
            if dE is not None and dE > self.energy_jump * (1 + abs(float(E0))):
                raise NonFiniteError(
                    f"{where}: energy jumped from {float(E0):.6g} to {float(E):.6g} (by {dE:.3g}, more than "
                    f"energy_jump = {self.energy_jump:g} relative): a collision with a singularity of L or a step "
                    "too large", step=step_index, time=float(t0))
            self._last_energy = (step_index + 1, E)
        return E

    def _energy_at(self, t0, step_index):
        """Energy at the start of this step: cached from the previous step when consecutive."""
        last = getattr(self, "_last_energy", None)
        if last is not None and last[0] == step_index:
            return last[1]
        try:
            E0 = self.system.energy(self.backend, *self._step_start)
            finite = math.isfinite(float(E0))
        except (ValueError, ZeroDivisionError, OverflowError, TypeError):
            return None
        return E0 if finite else None


def _magnitudes(a):
    """|a| as float64 (inf where an mpf exceeds float64's range, 0 below it)."""
    a = np.asarray(a)
    if a.dtype != object:
        return np.abs(a.astype(float))
    return np.array([abs(float(v)) for v in a.reshape(-1)]).reshape(a.shape)


#: RADAU5's kappa in the rate test theta / (1 - theta) |dx| <= kappa tol (Hairer-Wanner IV.8): the
#: estimated remaining error 0.1 unit round-off of the unknowns (tol = 10 eps). Measured on the
#: non-quadratic system of tests/compiled/test_compiled_general.py (gauss-2, h = 0.1, 1000 steps) against
#: the same map at 30 digits: kappa = 0.1 left 2.5e-13 in q (the plain |dx| rule: 7.8e-14),
#: kappa = 0.01 6.5e-14, with 5% fewer iterations than before (5298 against 5579)
RATE_KAPPA = 0.01

#: cost of a full Newton iteration (stage Jacobians, Newton matrix, LU) in simplified iterations
#: (residual, solve with the stored factor): residual + Jacobian + LU against residual + solve
#: measured 3.1-3.6x in float64 and 3.4-9.9x at 30 digits (particle, constant-speed, pendulum,
#: robot, MP particles, relativistic; gauss-2 and lobatto-iiia-iiib-3); the lower end, so that
#: "auto" leaves simplified Newton only when full Newton clearly pays
FULL_COST = 3.5


def _full_newton_cheaper(dn, prev, tol_abs, tol) -> bool:
    """For newton="auto": after a simplified increment dn (the previous one prev), do the
    iterations still needed cost less as full Newton? Simplified Newton contracts linearly
    (theta = dn / prev): log(tol_abs / dn) / log(theta) more increments; full Newton, quadratic
    from the relative size e = dn tol / tol_abs, about log2(log(tol) / log(e)) increments at
    FULL_COST each. At 30 digits with theta ~ 1e-2 (constant-speed) this is 13 simplified
    against 3 full iterations; in float64 the two are usually close and simplified stays."""
    # mpf values may lie below the float range (high dps); floats take the cheap log
    ln = lambda x: float(mpmath.log(x)) if isinstance(x, mpmath.mpf) else math.log(x)   # noqa: E731
    theta = dn / prev
    e = dn * tol / tol_abs
    if not (0 < theta < 1 and 0 < e < 1 and 0 < tol < 1) or dn <= tol_abs:
        return False
    n_simplified = ln(tol_abs / dn) / ln(theta)
    n_full = math.ceil(math.log2(ln(tol) / ln(e)))
    return n_simplified > FULL_COST * n_full


def _budget_short(dn, prev, tol_abs, left) -> bool:
    """For newton="simplified": does a contracting iteration (theta = dn / prev < 1) need more
    than ``left`` further increments to bring |dx| below tol_abs (|dx_k| ~ theta^k dn)? A
    diverging one (theta >= 1) is left to fail: simplified Newton is the one-matrix variant."""
    ln = lambda x: float(mpmath.log(x)) if isinstance(x, mpmath.mpf) else math.log(x)   # noqa: E731
    if not (0 < dn < prev) or dn <= tol_abs or not tol_abs > 0:
        return False
    return ln(tol_abs / dn) / ln(dn / prev) > left


@dataclass
class Solution:
    """Result of ``integrate`` (deprecated in favour of ``ldaspark.integrate``'s ``Result``): t (N+1),
    q, v (N+1, n), energy (N+1), constraint (N+1, m) = k(t_n, q_n, v_n), psi (N, s, m), and solver
    statistics. The first six fields are those of ``ldaspark.core.result.Result``, in its order
    (``LEADING_FIELDS``); build it with keywords."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    energy: np.ndarray
    constraint: np.ndarray
    psi: np.ndarray
    stats: dict
    dps: int | None
    method: str
    system: str


def _is_real(bk, a) -> bool:
    """No mpc among the entries (mpmath returns complex numbers outside a real domain)."""
    return not bk.is_mp or not any(isinstance(e, mpmath.mpc) for e in np.asarray(a).reshape(-1))


def _det_sign_mp(S) -> int:
    """sign(det S) of an mpf matrix by LU with partial pivoting, 0 only for an exactly zero pivot
    or a non-finite entry, as numpy's slogdet in float64 (mpmath.det returns 0 for a pivot below
    eps times the largest entry: (4) with entries 1 and 1e559 was "singular" and the monitor
    reported a sign change)."""
    a = [list(row) for row in S.tolist()]
    if not all(mpmath.isfinite(x) for row in a for x in row):
        return 0
    n, sign = len(a), 1
    for k in range(n):
        p = max(range(k, n), key=lambda i: abs(a[i][k]))
        if not a[p][k]:
            return 0
        if p != k:
            a[k], a[p] = a[p], a[k]
            sign = -sign
        piv = a[k][k]
        if piv < 0:
            sign = -sign
        for i in range(k + 1, n):
            f = a[i][k] / piv
            if f:
                for j in range(k + 1, n):
                    a[i][j] -= f * a[k][j]
    return sign


def _nonfinite_why(bk, G) -> str:
    """Why a residual of (21) is not a finite real number: in float64 an infinite entry is an
    overflow (one gauss-2 step of h = 1e300 on the particle: h^2 w x ~ 1e600), which was blamed on
    L or k alone; NaN or complex entries are a point outside the domain of L or k."""
    if not bk.is_mp and np.isinf(np.asarray(G, dtype=float)).any():
        return (" (infinite residual: a float64 overflow, h, q or v too large for L and k, or L or k "
                "evaluated outside its domain)")
    return " (complex or non-finite residual: L or k evaluated outside its domain)"


def _finite(x) -> bool:
    """x is a finite number: a float, or at mpmath precision an mpf, which may lie beyond
    float64's range (``Backend.norm_inf``): math.isfinite rounds it to a float first, and a
    residual of 1.5e319 at 400 digits (h = 1e160) was taken for a NaN and the step ended as
    "L or k evaluated outside its domain"."""
    return bool(mpmath.isfinite(x)) if isinstance(x, mpmath.mpf) else math.isfinite(x)


def _is_real_scalar(e) -> bool:
    return not isinstance(e, (complex, mpmath.mpc))


MAX_STEPS = 10 ** 9  # beyond this a run cannot finish; reject instead of hanging (h = 1e-300)


def _saddle_sign(system, bk, t, q, v) -> int:
    """sign(det (4)) at the working precision (0 when it is not finite): float64, or mpmath at
    dps digits, where (4) is accepted down to a reciprocal condition of 1e3 10^-dps
    (``check_saddle``): rounded to float64, det (4) of a K K^T of condition 1e16 is 0 at some
    points and positive at others, and a sign change the motion did not make stopped the run."""
    with bk.context():
        S = system.saddle_matrix(bk, t, q, v)
        if bk.is_mp:
            return _det_sign_mp(S)
    sgn, _ = np.linalg.slogdet(np.asarray(S, dtype=float))
    return int(sgn) if np.isfinite(sgn) else 0


def n_steps_for(t0, t_end, h, dps=None) -> int:
    """N with t0 + N h = t_end: in float64 (``dps`` None), or at ``dps`` digits, where h, t0 and
    t_end may lie beyond float64's range or precision (``_n_steps_mp``)."""
    if dps is not None:
        return _n_steps_mp(t0, t_end, h, int(dps))
    if h == 0 or not math.isfinite(float(h)):
        raise InputError(f"step size h must be finite and nonzero, got {h}")
    if not (math.isfinite(float(t0)) and math.isfinite(float(t_end))):
        raise InputError(f"t0 and t_end must be finite, got t0 = {t0}, t_end = {t_end}")
    span = float(t_end) - float(t0)
    if abs(span / float(h)) > MAX_STEPS:
        raise InputError(f"h = {h} needs {abs(span / float(h)):.3g} steps to reach t_end = {t_end} (limit {MAX_STEPS:.0e})")
    N = int(round(span / float(h)))
    if N <= 0:
        raise InputError(f"t_end = {t_end} is not reached from t0 = {t0} with h = {h}")
    # t_end on the grid to the float rounding of the data (half an ulp of t0, t_end and N h, and
    # of the computed span, in exact rationals): a fixed 1e-9 max(1, |span|) let t_span = (0,
    # 1e-12), h = 3e-13 end at 9e-13
    from fractions import Fraction
    a, b, hq = Fraction(float(t0)), Fraction(float(t_end)), Fraction(float(h))
    allow = Fraction(2) ** -53 * 2 * (abs(a) + abs(b) + N * abs(hq))
    if abs(N * hq - (b - a)) > allow:
        raise InputError(f"(t_end - t0) = {span} is not an integer multiple of h = {h} (off by "
                         f"{float(abs(N * hq - (b - a))):.3g}, float64 round-off {float(allow):.3g})")
    return N


def _n_steps_mp(t0, t_end, h, dps: int) -> int:
    """``n_steps_for`` at dps digits: in mpf (h = "1e-420" is 0.0 as a float), and t_end on the
    grid to the precision of the data: a float input stands for its value to half an ulp (2^-53
    relative: h = 0.1 and t_end = 1 are 10 steps), any other (int, decimal text, Fraction, sympy)
    is exact up to its conversion at dps digits; the sum over t0, t_end and N h of those radii,
    with 10 units of the digits for the arithmetic, bounds |N h - (t_end - t0)|."""
    from .backend import _mpf

    def radius(x, val):
        return abs(val) * (mpmath.mpf(2) ** -53 if isinstance(x, (float, np.floating)) else mpmath.mpf(10) ** -dps)

    with mpmath.workdps(dps + 10):
        h_, a, b = _mpf(h), _mpf(t0), _mpf(t_end)
        if h_ == 0 or not mpmath.isfinite(h_):
            raise InputError(f"step size h must be finite and nonzero, got {h}")
        if not (mpmath.isfinite(a) and mpmath.isfinite(b)):
            raise InputError(f"t0 and t_end must be finite, got t0 = {t0}, t_end = {t_end}")
        span = b - a
        ratio = span / h_
        if abs(ratio) > MAX_STEPS:
            raise InputError(f"h = {h} needs {mpmath.nstr(abs(ratio), 3)} steps to reach t_end = {t_end} "
                             f"(limit {MAX_STEPS:.0e})")
        N = int(mpmath.nint(ratio))
        if N <= 0:
            raise InputError(f"t_end = {t_end} is not reached from t0 = {t0} with h = {h}")
        allow = (radius(t0, a) + radius(t_end, b) + N * radius(h, h_)
                 + 10 * mpmath.mpf(10) ** -dps * max(abs(a), abs(b), N * abs(h_)))
        if abs(N * h_ - span) > allow:
            off = abs(N * h_ - span)
            # digits enough to show the offset (t_end = 1.000000000001 printed as 1.0 at 12 digits)
            shown = min(dps, 12 + max(0, int(mpmath.ceil(mpmath.log10(abs(span) / off))))) if span else 12
            raise InputError(f"(t_end - t0) = {mpmath.nstr(span, shown)} is not an integer multiple of h = {h} "
                             f"at {dps} digits (off by {mpmath.nstr(off, 3)})")
    return N


def march(method: SparkMethod, t0, q0, v0, h, n_steps: int, monitor_saddle: bool = True, predictor: str = "auto"):
    """The stepping loop of (21) shared by ``integrate`` and ``ldaspark.integrate``: yields
    (i, t_i, q_i, StepResult of step i) for i = 0..n_steps-1 from checked, consistent
    (t0, q0, v0) already converted by ``method.backend`` (t_i = t0 + i h). The caller stores
    what it needs (every point, every k-th, stage values for dense output, events) and may stop
    early; a failing step raises (NewtonError, NonFiniteError, SingularSaddleError) from the
    generator. Predictor: the previous step's unknowns shifted by the last velocity increment.
    ``monitor_saddle``: a sign change of det (4) between t0 and a step point is an error (the
    step landed on the second solution near the limit of (4), see ``integrate``).
    ``predictor`` (``ldaspark.core.rootfinder.PREDICTORS``): "auto" and "previous" as above,
    "zero" every step from zero increments (V_i = v1 = v0, Psi = 0: ``SparkMethod.step``'s
    default start)."""
    system, bk = method.system, method.backend
    q, v = q0, v0
    x = v_prev = None
    sign0 = _saddle_sign(system, bk, t0, q, v) if monitor_saddle else None
    for i in range(n_steps):
        ti = t0 + i * h
        if predictor == "zero":
            x = None
        elif x is not None and v_prev is not None:
            Vp, Lp, v1p = method.unpack(x)
            x = method.pack(Vp + (v - v_prev), Lp, v1p + (v - v_prev))
        r = method.step(ti, q, v, h, x0=x, step_index=i)
        if sign0 and _saddle_sign(system, bk, r.t1, r.q1, r.v1) != sign0:
            raise SingularSaddleError(
                f"step {i} (t = {float(ti):.6g} -> {float(r.t1):.6g}) crossed the singular set of the "
                "saddle matrix (4): det (4) changed sign, so the step solved (21) on the wrong branch or the "
                "solution left the region where (4) holds (monitor_saddle=False skips this check)")
        yield i, ti, q, r
        v_prev = v
        q, v, x = r.q1, r.v1, r.x


def integrate(system: LagrangianSystem, tableau: SparkTableau, t0, q0, v0, h, t_end=None,
              n_steps=None, dps=None, project=False, tol=None, newton="auto", progress=None,
              check_initial=True, monitor_saddle=True, energy_jump=None) -> Solution:
    """Integrate (1) with the SPARK method (21) at constant step h from consistent data.

    Exactly one of ``t_end`` / ``n_steps``. With ``dps`` the computation runs in mpmath at
    that precision (inputs may be strings or sympy numbers to carry full precision).
    ``monitor_saddle`` watches the sign of det (4) at every step point: near the limit of (4)
    the stage equations have a second, nearby solution, and a sign change means the step
    landed on it (or the solution left the region where (4) holds); it is an error, not a
    silent jump. Every step stops with NonFiniteError on NaN, infinity or complex values (or an
    energy (8) that is not a finite real number: the solution left the domain of L).
    ``energy_jump`` (off by default) also stops a step that changes the energy by more than
    energy_jump (1 + |E|): the only monitor that sees a passage through a singularity of L such
    as 1/q1, which leaves finite values and a regular (4) behind.
    ``newton``: "auto" (default), "full" or "simplified" (``SparkMethod``); "auto" gives full
    Newton's numbers to within the Newton tolerance at less cost.
    Raises InconsistentInitialDataError (unless ``project``), SingularSaddleError, NewtonError,
    NonFiniteError.
    """
    method = SparkMethod(system, tableau, dps=dps, tol=tol, newton=newton, energy_jump=energy_jump)
    bk = method.backend
    with bk.context():
        try:
            h_, t0_ = bk.scalar(h), bk.scalar(t0)
            q, v = bk.array(q0), bk.array(v0)
        except (TypeError, ValueError) as exc:
            raise InputError(f"t0, h, q0 and v0 must be numbers: {exc}") from None
        if not (math.isfinite(float(h_)) and math.isfinite(float(t0_))) or h_ == 0:
            raise InputError(f"step size h must be finite and nonzero and t0 finite, got h = {h}, t0 = {t0}")
        if (t_end is None) == (n_steps is None):
            raise InputError("give exactly one of t_end or n_steps")
        if n_steps is None:
            n_steps = n_steps_for(t0, t_end, h)
        from .validate import count
        n_steps = count(n_steps, "n_steps", 1, MAX_STEPS)
        # the one initial-point check of every engine (numbers, shapes, finite, (8) and k finite,
        # then (4), the projection and (1c) unless ``check_initial`` is off)
        from .validate import initial_point
        t0_, q, v = initial_point(system, bk, t0_, q, v, project=project and check_initial, tol=tol,
                                  consistent=check_initial)
        N = n_steps
        from .validate import check_storage
        check_storage(N + 1, 2 + 2 * system.n + (tableau.s + 1) * system.m, bk.is_mp)
        ts = [t0_ + i * h_ for i in range(N + 1)]
        Qs, Vs, Ps = [q], [v], []
        for i, _, _, r in march(method, t0_, q, v, h_, N, monitor_saddle=monitor_saddle):
            Qs.append(r.q1)
            Vs.append(r.v1)
            Ps.append(r.Psi)
            if progress is not None:
                progress(i + 1, N)
        E = [system.energy(bk, ts[i], Qs[i], Vs[i]) for i in range(N + 1)]
        K = [system.constraint(bk, ts[i], Qs[i], Vs[i]) for i in range(N + 1)]
    dt = object if bk.is_mp else float
    return Solution(t=np.array(ts, dtype=dt), q=np.array(Qs, dtype=dt), v=np.array(Vs, dtype=dt),
                    energy=np.array(E, dtype=dt), constraint=np.array(K, dtype=dt), psi=np.array(Ps, dtype=dt),
                    stats=method.stats.as_dict(), dps=dps, method=tableau.name, system=system.name)
