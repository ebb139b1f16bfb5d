"""Comparator methods of sections 7.3-7.5 and 8.4 (not Lagrange-d'Alembert SPARK methods
themselves, or other implementations of one), behind one entry point
``integrate_comparator(name, system, t0, q0, v0, h, n_steps, dps=None)`` returning a
``ldaspark.core.spark.Solution``.

Names (shared contract between engineers):

* ``gauss-irk-S``: the "standard" s-stage Gauss IRK for the index-2 DAE, imposing
  k(T_i, Q_i, V_i) = 0 at every stage instead of (21e-f) (7.3-7.4). Order 1 (s = 1),
  2 (s = 2) and k(t1, q1, v1) != 0.
* ``lobatto-iiia-iiib-2-leapfrog``: the step-by-step form after (25) for constant h
  (mechanical systems), grad U evaluated once per step.
* ``lobatto-iiia-iiib-2-modified``: 2-stage Lobatto IIIA-B SPARK with (21e)
  0 = (K_1 + K_2)/2 replaced by 0 = k(t0 + h/2, q0 + h/2 V_1, V_1) (8.4); a Newton solve
  of the full SPARK system (any system).
* ``lobatto-iiia-iiib-2-modified-leapfrog``: the same method in its semi-implicit
  step-by-step form (mechanical systems), grad U once per step.
* ``mp-lobatto-iiib-a-2``: McLachlan-Perlmutter's 2-stage Lobatto IIIB-A LDA method (26)
  (mechanical systems), grad U once per step.
* ``euler-i-ii-composition``, ``euler-ii-i-composition``: "symplectic" Euler SPARK I then II
  (resp. II then I), each with step h/2 (7.5: neither equals Lobatto IIIA-B).

Mechanical systems are L = 1/2 v^T M v - U(t, q), k = K(t, q) v + b(t, q) with constant M; the parts
are taken from ``system.mechanical`` or derived from L and k (``mechanical_parts``).
Every Solution's ``stats`` carries ``n_grad_U`` (evaluations of grad U, or of grad_q L for the
SPARK-based comparators, one per stage point per Newton iteration).
"""
from __future__ import annotations

import contextlib

import math
import re
from typing import Callable

import mpmath
import numpy as np
import sympy

from .backend import Backend, SingularMatrixError, fmt
from .errors import InputError, LdasparkError, NewtonError, NonFiniteStepError
from .spark import Solution, SparkMethod
from .derive import real_jacobian
from .system import _NONSMOOTH, LagrangianSystem, _arr
from .families import euler_i, euler_ii, gauss, lobatto_iiia_iiib
from . import validate

FIXED_NAMES = ("lobatto-iiia-iiib-2-leapfrog", "lobatto-iiia-iiib-2-modified",
               "lobatto-iiia-iiib-2-modified-leapfrog", "mp-lobatto-iiib-a-2",
               "euler-i-ii-composition", "euler-ii-i-composition")


#: the comparators of Fig. 4 whose semi-implicit steps need the mechanical form (M, grad U, K, b)
#: on every engine (the modified method of 8.4 and the others run general systems generically)
MECHANICAL_ONLY = ("lobatto-iiia-iiib-2-leapfrog", "lobatto-iiia-iiib-2-modified-leapfrog", "mp-lobatto-iiib-a-2")


def require_mechanical(name: str, system: LagrangianSystem) -> None:
    """The InputError comparator ``name`` gives a system it cannot run, before any step (None when
    it can): what the driver raises instead of falling back to an engine that refuses it too."""
    if name in MECHANICAL_ONLY:
        # at the run's parameter values, as the comparator engine runs it (``engines.comparator``):
        # a mass matrix with a parameter is constant, not a refusal
        MechanicalParts(system.substituted() if getattr(system, "params", ()) else system, Backend(None))


def comparator_names(max_s: int = 4) -> list[str]:
    return [f"gauss-irk-{s}" for s in range(1, max_s + 1)] + list(FIXED_NAMES)


def is_comparator(name: str) -> bool:
    return name in FIXED_NAMES or re.fullmatch(r"gauss-irk-[1-9][0-9]*", name) is not None


