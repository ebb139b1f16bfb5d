"""The step-acceptance guard: no step whose Newton iteration converged to another root of the
stage equations (21) is handed back as part of a solution.

Near the Newton limit (h of the order of the period of the fastest motion) the stage equations
(21a-f) can have several roots; a Newton iteration started from a poor guess may converge to
one far from the trajectory, with the constraint (1c) still satisfied to round-off: only the
energy (8) shows the jump. The guard runs on every engine (on by default, ``guard=False`` turns
it off):

1. **Which steps are suspect.** For a consistent step of an order-p method the energy change
   dE_n = E(t_{n+1}) - E(t_n) is the local error of the energy, C h^{p+1} with C varying
   smoothly along the trajectory (conservative systems), or h times the power of the
   nonconservative / rheonomic forces plus that error (the discrete energy balance (2.2)); in
   both cases consecutive steps change it by a factor 1 + O(h). The guard estimates what the
   local error can explain from the previous steps: r_n = max |dE_k| over the previous
   ``WINDOW`` steps (16 steps: more than half a period of an energy error oscillating with
   period >= 32 steps, so a zero crossing of dE never hides the scale), and flags step n when

       |dE_n| > SAFETY * r_n + ROUND_ULPS * eps * (1 + max(|E_n|, |E_{n+1}|))

   with SAFETY = 10 (the local error constant may not grow tenfold within 16 steps of a
   resolved trajectory; the rattleback's wrong root changed the energy 16.6x its value, 10^9 times
   the previous steps' changes) and the second term the round-off of evaluating E (1024 ulps:
   energy-preserving methods on quadratic energies change E only by round-off). Step 0 has no
   history and is not judged (it starts from the zero-increment predictor, the safe start
   below). On the generic engine a step whose Newton took more than ITER_FACTOR times the
   largest iteration count of the previous WINDOW steps plus ITER_EXTRA is flagged too.
2. **Re-solved from safe starts.** A flagged step is solved again by the generic engine's full
   Newton from the same state: from the previous step's collocation polynomial (the stage
   velocities V_i of the previous step interpolated at their nodes c_i and extrapolated to
   1 + c_i, the multipliers kept), then from the explicit Euler predictor (Q_i = q0 + c_i h v0:
   zero increments), then with the generic engine's default variant ("auto"). The first that
   converges gives the safe root.
3. **Verdict.** When the safe root and the engine's root agree to ROOT_AGREE (relative; both are
   converged to the Newton tolerance, ~1e-15, while distinct roots differ at O(1)) the energy
   change is real and the step stands. Otherwise the run stops at that step with status -4
   (``STATUS_GUARD``) and a message naming the step, the two roots and their energies; the
   trajectory ends at the state before the step. A run with a looser Newton tolerance tol than
   the default compares at max(ROOT_AGREE, ROOT_TOL_FACTOR tol) and counts energy changes below
   ENERGY_TOL_FACTOR tol (1 + |E|) as Newton's (``same_root``, ``flagged``).

The cost is one vectorised pass over the step energies (compiled engine) or a few float
operations per step (generic engine) when no step is flagged; docs/performance.md gives the
measured cost on the skate.
"""
from __future__ import annotations

import math
from collections import deque

import mpmath
import numpy as np

from .errors import LdasparkError
from .grid import steps_between

STATUS_GUARD = -4
#: previous steps whose energy changes estimate the local error
WINDOW = 16
#: how far beyond the previous steps' energy changes a step may go (see the module docstring)
SAFETY = 10.0
#: the round-off of evaluating the energy (8), in units of eps (1 + |E|)
ROUND_ULPS = 1024
#: a step whose Newton iterations exceed ITER_FACTOR * (the previous WINDOW steps' largest) +
#: ITER_EXTRA is flagged (generic engine)
ITER_FACTOR = 2
ITER_EXTRA = 2
#: two roots agree when max |q1 - q1'|, |v1 - v1'| <= ROOT_AGREE (1 + max |q1'|, |v1'|): both
#: converged to the Newton tolerance (10 eps relative), distinct roots differ at O(1); 1e-8 leaves
#: room for the conditioning of the stage equations near the Newton limit (cond ~ 1e6)
ROOT_AGREE = 1e-8
#: a user's Newton tolerance tol (``tol=``, ``Newton(tol=...)``) leaves each root, and the energy
#: (8) at each step, uncertain at ~tol relative instead of round-off: two roots agree within
#: max(ROOT_AGREE, ROOT_TOL_FACTOR tol) (tol = 1e-5 left differences of 2e-9..2e-6 on the
#: friction skate, which ROOT_AGREE called two roots), and an energy change within
#: ENERGY_TOL_FACTOR tol (1 + |E|) is Newton's, not a step's; distinct roots still differ at O(1)
#: for tol <= 1e-4
ROOT_TOL_FACTOR = 1e3
ENERGY_TOL_FACTOR = 10.0
_EPS = float(np.finfo(float).eps)
#: a run that kept every ``every``-th step is judged on its samples; a flagged interval is located
#: by running the prefix again with every step kept, when that prefix holds at most this many
#: floats (128 MB; beyond it the flagged intervals are counted as unverified)
EVERY_STEP_FLOATS = 2 ** 24
#: the longest first saved interval run again with every step kept (4096 steps: a few ms of a
#: kernel; a run that keeps only its end, every >= n_steps, is judged from its samples only)
HEAD = 4096
#: flagged steps solved again per run; beyond it they are counted as unverified
MAX_RESOLVES = 1000


