"""Dense output (continuous extensions) and event location.

``CollocationDense``, the dense output of every SPARK run (generic or compiled engine, float64 or
mpmath): on the step n from t_n to t_n+1 = t_n + h, with theta = (t - t_n) / h in [0, 1], the
polynomial p(theta) = sum_j l_j(theta) V_j through the stage velocities (c_j, V_j) (Lagrange
basis l_j on the distinct nodes c_j) corrected to the grid:

    v(t) = p(theta) + e(theta),    q(t) = q_n + h int_0^theta v,

e the quadratic with v(t_n) = v_n, v(t_n+1) = v_n+1 and q(t_n+1) = q_n+1 (e(0) = v_n - p(0),
e(1) = v_n+1 - p(1), int_0^1 e = (q_n+1 - q_n) / h - int_0^1 p). The saved grid values are
reproduced (to a few ulps; exactly at the start of a step), and the mismatches that e absorbs are
O(h^stage order), so the order of p is not lowered. Without e the polynomial missed the grid
(lobatto-iiia-iiib-2: v(0) = [-0.0101, 0.45] for v_0 = [0, 0.5] on the pendulum at h = 0.1).
For s <= 3 stages v is a quadratic, so the corrected polynomial is the cubic Hermite interpolant
of (q_n, v_n), (q_n+1, v_n+1); from s = 4 on the stages carry what the grid alone does not (a
high-degree Hermite of the grid alone was tried and rejected: gauss-8 at h = 1.5 on the skate, q
off by 7e-2).

The generic engine has the V_j of each step; the compiled engine keeps none and solves each
step again from its saved (t_n, q_n, v_n) (``compiled.runner.StageSolver``: the SPARK kernel for
one step, full Newton; the generic step where it fails), so the V_j agree with the run's to the
Newton tolerance and both engines' dense outputs agree to ~1e-12 (lobatto-iiia-iiib-2, which the
compiled engine runs with the semi-implicit kernel (25), too: the same method (21)). A step whose
stages cannot be recomputed to the saved end has V = 0: the cubic Hermite of its ends. Dense
output solves a step when it is first evaluated (``CollocationDense(..., stage_fn=...)``; a
pickled copy carries every step's stages); events only the steps where an event changes sign.

Measured orders of the maximal error over [0, 2] on the skate (exact solution, h = 0.2, 0.1, 0.05,
both engines alike; ``tests/api/test_dense_events.py``), before the correction (the generic
engine's uncorrected p) in brackets:

    method                 nodal   q(t)     v(t)
    gauss-2                  4     4 (3)    3 (2)
    gauss-3                  6     4 (4)    3 (3)
    gauss-4                  8     5 (5)    4 (4)
    lobatto-iiia-iiib-2      2     2 (2)    2 (1)
    lobatto-iiia-iiib-3      4     4 (3)    3 (2)

Large steps on the skate over [0, 60] (max error against compiled gauss-6, h = 0.01): gauss-6 at
h = 1.0 q 5.4e-6, v 4.0e-5; gauss-8 at h = 1.5 q 8.8e-7, v 6.1e-6 (the uncorrected p: 1.1e-6 /
4.7e-5 and 1.4e-7 / 6.2e-6, not at the grid; the cubic Hermite the compiled engine had: 9.7e-3 /
3.0e-2 and 4.5e-2 / 9.3e-2). The correction of v at the ends moves q inside the step by
h int e = O(h^(s+1)), the order of p's own q error, with a larger constant at these steps.

``HermiteDense``: the comparators (no SPARK stages, every engine): the cubic Hermite interpolant of
(t_n, q_n, v_n) and (t_n+1, q_n+1, v_n+1) for q and its derivative for v.

``CollocationDense(..., v_nodes=None)``: the uncorrected p, for files written before the
correction (``resultio``: they stored no grid velocities with the stages).

Both are evaluated in float64 (also after an mpmath run) on increasing (h > 0) or decreasing
(h < 0) grids.

Events: functions g(t, q, v) -> float with optional attributes ``terminal`` (bool) and
``direction`` (sign of the crossing: > 0 upward only, < 0 downward only, 0 both), as in
``scipy.integrate.solve_ivp``: the direction is along the integration (with h < 0, "upward" is
g increasing as t decreases), and the crossings come in the run's order. A sign change of g
between two consecutive steps is located by ``scipy.optimize.brentq`` on g(t, sol(t)) inside
that step.
"""
from __future__ import annotations