# --- mechanical form ------------------------------------------------------------------------
class MechanicalParts:
    """Numeric M, grad U(q), K(q), b(q) and d(K(q) v + b(q))/dq of a mechanical system, with
    evaluation counters (``n_grad_U``)."""

    def __init__(self, system: LagrangianSystem, backend: Backend):
        if getattr(system, "N", None) is not None:
            raise InputError(f"{system.name}: the semi-implicit comparators have no nonideal term (3.3)")
        mech = system.mechanical or derive_mechanical(system)
        from .system import check_mechanical, completed_mechanical, refuse_text
        refuse_text(mech, f"{system.name}: mechanical")     # set by hand after construction: never sympify text
        if system.mechanical is not None:
            check_mechanical(system, mech)                   # the generic engine's M (L_vv), symmetric
            mech = completed_mechanical(mech)                # U and b default to 0, as on every engine
        q, v = system.q, system.v
        M = sympy.Matrix(mech["M"])
        if M.free_symbols:
            raise InputError(f"{system.name}: the semi-implicit comparators need a constant mass matrix M")
        K = sympy.Matrix(mech["K"])
        b = sympy.Matrix(mech["b"]).reshape(K.rows, 1)
        U = sympy.sympify(mech["U"], strict=True)
        tq = [system.t] + list(q)       # U, K, b may depend on t (section 7 with U(t, q), K(t, q), b(t, q))
        gU = real_jacobian([U], q, tq).T
        kq = real_jacobian(K * sympy.Matrix(v) + b, q, tq + list(v))
        mod = [_NONSMOOTH, backend.lambdify_module]      # Abs' = sign, sign' = 0 off its jump
        self.bk = backend
        self.n, self.m = system.n, K.rows
        with backend.context():
            self.M = backend.array([[M[i, j] for j in range(self.n)] for i in range(self.n)])
        from .gensource import lambdify      # no user text in generated source
        self._gU = lambdify(tq, gU.tolist(), mod[1], namespaces=mod[:1])
        self._K = lambdify(tq, [K.tolist(), b.tolist()], mod[1], namespaces=mod[:1])
        self._kq = lambdify(tq + list(v), kq.tolist(), mod[1], namespaces=mod[:1])
        self.n_grad_U = 0

    def grad_U(self, t, q):
        self.n_grad_U += 1
        return _arr(self._gU(t, *q), self.bk)[:, 0]

    def K_b(self, t, q):
        K, b = self._K(t, *q)
        # reshaped, not indexed: m = 0 prints b as [] (shape (0,), no column to index)
        return _arr(K, self.bk).reshape(self.m, self.n), _arr(b, self.bk).reshape(self.m)

    def k_q(self, t, q, v):
        return _arr(self._kq(t, *q, *v), self.bk).reshape(self.m, self.n)


def derive_mechanical(system: LagrangianSystem) -> dict:
    """M, U, K, b with L = 1/2 v^T M v - U(t, q) and k = K(t, q) v + b(t, q), M constant (the form
    the compiled engine detects, ``compiled.runner.mechanical_parts``), or InputError.

    Decided as the compiled engine decides it: L_vv free of (t, q, v), grad_v L - M v = 0 at random
    points (``numerically_zero``; then L = v^T M v / 2 - U exactly), k_v free of v (then k = K v + b).
    sympy.simplify of L - (v^T M v / 2 - U) missed identities the compiled engine found (a term
    vx (log(exp(x)) - x): the compiled comparator ran, the generic one refused)."""
    from .system import _derived_nonzeros, numerically_zero
    q, v, t = list(system.q), list(system.v), system.t
    zero_v = {x: 0 for x in v}
    M = system.L_vv
    U = -system.L.xreplace(zero_v)
    K = system.k_v
    b = system.k.xreplace(zero_v)
    syms = q + v + [t] + list(getattr(system, "params", ()))
    # grad_v L - M v row by row over the nonzero entries (the dense M v is n^2 sympy products)
    rows: dict = {}
    for (i, j), e in _derived_nonzeros(system, "L_vv").items():
        rows.setdefault(i, []).append(e * v[j])
    Lv = _derived_nonzeros(system, "L_v")
    gyro = [Lv.get((i, 0), sympy.S.Zero) - sympy.Add(*rows.get(i, ())) for i in sorted(set(rows) | {i for i, _ in Lv})]
    ok = (not (M.free_symbols & (set(q) | set(v) | {t}))
          and not (K.free_symbols & set(v))
          and all(e == 0 or numerically_zero(e, syms, signs=True) for e in gyro))
    if not ok:
        raise InputError(f"{system.name} is not of the mechanical form L = v^T M v/2 - U(t, q), "
                         "k = K(t, q) v + b(t, q) with constant M needed by this comparator")
    return {"M": M, "U": U, "K": K, "b": b}