class RootMismatchError(LdasparkError):
    """The step-acceptance guard found two roots of the stage equations (21) at one step: the
    engine's and the one from a safe start. Names the step, its time, both roots and energies."""

    def __init__(self, message, step=None, time=None):
        super().__init__(message)
        self.step = step
        self.time = time


def _floor_rel(tol) -> float:
    """The relative size of an energy change that is noise: the round-off of evaluating E, or the
    Newton tolerance's share (ENERGY_TOL_FACTOR tol) when the user loosened it."""
    return max(ROUND_ULPS * _EPS, ENERGY_TOL_FACTOR * float(tol)) if tol is not None else ROUND_ULPS * _EPS


def _round(E0, E1, tol=None):
    return _floor_rel(tol) * (1.0 + max(abs(E0), abs(E1)))


def flagged(E, tol=None) -> np.ndarray:
    """The steps n >= 1 whose energy change E[n + 1] - E[n] exceeds the threshold of the module
    docstring (E: the energy (8) at every step point, float64; tol: the run's Newton tolerance,
    None for the default). Vectorised: O(N WINDOW)."""
    E = np.asarray(E, dtype=float)
    if len(E) < 3:
        return np.zeros(0, dtype=int)
    a = np.abs(E[1:] - E[:-1])            # np.diff's numbers, without its generality (a short run's cost)
    absE = np.abs(E)
    floor = _floor_rel(tol) * (1.0 + np.maximum(absE[:-1], absE[1:]))
    # the previous step alone bounds the window's maximum from below: only the steps beyond
    # SAFETY times their predecessor's change can be flagged (a few in a run; the window's
    # maximum is taken for those only)
    cand = (a[1:] > SAFETY * a[:-1] + floor[1:]).nonzero()[0] + 1
    if not len(cand):
        return np.zeros(0, dtype=int)
    bad = [n for n in cand if a[n] > SAFETY * a[max(0, n - WINDOW):n].max() + floor[n]]
    return np.asarray(bad, dtype=int)


class StepGuard:
    """The guard's test one step at a time (generic engine): ``suspect(n, E0, E1, iterations)``
    says whether step n is flagged; ``accept(E0, E1, iterations)`` enters the step into the
    history. The same threshold as ``flagged``."""

    def __init__(self, tol=None):
        self.dE = deque(maxlen=WINDOW)
        self.its = deque(maxlen=WINDOW)
        self.tol = tol

    def suspect(self, n, E0, E1, iterations=None) -> bool:
        if n == 0 or not self.dE:
            return False
        d = abs(E1 - E0)
        if d > SAFETY * max(self.dE) + _round(E0, E1, self.tol):
            return True
        return iterations is not None and len(self.its) > 0 and \
            iterations > ITER_FACTOR * max(self.its) + ITER_EXTRA

    def accept(self, E0, E1, iterations=None):
        self.dE.append(abs(E1 - E0))
        if iterations is not None:
            self.its.append(iterations)


def _extrapolated_start(method, prev, v):
    """The packed unknowns from the previous step's collocation polynomial: ``prev`` = (V (s, n),
    Psi (s, m), h) of the previous step, ``v`` the velocity at its end. The velocity polynomial
    through (c_i, V_i) and (1, v) (nodes in units of h from the previous step's start) is
    evaluated at 1 + c_i (the new stages) and at 2 (the new end point); Lambda = h Psi kept."""
    V, Psi, h = prev
    c = np.asarray([float(x) for x in method.tab.c])
    nodes, vals = [], []
    for ci, Vi in zip(c, np.asarray(V, dtype=float)):
        if all(abs(ci - x) > 1e-12 for x in nodes):
            nodes.append(ci)
            vals.append(Vi)
    if all(abs(1.0 - x) > 1e-12 for x in nodes):
        nodes.append(1.0)
        vals.append(np.asarray(v, dtype=float))
    nodes, vals = np.asarray(nodes), np.asarray(vals)

    def at(tau):
        w = np.ones(len(nodes))
        for j in range(len(nodes)):
            for k in range(len(nodes)):
                if k != j:
                    w[j] *= (tau - nodes[k]) / (nodes[j] - nodes[k])
        return w.dot(vals)
    Vn = np.array([at(1.0 + ci) for ci in c])
    return method.pack(Vn, np.asarray(Psi, dtype=float) * float(h), at(2.0))