from typing import Any, Callable, Sequence, Union

import numpy as np

from .errors import InputError


def _lagrange_weights(nodes: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """W[k, j] = l_j(theta_k), the Lagrange basis on ``nodes`` (a handful of points in [0, 1])."""
    th = np.asarray(theta, float)[:, None]
    W = np.ones((th.shape[0], len(nodes)))
    for j, xj in enumerate(nodes):
        for i, xi in enumerate(nodes):
            if i != j:
                W[:, j] *= (th[:, 0] - xi) / (xj - xi)
    return W


class _Dense:
    """Piecewise interpolant on the step grid ``t`` (N + 1 points, increasing for h > 0 or
    decreasing for h < 0)."""

    def __init__(self, t: np.ndarray):
        self.t = np.asarray(t, float)
        d = np.diff(self.t)
        if len(self.t) < 2 or not (np.all(d > 0) or np.all(d < 0)):
            raise InputError("dense output needs at least one step and strictly monotone times (increasing for "
                             "h > 0, decreasing for h < 0)")
        #: +1 on an increasing grid (h > 0), -1 on a decreasing one (h < 0)
        self.direction = 1.0 if d[0] > 0 else -1.0

    @property
    def t_min(self) -> float:
        return float(min(self.t[0], self.t[-1]))

    @property
    def t_max(self) -> float:
        return float(max(self.t[0], self.t[-1]))

    def _locate(self, t):
        from .validate import times
        tt = np.atleast_1d(times(t))
        lo, hi = self.t_min, self.t_max
        span = hi - lo
        if np.any(tt < lo - 1e-12 * span) or np.any(tt > hi + 1e-12 * span):
            raise InputError(f"dense output is defined on [{lo:g}, {hi:g}], got t outside it")
        s = self.direction           # s t is increasing: the step holding t, from the run's start
        k = np.clip(np.searchsorted(s * self.t, s * tt, side="right") - 1, 0, len(self.t) - 2)
        h = self.t[k + 1] - self.t[k]
        return tt, k, (tt - self.t[k]) / h, h

    def __call__(self, t: Any) -> tuple:
        """(q, v) at t: arrays (n,) for a scalar t, (len(t), n) for an array."""
        tt, k, theta, h = self._locate(t)
        q, v = self._eval(k, theta, h)
        if np.ndim(t) == 0:
            return q[0], v[0]
        return q, v


def _distinct_nodes(c) -> list:
    """Indices of the distinct nodes of ``c`` (the first of equal ones)."""
    c = np.asarray(c, float)
    return [i for i in range(len(c)) if all(abs(c[i] - c[j]) > 1e-14 for j in range(i))]


class CollocationDense(_Dense):
    """The stage polynomial of a SPARK method corrected to the grid (see module docstring).

    t (N+1,), q_nodes (N+1, n); c (s,) the tableau's nodes; V (N, s, n) stage velocities;
    v_nodes (N+1, n) the saved velocities. With theta = (t - t_n) / h in [0, 1], l_j the Lagrange
    basis on the distinct nodes c_j and p(theta) = sum_j l_j(theta) V_j:
    v(t) = p(theta) + e(theta), q(t) = q_n + h int_0^theta v, where the quadratic e makes
    v(t_n) = v_n, v(t_n+1) = v_n+1 and q(t_n+1) = q_n+1. A step whose V are all zero (its stages
    could not be recomputed) is the cubic Hermite interpolant of the grid.

    ``v_nodes=None`` is the uncorrected polynomial p (files written before the correction, which
    stored no velocities with the stages): for a collocation A (Gauss, Lobatto IIIA) q is then the
    collocation polynomial through (t_n, q_n) and the stage points (T_i, Q_i) of (21a)."""

    def __init__(self, t, q_nodes, c, V, v_nodes=None, stage_fn=None):
        super().__init__(t)
        keep = _distinct_nodes(c)
        self.c = np.asarray(c, float)[keep]
        self.q = np.asarray(q_nodes, float)
        self.v = None if v_nodes is None else np.asarray(v_nodes, float)
        # V None with ``stage_fn(i)`` (the stage velocities of step i, None where they cannot be
        # recomputed): solved when a step is first evaluated, not for every step up front (the
        # compiled engine's one-step solve costs ~100 us a step, 25x the run itself)
        self._keep = keep
        if V is None:
            self._V = np.zeros((len(self.t) - 1, len(keep), self.q.shape[1]))
            self._have = np.zeros(len(self.t) - 1, dtype=bool)
            self._stage_fn = stage_fn
        else:
            self._V = np.asarray(V, float)[:, keep, :]
            self._have, self._stage_fn = None, None
        P = np.polynomial.polynomial
        self._basis = []
        for j, cj in enumerate(self.c):
            others = np.delete(self.c, j)
            lj = P.polyfromroots(others) / np.prod(cj - others) if len(others) else np.array([1.0])
            self._basis.append((lj, P.polyint(lj)))
        # per basis polynomial: l_j(0), l_j(1), int_0^1 l_j
        self._ends = np.array([[P.polyval(0.0, lj), P.polyval(1.0, lj), P.polyval(1.0, ij)]
                               for lj, ij in self._basis])

    def _solve_steps(self, ks) -> None:
        if self._have is None:
            return
        for i in np.unique(np.asarray(ks, dtype=int)):
            if not self._have[i]:
                Vi = self._stage_fn(int(i))
                if Vi is not None:       # else zeros: this step is the cubic Hermite of the grid
                    self._V[i] = np.asarray(Vi, float)[self._keep]
                self._have[i] = True

    @property
    def V(self) -> np.ndarray:
        """The stage velocities (N, s, n) of every step (solved now where they were not yet)."""
        self._solve_steps(range(len(self.t) - 1))
        return self._V

    @V.setter
    def V(self, value) -> None:
        self._V = np.asarray(value, float)
        self._have = self._stage_fn = None

    def __getstate__(self):
        # a pickled or saved copy carries every step's stages, not the solver
        self._solve_steps(range(len(self.t) - 1))
        state = dict(self.__dict__)
        state["_have"] = state["_stage_fn"] = None
        return state

    def _eval(self, k, theta, h):
        P = np.polynomial.polynomial
        self._solve_steps(k)
        L = np.stack([P.polyval(theta, lj) for lj, _ in self._basis], axis=1)        # (K, s)
        B = np.stack([P.polyval(theta, ij) for _, ij in self._basis], axis=1)
        V = self._V[k]                                                                  # (K, s, n)
        if self.v is None:
            v = np.einsum("kj,kjn->kn", L, V)
            q = self.q[k] + h[:, None] * np.einsum("kj,kjn->kn", B, V)
            return q, v
        th = theta[:, None]
        l0, l1 = self._ends[:, 0][None, :], self._ends[:, 1][None, :]
        # p minus its chord, and its integral: zero at theta = 0 and (the chord's) at theta = 1
        A0, A1 = th - th ** 2 / 2, th ** 2 / 2                   # int_0^theta (1 - x), int_0^theta x
        w = L - (1 - th) * l0 - th * l1
        W = B - A0 * l0 - A1 * l1
        v0, v1 = self.v[k], self.v[k + 1]
        # the correction e = a (1 - theta) + b theta + g 6 theta (1 - theta) with a = v_n - p(0),
        # b = v_n+1 - p(1) and int_0^1 e = (q_n+1 - q_n) / h - int_0^1 p, so that
        # g = (q_n+1 - q_n) / h - (v_n + v_n+1) / 2 - int_0^1 (p - chord of p)
        wbar = self._ends[:, 2] - 0.5 * (self._ends[:, 0] + self._ends[:, 1])
        g = (self.q[k + 1] - self.q[k]) / h[:, None] - 0.5 * (v0 + v1) - np.einsum("j,kjn->kn", wbar, V)
        v = np.einsum("kj,kjn->kn", w, V) + (1 - th) * v0 + th * v1 + 6 * th * (1 - th) * g
        q = self.q[k] + h[:, None] * (np.einsum("kj,kjn->kn", W, V) + A0 * v0 + A1 * v1
                                      + (3 * th ** 2 - 2 * th ** 3) * g)
        return q, v


class HermiteDense(_Dense):
    """Cubic Hermite interpolant of the nodal (q, v) (see module docstring)."""

    def __init__(self, t, q, v):
        super().__init__(t)
        self.q = np.asarray(q, float)
        self.v = np.asarray(v, float)

    def _eval(self, k, theta, h):
        th = theta[:, None]
        hh = h[:, None]
        q0, q1, v0, v1 = self.q[k], self.q[k + 1], self.v[k], self.v[k + 1]
        h00, h10 = 2 * th ** 3 - 3 * th ** 2 + 1, th ** 3 - 2 * th ** 2 + th
        h01, h11 = -2 * th ** 3 + 3 * th ** 2, th ** 3 - th ** 2
        q = h00 * q0 + h10 * hh * v0 + h01 * q1 + h11 * hh * v1
        d00, d10, d01, d11 = 6 * th ** 2 - 6 * th, 3 * th ** 2 - 4 * th + 1, -6 * th ** 2 + 6 * th, 3 * th ** 2 - 2 * th
        v = (d00 * q0 + d01 * q1) / hh + d10 * v0 + d11 * v1
        return q, v


class Event:
    """A checked event function: ``g(t, q, v)`` with ``terminal`` (bool) and ``direction`` (a
    finite real number) read once, here. g gets copies of q and v (an event that
    modifies its argument cannot change the trajectory) and must return a real number."""

    def __init__(self, g: Callable, index: int):
        from .validate import _describe, _is_bool
        if not callable(g):
            raise InputError(f"event {index} must be a callable g(t, q, v), got {_describe(g)}")
        self.g, self.index = g, index
        term = getattr(g, "terminal", False)
        if not (_is_bool(term) or (isinstance(term, (int, np.integer)) and term in (0, 1))):
            raise InputError(f"event {index}: terminal must be True or False, got {_describe(term)}")
        self.terminal = bool(term)
        d = getattr(g, "direction", 0)
        if not isinstance(d, (int, float, np.integer, np.floating, np.ndarray, str, bytes)) and not _is_bool(d):
            from .validate import real_value
            try:                # an mpf, Fraction or Decimal direction is a real number too
                d = real_value(d, f"event {index}: direction")
            except InputError:
                pass            # refused below, in the words of the other types
        if _is_bool(d) or not isinstance(d, (int, float, np.integer, np.floating)) or not np.isfinite(d):
            raise InputError(f"event {index}: direction must be a finite real number (> 0 upward, < 0 "
                             f"downward, 0 both), got {_describe(d)}")
        self.direction = float(d)

    def __call__(self, t, q, v) -> float:
        from .validate import _describe
        qc, vc = np.array(q, dtype=float), np.array(v, dtype=float)    # copies: g may modify them
        try:
            val = self.g(float(t), qc, vc)
        except Exception as exc:    # the user's code: its error named in one line, the original kept as __cause__
            raise InputError(f"event {self.index} raised {type(exc).__name__} at t = {float(t):g}: "
                             f"{' '.join(str(exc).split())[:120]}") from exc
        from .validate import real_value
        # an mpf, Fraction or Decimal is a real number too (an event computed at dps returns mpf)
        if isinstance(val, np.ndarray) and val.shape != ():
            raise InputError(f"event {self.index} must return a real number, got {_describe(val)}")
        try:
            val = real_value(val, f"event {self.index} return value")
        except InputError as exc:
            if "finite" in str(exc):
                raise InputError(f"event {self.index} returned NaN or infinity at t = {float(t):g}") from None
            raise InputError(f"event {self.index} must return a real number, got {_describe(val)}") from None
        return val


def check_events(events: Union[None, Callable, Sequence[Callable]]) -> list:
    """Normalise ``events`` (None, one callable, or a sequence of callables) to a list of
    ``Event``: validated once here for every engine."""
    from .validate import _describe
    if events is None:
        return []
    if callable(events):
        evs = [events]
    elif isinstance(events, (list, tuple)):
        evs = list(events)
    else:
        raise InputError(f"events must be a callable g(t, q, v) or a list of them, got {_describe(events)}")
    return [g if isinstance(g, Event) else Event(g, i) for i, g in enumerate(evs)]


def _crossed(g0: float, g1: float, direction: float) -> bool:
    if g0 == 0 or np.sign(g0) == np.sign(g1):
        return False
    up = g1 > g0
    return direction == 0 or (direction > 0 and up) or (direction < 0 and not up)


class EventTracker:
    """Watches g_e(t, q, v) at the step points; ``after_step`` locates crossings in a step."""

    def __init__(self, events: Sequence[Callable], t0, q0, v0):
        self.events = check_events(list(events))
        self.found = [[] for _ in self.events]
        self.n = len(float_vec(q0))
        self.g = [g(t0, float_vec(q0), float_vec(v0)) for g in self.events]

    def after_step(self, t0: Any, t1: Any, q1: Any, v1: Any, piece: Callable) -> bool:
        """Check the step [t0, t1] (end state q1, v1, local dense output ``piece``);
        returns True when a terminal event occurred in it."""
        from scipy.optimize import brentq
        stop = False
        q1f, v1f = float_vec(q1), float_vec(v1)
        for e, g in enumerate(self.events):
            g1 = g(t1, q1f, v1f)
            if _crossed(self.g[e], g1, g.direction):
                fn = lambda tt, g=g: g(tt, *piece(tt))
                a, b = float(t0), float(t1)      # a > b on a decreasing grid (h < 0)
                ga, gb = fn(a), fn(b)
                if ga == 0:
                    te = a
                elif gb == 0 or np.sign(ga) == np.sign(gb):
                    te = b   # the interpolant disagrees in sign with the nodes only at round-off level
                else:
                    lo, hi = min(a, b), max(a, b)
                    te = brentq(fn, lo, hi, xtol=4 * np.finfo(float).eps * max(1.0, abs(lo), abs(hi)),
                                rtol=4 * np.finfo(float).eps)
                qe, ve = piece(te)
                self.found[e].append((te, np.asarray(qe, float), np.asarray(ve, float)))
                stop = stop or g.terminal
            self.g[e] = g1
        return stop

    def arrays(self) -> tuple:
        """(t_events, q_events, v_events): one array per event function."""
        te = [np.array([x[0] for x in f], float) for f in self.found]
        # (0, n) when an event never fired (reshape(0, -1) is ambiguous for an empty array)
        qe = [np.array([x[1] for x in f], float).reshape(len(f), self.n) for f in self.found]
        ve = [np.array([x[2] for x in f], float).reshape(len(f), self.n) for f in self.found]
        return te, qe, ve


def float_vec(x) -> np.ndarray:
    """float64 copy of a state vector (float64 or mpmath numbers)."""
    a = np.asarray(x)
    if a.dtype == object:
        return np.array([float(e) for e in a.reshape(-1)], float).reshape(a.shape)
    return a.astype(float)


def step_piece(t0: Any, h: Any, start: tuple, end: tuple, c: Any, V: Any, t1: Any = None) -> CollocationDense:
    """Dense output of one step from its stage velocities V (s, n) and its ends ``start`` =
    (q_n, v_n), ``end`` = (q_n+1, v_n+1) (used while stepping, for events; None for V: the cubic
    Hermite interpolant). ``t1``: the step's end on the run's grid t0 + (n + 1) h, where the event
    search evaluates it; t_n + h can miss it by an ulp of t, more than the piece's slack at large
    t (None: t_n + h)."""
    t0f = float(t0)
    t = np.array([t0f, t0f + float(h) if t1 is None else float(t1)])
    q = np.array([float_vec(start[0]), float_vec(end[0])])
    v = np.array([float_vec(start[1]), float_vec(end[1])])
    if V is None:
        return HermiteDense(t, q, v)
    return CollocationDense(t, q, c, float_vec(V)[None], v)