# --- a small Newton solver for the semi-implicit forms --------------------------------------
def _newton(fun, x0, bk: Backend, tol, max_iter, step_index, t, counts=None):
    """Newton on fun(x) -> (G, J); same stopping rule as SparkMethod.step. ``counts`` (a dict):
    the counters every engine reports, added to: ``nfev`` and ``njev`` one per call of fun (a
    residual at the step's point and its Jacobian), ``nlu`` one per factorised solve."""
    counts = {} if counts is None else counts
    x = x0.copy()
    # round-off of the unknowns' values (invariant under the scale of h and of the state)
    tol_abs = tol * bk.norm_inf(x)
    prev = None
    res = float("inf")
    it = 0
    for it in range(1, max_iter + 1):
        with _domain(step_index, t):
            G, J = fun(x)
        counts["nfev"] = counts.get("nfev", 0) + 1
        counts["njev"] = counts.get("njev", 0) + 1
        # every iteration run, a failed step's too (``Result``: the counters' one meaning)
        counts["newton_iterations"] = counts.get("newton_iterations", 0) + 1
        res = bk.norm_inf(G)
        if not math.isfinite(res):
            break
        try:
            dx = bk.solve(J, -G)
        except SingularMatrixError as exc:
            raise NewtonError(f"step {step_index} at t = {float(t):.6g}: {exc}", step=step_index,
                              time=float(t), residual=res, iterations=it) from None
        counts["nlu"] = counts.get("nlu", 0) + 1
        x_new = x + dx
        dn = bk.norm_inf(dx)
        if not math.isfinite(dn):
            break
        if dn <= tol_abs or (prev is not None and dn >= 0.5 * prev and dn <= 1e3 * tol_abs):
            return x_new, it
        # residual at round-off of its own scale |J| |x|: converged (see SparkMethod.step)
        scale = np.abs(J).dot(np.abs(x))
        if all(abs(g) <= SparkMethod.ROUNDOFF_FACTOR * bk.eps * sc for g, sc in zip(G, scale)):
            return x, it
        x = x_new
        prev = dn
    # a NaN or infinite residual or increment: outside the domain of L or k, or an overflow
    # (status -3, as the compiled kernels and SparkMethod.step report it), not a slow iteration
    err = NewtonError if math.isfinite(res) else NonFiniteStepError
    raise err(f"Newton did not converge at step {step_index}, t = {float(t):.6g}: residual {fmt(res)}",
              step=step_index, time=float(t), residual=res, iterations=it)


@contextlib.contextmanager
def _domain(k, t):
    """Evaluations of grad U, K, b and their derivatives in step k of a semi-implicit comparator:
    outside the domain of L or k (math's ValueError, an mpc that is no mpf: TypeError, a division
    by zero, an overflow) the step stops with NonFiniteStepError naming the step, as
    SparkMethod.step does (never the raw exception out of ``integrate``)."""
    try:
        yield
    except (ValueError, ZeroDivisionError, OverflowError, TypeError) as exc:
        raise NonFiniteStepError(f"step {k} at t = {float(t):.6g}: {type(exc).__name__}: {exc} evaluating L or k "
                                 "(the solution left their domain)", step=k, time=float(t)) from None


def _saddle(bk, M, KT, Cv):
    n, m = KT.shape
    J = bk.zeros((n + m, n + m))
    J[:n, :n] = M
    J[:n, n:] = KT
    J[n:, :n] = Cv
    return J


# --- SPARK variants with other constraint rows ----------------------------------------------
class GaussIRK(SparkMethod):
    """Standard s-stage Gauss IRK for the index-2 DAE: (21a-d) with 0 = k(T_i, Q_i, V_i),
    i = 1..s, replacing (21e-f) (7.3-7.4). v1 is still defined by (21d)."""

    def residual(self, t0, q0, p0, h, x, jacobian=True):
        G, J, (T, Q, q1) = super().residual(t0, q0, p0, h, x, jacobian)
        s, n, m = self.s, self.n, self.m
        r0 = s * n + n                    # first row of (21e-f), s*m rows in all
        # k, k_q, k_v at the stages (T_i, Q_i, V_i) do not depend on the multipliers: those of the
        # stage evaluations of (21b) just made (evaluated again, they were counted twice in nfev,
        # 2 s + 1 points per residual instead of the s + 1 of ``Result``)
        for i in range(s):
            e = self._stage_evals[i]
            G[r0 + i * m:r0 + (i + 1) * m] = e.k
            if jacobian:
                J[r0 + i * m:r0 + (i + 1) * m, :] = 0
                for j in range(s):
                    blk = h * self.tab.A[i, j] * e.k_q
                    if i == j:
                        blk = blk + e.k_v
                    J[r0 + i * m:r0 + (i + 1) * m, j * n:(j + 1) * n] = blk
        return G, J, (T, Q, q1)