def safe_root(methods, t, q, v, h, prev=None, step_index=0):
    """(label, StepResult) of the first safe start that converges, or (None, None): ``methods``
    = (full-Newton SparkMethod, default-variant SparkMethod); ``prev`` as ``_extrapolated_start``."""
    full, auto = methods
    tries = []
    if prev is not None:
        try:
            tries.append(("the previous step's collocation polynomial", full, _extrapolated_start(full, prev, v)))
        except (ValueError, FloatingPointError):
            pass
    tries.append(("the explicit Euler predictor", full, None))
    tries.append(("the generic engine's step", auto, None))
    for label, meth, x0 in tries:
        if x0 is not None:
            x0 = meth.backend.array(x0)      # the working number type (mpmath at dps)
        try:
            return label, meth.step(t, q, v, h, x0=x0, step_index=step_index)
        except LdasparkError:
            continue
    return None, None


def same_root(q1, v1, q1s, v1s, tol=None) -> bool:
    """Whether (q1, v1) and (q1s, v1s) are one root: within ROOT_AGREE, or ROOT_TOL_FACTOR times
    the run's Newton tolerance ``tol`` when that is larger (None: the default tolerance)."""
    agree = ROOT_AGREE if tol is None else max(ROOT_AGREE, ROOT_TOL_FACTOR * float(tol))
    if _is_mp(q1, v1, q1s, v1s):
        # in the run's numbers: rounded to float64, two equal roots beyond its range (euler-i,
        # h = 1e300 at 30 digits: q1 = -2.1e559) were inf - inf = NaN apart, "two roots", status -4
        a = [mpmath.mpf(e) for x in (q1, v1) for e in np.asarray(x).reshape(-1)]
        b = [mpmath.mpf(e) for x in (q1s, v1s) for e in np.asarray(x).reshape(-1)]
        scale = 1 + max((abs(e) for e in b), default=mpmath.mpf(0))
        diff = max((abs(x - y) for x, y in zip(a, b)), default=mpmath.mpf(0))
        return bool(mpmath.isfinite(diff)) and diff <= agree * scale
    q1, v1, q1s, v1s = (np.asarray(x, dtype=float) for x in (q1, v1, q1s, v1s))
    scale = 1.0 + max(float(np.max(np.abs(q1s), initial=0.0)), float(np.max(np.abs(v1s), initial=0.0)))
    diff = max(float(np.max(np.abs(q1 - q1s), initial=0.0)), float(np.max(np.abs(v1 - v1s), initial=0.0)))
    return math.isfinite(diff) and diff <= agree * scale


def _is_mp(*arrays) -> bool:
    """Whether any entry is an mpf (a run at dps digits)."""
    return any(isinstance(e, mpmath.mpf) for a in arrays for e in np.asarray(a, dtype=object).reshape(-1))


def _fmt(a) -> str:
    if _is_mp(a):      # mpf beyond float64's range printed as inf before
        return "[" + " ".join(mpmath.nstr(mpmath.mpf(e), 11) for e in np.asarray(a).reshape(-1)) + "]"
    return np.array2string(np.asarray(a, dtype=float), precision=10, max_line_width=10 ** 6)


def _fmt_energy(E) -> str:
    return mpmath.nstr(E, 10) if isinstance(E, mpmath.mpf) else f"{float(E):.10g}"


def mismatch(n, t, h, engine_root, safe, label) -> RootMismatchError:
    """The error that stops the run: step n from time t, the engine's root (q1, v1, E1) and the
    safe root (q1', v1', E1') found from ``label``."""
    (q1, v1, E1), (q1s, v1s, E1s) = engine_root, safe
    return RootMismatchError(
        f"step {n} (t = {float(t):.6g} -> {float(t) + float(h):.6g}): the step-acceptance guard found two roots "
        f"of the stage equations (21): the engine's q1 = {_fmt(q1)}, v1 = {_fmt(v1)} with energy (8) "
        f"E = {_fmt_energy(E1)}, and from {label} q1 = {_fmt(q1s)}, v1 = {_fmt(v1s)} with E = {_fmt_energy(E1s)}; "
        "the step is beyond the Newton limit of this h (reduce h, or guard=False to keep the engine's root)",
        step=n, time=float(t))