class ModifiedLobatto2(SparkMethod):
    """2-stage Lobatto IIIA-B SPARK with (21e) replaced by 0 = k(t0 + h/2, q0 + h/2 V_1, V_1)
    (section 8.4); (21f) kept."""

    def __init__(self, system, dps=None, tol=None, max_iter=50):
        super().__init__(system, lobatto_iiia_iiib(2), dps=dps, tol=tol, max_iter=max_iter)

    def residual(self, t0, q0, p0, h, x, jacobian=True):
        G, J, (T, Q, q1) = super().residual(t0, q0, p0, h, x, jacobian)
        n, m, bk = self.n, self.m, self.backend
        V, _, _ = self.unpack(x)
        half = h / 2
        e = self.system.stage(bk, t0 + half, q0 + half * V[0], V[0], bk.zeros(m), jacobian)
        r0 = 2 * n + n
        G[r0:r0 + m] = e.k
        if jacobian:
            J[r0:r0 + m, :] = 0
            J[r0:r0 + m, :n] = e.k_v + half * e.k_q
        self.stats.nfev += 1
        return G, J, (T, Q, q1)


# --- drivers ------------------------------------------------------------------------------
def _finish_solution(system, bk, ts, Qs, Vs, Ps, stats, dps, name):
    with bk.context():
        # the run's work was done to its end: a point outside the domain of L made by step k
        # carries the run's counters, k steps accepted
        try:
            E = [_energy_checked(system, bk, ts, Qs, Vs, i) for i in range(len(ts))]
        except LdasparkError as exc:
            from .result import attach_counters
            raise attach_counters(exc, dict(stats, steps=int(getattr(exc, "step", 0) or 0)))
        K = [system.constraint(bk, ts[i], Qs[i], Vs[i]) for i in range(len(ts))]
    dt = object if bk.is_mp else float
    return Solution(t=np.array(ts, dtype=dt), q=np.array(Qs, dtype=dt), v=np.array(Vs, dtype=dt),
                    energy=np.array(E, dtype=dt), constraint=np.array(K, dtype=dt), psi=np.array(Ps, dtype=dt),
                    stats=stats, dps=dps, method=name, system=system.name)


def _energy_checked(system, bk, ts, Qs, Vs, i):
    """Energy (8) at step point i; NonFiniteError naming the step that produced a point with
    NaN / infinite / complex values or outside the domain of L (as SparkMethod's per-step check)."""
    from .errors import NonFiniteError
    try:
        E = system.energy(bk, ts[i], Qs[i], Vs[i])
        ok = (not isinstance(E, (complex, mpmath.mpc)) and math.isfinite(float(E))
              and bk.isfinite(Qs[i]) and bk.isfinite(Vs[i]))
    except (ValueError, ZeroDivisionError, OverflowError, TypeError):
        ok = False
    if not ok:
        k = max(i - 1, 0)
        raise NonFiniteError(f"step {k} (t = {float(ts[k]):.6g} -> {float(ts[i]):.6g}) produced a point where the "
                             "energy (8) is not a finite real number: the solution left the domain of L",
                             step=k, time=float(ts[k]))
    return E


def _spark_variant_loop(method_objs, system, t0, q0, v0, h, n_steps, name, progress):
    """Run one or more SparkMethod objects in sequence per step (compositions use two, each
    with its own fraction of h)."""
    bk = method_objs[0][0].backend
    with bk.context():
        h_ = bk.scalar(h)
        t = bk.scalar(t0)
        q, v = bk.array(q0), bk.array(v0)
        ts, Qs, Vs, Ps = [t], [q], [v], []
        guesses = [None] * len(method_objs)
        done = [0]

        def spent():
            return {"steps": done[0], **{c: sum(meth.stats.as_dict()[c] for meth, _ in method_objs)
                                         for c in ("newton_iterations", "nfev", "njev", "nlu")}}
        for k in range(n_steps):
            psi = []
            tk = t
            done[0] = k
            for idx, (meth, frac) in enumerate(method_objs):
                hh = h_ * frac
                with _counted(spent):
                    r = meth.step(tk, q, v, hh, x0=guesses[idx], step_index=k)
                guesses[idx] = r.x
                q, v, tk = r.q1, r.v1, tk + hh
                psi.extend(list(r.Psi))
            t = bk.scalar(t0) + (k + 1) * h_
            ts.append(t)
            Qs.append(q)
            Vs.append(v)
            Ps.append(psi)
            if progress is not None:
                progress(k + 1, n_steps)
    st = {"steps": n_steps, "newton_iterations": 0, "nfev": 0, "njev": 0, "nlu": 0}
    for meth, _ in method_objs:
        d = meth.stats.as_dict()
        for key in ("newton_iterations", "nfev", "njev", "nlu"):
            st[key] += d[key]
    st["n_grad_U"] = st["nfev"]          # every stage evaluation evaluates grad_q L
    st["mean_iterations"] = st["newton_iterations"] / max(n_steps, 1)
    return _finish_solution(system, bk, ts, Qs, Vs, Ps, st, method_objs[0][0].dps, name)


@contextlib.contextmanager
def _counted(spent: Callable):
    """A step failure raised inside carries the run's counters so far (``spent()``, the
    ``FAILURE_COUNTERS`` of ``ldaspark.core.result``: the accepted steps and the work of every
    step, the failed one included), as the compiled kernels' failures do."""
    from .result import attach_counters
    try:
        yield
    except LdasparkError as exc:
        attach_counters(exc, spent())
        raise


@contextlib.contextmanager
def _semi_implicit(system, dps, tol, h, t0, q0, v0):
    """Set-up shared by the semi-implicit comparators (25), (8.4), (26): in the backend's
    context, yields (backend, mechanical parts, Newton tolerance, h, h/2, t0, q0, v0), the numbers
    as the backend's."""
    bk = Backend(dps)
    mp = MechanicalParts(system, bk)
    tol = tol if tol is not None else 10 * bk.eps
    with bk.context():
        h_ = bk.scalar(h)
        yield bk, mp, tol, h_, h_ / 2, bk.scalar(t0), bk.array(q0), bk.array(v0)