class SparkSafeRoot:
    """``resolve(n, state, prev, before)`` for a SPARK tableau: the safe starts of ``safe_root``
    with generic full / default Newton at ``dps`` digits (None: float64); the method objects are
    built at the first flagged step. ``before`` = (t, q, v) at the start of step n - 1: a block
    engine keeps no stages, so the previous step is solved again to extrapolate from."""

    def __init__(self, system, tableau, dps, tol, max_iter, h):
        self.args = (system, tableau, dps, tol, max_iter)
        self.h = h
        self.methods = None

    def _methods(self):
        if self.methods is None:
            from .spark import SparkMethod
            system, tableau, dps, tol, max_iter = self.args
            mk = lambda kind: SparkMethod(system, tableau, dps=dps, tol=tol, newton=kind,  # noqa: E731
                                          max_iter=max_iter)
            self.methods = (mk("full"), mk("auto"))
        return self.methods

    def __call__(self, n, state, prev=None, before=None):
        methods = self._methods()
        t, q, v = state
        if prev is None and before is not None and n >= 1:
            try:
                r = methods[0].step(before[0], before[1], before[2], self.h, step_index=n - 1)
                prev = (r.V, r.Psi, self.h)
            except LdasparkError:
                prev = None
        label, r = safe_root(methods, t, q, v, self.h, prev, step_index=int(n))
        # the energy in the run's numbers (an mpf at dps may lie beyond float64's range)
        if r is None:
            return None, None
        return label, (r.q1, r.v1, r.energy if _is_mp([r.energy]) else float(r.energy))


def counters() -> dict:
    """The guard's counters of a run, all zero (``Result.stats``)."""
    return {"guard": True, "guard_flagged": 0, "guard_confirmed": 0, "guard_unverified": 0}


def judge(samples, every, h, resolve, rerun=None, floats_per_step=0, tol=None):
    """The guard on a run kept every ``every``-th step (a block engine, an ensemble member):
    (its counters, None) or (its counters, (n, RootMismatchError, steps)) for the first step n with
    another root, ``steps`` holding every step up to at least n + 1.

    samples: t, q, v, energy (float64 arrays; every = 1: every step). resolve(n, (t, q, v),
    before): (label, (q1, v1, E1)) of step n from a safe start (``SparkSafeRoot``), or (None, None).
    rerun(n): the first n steps again with every step kept (t, q, v, energy), for every > 1; None:
    the samples hold every step. floats_per_step bounds what a rerun may hold (EVERY_STEP_FLOATS).
    Without a flagged sample (and, for every > 1, a first interval longer than HEAD) nothing is run
    again: the guard costs one vectorised pass over the saved energies. tol: the run's Newton
    tolerance (``flagged``, ``same_root``), None for the default."""
    st = counters()
    if len(samples.t) < 3:
        return st, None
    bad = flagged(np.asarray(samples.energy, dtype=float), tol)
    every = 1 if rerun is None else int(every)
    # the first saved interval has no history among the samples: its steps are judged on a
    # rerun with every step kept when it is short (HEAD steps), else left unjudged
    head = 1 < every <= HEAD
    if not len(bad) and not head:
        return st, None
    steps = samples
    if every > 1:       # locate: the prefix to the end of the last flagged interval, every step
        t = np.asarray(samples.t, dtype=float)
        j = bad[-1] + 1 if len(bad) else 1
        last = steps_between(samples.t[0], samples.t[min(j, len(t) - 1)], h)
        if (last + 1) * floats_per_step > EVERY_STEP_FLOATS:
            st["guard_flagged"] = st["guard_unverified"] = int(len(bad))
            return st, None
        try:
            steps = rerun(last)
        except LdasparkError:
            st["guard_flagged"] = st["guard_unverified"] = int(len(bad))
            return st, None
        bad = flagged(np.asarray(steps.energy, dtype=float), tol)
    st["guard_flagged"] = int(len(bad))
    t, q, v, E = (np.asarray(getattr(steps, a), dtype=float) for a in ("t", "q", "v", "energy"))
    for count, n in enumerate(bad):
        if count >= MAX_RESOLVES:
            st["guard_unverified"] += len(bad) - count
            break
        before = (t[n - 1], q[n - 1], v[n - 1]) if n >= 1 else None
        label, safe = resolve(int(n), (t[n], q[n], v[n]), before)
        if safe is None:
            st["guard_unverified"] += 1
        elif same_root(q[n + 1], v[n + 1], safe[0], safe[1], tol):
            st["guard_confirmed"] += 1
        else:
            return st, (int(n), mismatch(int(n), t[n], h, (q[n + 1], v[n + 1], E[n + 1]), safe, label), steps)
    return st, None