def _leapfrog(system, t0, q0, v0, h, n_steps, dps, tol, max_iter, constraint, name, progress):
    """Step-by-step form after (25) for constant h, with the half-step constraint either
    (K(q_k) v + b(q_k) + K(q_{k+1}) v + b(q_{k+1}))/2 = 0 ("mean", Lobatto IIIA-B) or
    k(q_k + h/2 v, v) = 0 ("midpoint", the modified method of 8.4):

        M v_{k+1/2} = M v_{k-1/2} - h (grad U(q_k) + K(q_k)^T Psi~_k),  q_{k+1} = q_k + h v_{k+1/2},

    started with M v_{1/2} = M v_0 - h/2 (grad U(q_0) + K(q_0)^T Psi_{1,0}). The outputs
    v_k (not needed by the recursion) come from the linear system
    M v_k + K(q_k)^T (h/2 Psi_{2,k-1}) = M v_{k-1/2} - h/2 grad U(q_k), K(q_k) v_k = -b(q_k)
    (the paper prints v_{k+1/2} on its right-hand side; the SPARK step gives v_{k-1/2}).
    grad U(q_k) is evaluated once per step and shared by both uses."""
    with _semi_implicit(system, dps, tol, h, t0, q0, v0) as (bk, mp, tol, h_, half, t0_, q, v):
        n, m, M, iters = mp.n, mp.m, mp.M, 0
        counts = {"nfev": 0, "njev": 0, "nlu": 0, "newton_iterations": 0}
        ts, Qs, Vs, Ps = [t0_], [q], [v], []
        g = mp.grad_U(t0_, q)
        w = None                 # v_{k-1/2}
        psi2_prev = bk.zeros(m)  # Psi_{2,k-1}
        x = np.concatenate([v, bk.zeros(m)])
        # a failure in a step (its Newton, or a point outside the domain) carries the counters
        with _counted(lambda: dict(counts, steps=len(ts) - 1)):
            for k in range(n_steps):
                # t_k, and where the constraint is imposed: t_{k+1} (mean) or t_k + h/2 (midpoint)
                tk, t1 = ts[-1], t0_ + (k + 1) * h_
                tc = t1 if constraint == "mean" else tk + half
                with _domain(k, tk):
                    Kk, bk_k = mp.K_b(tk, q)
                rhs = M.dot(v) - half * g if k == 0 else M.dot(w) - h_ * g

                def fun(z, q=q, Kk=Kk, bk_k=bk_k, rhs=rhs, tc=tc):
                    vh, lam = z[:n], z[n:]
                    r1 = M.dot(vh) + Kk.T.dot(lam) - rhs
                    if constraint == "mean":
                        q1 = q + h_ * vh
                        K1, b1 = mp.K_b(tc, q1)
                        r2 = (Kk.dot(vh) + bk_k + K1.dot(vh) + b1) / 2
                        Cv = (Kk + K1 + h_ * mp.k_q(tc, q1, vh)) / 2
                    else:
                        qm = q + half * vh
                        Km, bm = mp.K_b(tc, qm)
                        r2 = Km.dot(vh) + bm
                        Cv = Km + half * mp.k_q(tc, qm, vh)
                    return np.concatenate([r1, r2]), _saddle(bk, M, Kk.T, Cv)

                x, it = _newton(fun, x, bk, tol, max_iter, k, tk, counts)
                iters += it
                w, lam = x[:n], x[n:]
                q = q + h_ * w
                # output v_{k+1} and Psi_{2,k} from the (otherwise unneeded) linear system
                with _domain(k, tk):              # q_{k+1} outside the domain: step k failed
                    g = mp.grad_U(t1, q)
                    K1, b1 = mp.K_b(t1, q)
                    sol = bk.solve(_saddle(bk, M, K1.T, K1), np.concatenate([M.dot(w) - half * g, -b1]))
                counts["nlu"] += 1
                v, mu = sol[:n], sol[n:]
                psi2 = mu / half
                psi1 = lam / half - psi2_prev
                psi2_prev = psi2
                ts.append(t1)
                Qs.append(q)
                Vs.append(v)
                Ps.append([psi1, psi2])
                if progress is not None:
                    progress(k + 1, n_steps)
    st = {"steps": n_steps, "newton_iterations": iters, **counts, "n_grad_U": mp.n_grad_U,
          "mean_iterations": iters / max(n_steps, 1)}
    return _finish_solution(system, bk, ts, Qs, Vs, Ps, st, dps, name)


def _mp_iiib_a(system, t0, q0, v0, h, n_steps, dps, tol, max_iter, name, progress):
    """McLachlan-Perlmutter's 2-stage Lobatto IIIB-A LDA method (26a-d):
    Q_1 = q0 + h/2 v0, M v1 = M v0 - h (grad U(Q_1) + K(Q_1)^T Psi_1),
    q1 = q0 + h/2 (v0 + v1), 0 = K(q1) v1 + b(q1). One grad U per step."""
    with _semi_implicit(system, dps, tol, h, t0, q0, v0) as (bk, mp, tol, h_, half, t0_, q, v):
        n, m, M, iters = mp.n, mp.m, mp.M, 0
        counts = {"nfev": 0, "njev": 0, "nlu": 0, "newton_iterations": 0}
        ts, Qs, Vs, Ps = [t0_], [q], [v], []
        x = np.concatenate([v, bk.zeros(m)])
        # a failure in a step (its Newton, or a point outside the domain) carries the counters
        with _counted(lambda: dict(counts, steps=len(ts) - 1)):
            for k in range(n_steps):
                tk, t1 = ts[-1], t0_ + (k + 1) * h_
                Q1 = q + half * v                                   # (26a), at t_k + h/2
                with _domain(k, tk):
                    g = mp.grad_U(tk + half, Q1)
                    KQ, _ = mp.K_b(tk + half, Q1)
                rhs = M.dot(v) - h_ * g

                def fun(z, q=q, v=v, KQ=KQ, rhs=rhs, t1=t1):
                    v1, lam = z[:n], z[n:]
                    r1 = M.dot(v1) + KQ.T.dot(lam) - rhs            # (26b), lam = h Psi_1
                    q1 = q + half * (v + v1)                        # (26c)
                    K1, b1 = mp.K_b(t1, q1)
                    r2 = K1.dot(v1) + b1                            # (26d), at t_{k+1}
                    return np.concatenate([r1, r2]), _saddle(bk, M, KQ.T, K1 + half * mp.k_q(t1, q1, v1))

                x, it = _newton(fun, x, bk, tol, max_iter, k, tk, counts)
                iters += it
                v1, lam = x[:n], x[n:]
                q = q + half * (v + v1)
                v = v1
                ts.append(t1)
                Qs.append(q)
                Vs.append(v)
                Ps.append([lam / h_])
                if progress is not None:
                    progress(k + 1, n_steps)
    st = {"steps": n_steps, "newton_iterations": iters, **counts, "n_grad_U": mp.n_grad_U,
          "mean_iterations": iters / max(n_steps, 1)}
    return _finish_solution(system, bk, ts, Qs, Vs, Ps, st, dps, name)


def integrate_comparator(name: str, system: LagrangianSystem, t0, q0, v0, h, n_steps: int,
                         dps: int | None = None, tol=None, max_iter: int = 50,
                         progress=None, max_stages: int | None = None) -> Solution:
    """Integrate with comparator ``name`` (see module docstring) at constant step h.

    Initial data must be consistent (k(t0, q0, v0) = 0). With ``dps`` the computation runs in
    mpmath (pass h as a string or mpf to keep full precision)."""
    if not isinstance(n_steps, int) or n_steps <= 0:
        raise InputError(f"n_steps must be a positive integer, got {n_steps!r}")
    bk = Backend(dps)
    with bk.context():       # the one initial-point check of every engine (ldaspark.core.validate)
        validate.initial_point(system, bk, t0, q0, v0, tol=tol)
    mt = re.fullmatch(r"gauss-irk-([1-9][0-9]*)", name)
    if mt:
        meth = GaussIRK(system, gauss(int(mt.group(1)), max_stages=max_stages), dps=dps, tol=tol, max_iter=max_iter)
        return _spark_variant_loop([(meth, 1)], system, t0, q0, v0, h, n_steps, name, progress)
    if name == "lobatto-iiia-iiib-2-modified":
        meth = ModifiedLobatto2(system, dps=dps, tol=tol, max_iter=max_iter)
        return _spark_variant_loop([(meth, 1)], system, t0, q0, v0, h, n_steps, name, progress)
    if name in ("euler-i-ii-composition", "euler-ii-i-composition"):
        first, second = (euler_i(), euler_ii()) if name == "euler-i-ii-composition" else (euler_ii(), euler_i())
        with bk.context():
            frac = bk.scalar(1) / 2
        objs = [(SparkMethod(system, first, dps=dps, tol=tol, max_iter=max_iter), frac),
                (SparkMethod(system, second, dps=dps, tol=tol, max_iter=max_iter), frac)]
        return _spark_variant_loop(objs, system, t0, q0, v0, h, n_steps, name, progress)
    if name == "lobatto-iiia-iiib-2-leapfrog":
        return _leapfrog(system, t0, q0, v0, h, n_steps, dps, tol, max_iter, "mean", name, progress)
    if name == "lobatto-iiia-iiib-2-modified-leapfrog":
        return _leapfrog(system, t0, q0, v0, h, n_steps, dps, tol, max_iter, "midpoint", name, progress)
    if name == "mp-lobatto-iiib-a-2":
        return _mp_iiib_a(system, t0, q0, v0, h, n_steps, dps, tol, max_iter, name, progress)
    raise InputError(f"unknown comparator {name!r}; choose from gauss-irk-S, {', '.join(FIXED_NAMES)}")


class ComparatorSafeRoot:
    """The guard's safe root for a comparator: its own step from the same state, started afresh
    (its default guess)."""

    def __init__(self, system, prob, opts):
        self.system, self.prob, self.opts = system, prob, opts

    def __call__(self, n, state, prev=None, before=None):
        t, q, v = state
        o = self.opts
        try:
            sol = integrate_comparator(self.prob.name, self.system, t, q, v, self.prob.h, 1, dps=o.dps, tol=o.tol,
                                       max_iter=o.newton.iterations, max_stages=o.max_stages)
        except LdasparkError:
            return None, None
        return "the comparator's own start", (np.asarray(sol.q[-1], float), np.asarray(sol.v[-1], float),
                                              float(sol.energy[-1]))
