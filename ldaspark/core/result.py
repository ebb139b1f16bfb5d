"""One result type for every engine (generic float64 / mpmath, compiled, comparators) and for
ensembles (a leading batch axis).

Shapes for one run with S saved points (S = N + 1 for ``save_every = 1``):

* ``t`` (S,), ``q`` and ``v`` (S, n), ``energy`` (S,) = E of (8), ``constraint`` (S, m) = k(t, q, v)
  of (1c), ``psi`` (S - 1, s, m): the stage multipliers Psi_i of (21b) of the step starting at
  ``t[j]``, on the generic, mpmath and compiled engines alike (``None`` only where the method does
  not form stage multipliers: the semi-implicit kernel of (25), which runs lobatto-iiia-iiib-2 and
  the semi-implicit comparators of (25), 8.4 and (26) on mechanical systems on the compiled
  engine). The comparators of sections 7-8 on the generic
  engine give the multipliers of their own stage equations in the same layout (the Gauss IRK's
  and 8.4's stage multipliers, a composition's two sub-steps' side by side, and the leapfrog
  forms' those of the Lobatto IIIA-B method they equal; (S - 1, 1, m) for mp-lobatto-iiib-a-2),
  not those of (21) for their own tableau. Sign: psi is the multiplier of
  (1), d/dt grad_v L = grad_q L - K^T psi; sympy.physics.mechanics' ``LagrangesMethod`` writes the
  same equations with +K^T lam, so for the same constraint expressions psi = -lam.
* ``status``: 0 success, 1 a terminal event stopped the run, negative failure (scipy's
  convention): -1 the Newton iteration of (21) failed, -2 the saddle matrix (4) became singular
  or changed sign, -3 another step failure (non-finite values), -4 the step-acceptance guard
  found another root of (21) at a step (``ldaspark.core.guard``). On failure the arrays hold the
  trajectory up to the last good step and ``message`` says why.
* ``stats``: the engine's counters, and what ran: ``engine``, ``root_finder`` (the fields of
  ``ldaspark.Newton``), the rescues (``full_newton_steps``, ``rescued_steps`` on the compiled
  engine) and the guard's ``guard_flagged`` / ``guard_confirmed`` / ``guard_unverified``.
* counters ``nfev`` (the stage points of the residual evaluations, s + 1 each for (21) and the
  Gauss IRK, s + 2 for the modified method of 8.4 with its midpoint; the semi-implicit forms of
  (25), 8.4 and (26) count the evaluations of their multiplier solve, which are not the same on
  the generic and compiled engines; the model's derivatives for a Jacobian are ``njev``'s), ``njev`` (Jacobian assemblies), ``nlu`` (LU
  factorisations), ``newton_iterations``. One meaning on every engine and path, success or
  failure: each counts the work of every step the run attempted, the failed step included, with
  every retry of a step (the compiled kernels' fallback chain, the generic step that rescues a
  kernel step); ``stats["steps"]`` is the number of accepted steps (the rows of the trajectory
  up to its last good point). A block engine's rerun of the prefix of a failed block repeats
  steps already counted and is not counted again, nor are the diagnoses of a failure
  (``Engine.explain``), the guard's re-solves and the stage re-solves of a block engine's dense
  output and events. Where the counts differ by engine for the same run: the compiled chain may
  try a step more ways than the generic engine (more work counted for the same step; see
  ``compiled.rescue``), and a block engine has run its whole block when a monitor (det (4), the
  guard, ``energy_jump``) or a terminal event cuts the run, so it counts the steps after the cut
  too (``steps`` still counts the accepted ones).
* ``sol``: the dense output (``ldaspark.core.dense``) when asked for, ``sol(t) -> (q, v)``.
* ``t_events`` / ``q_events`` / ``v_events``: one array per event function.
* ``coordinate_names``: the names of the coordinates (columns of q and v), or None.

An ensemble (``batch`` = B) has arrays with a leading axis B, ``status`` an int array (B,),
``message`` a list, counters arrays (B,), ``n_valid`` (B,) the number of valid rows of each
member (rows after a failure repeat the last good state; nothing is NaN) and ``members`` the
individual Results.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Optional

import numpy as np

from .errors import InputError, LdasparkError

STATUS_SUCCESS = 0
STATUS_EVENT = 1
STATUS_NEWTON = -1
STATUS_SADDLE = -2
STATUS_OTHER = -3
STATUS_GUARD = -4

#: the message of a run that reached t_end (every engine)
MSG_DONE = "The integration reached t_end."

COUNTERS = ("nfev", "njev", "nlu", "newton_iterations")
#: the counters a step failure carries to the driver (``failure_counters``): the work of the
#: failed call up to and including its failed step, and its accepted steps
FAILURE_COUNTERS = ("steps",) + COUNTERS
#: the leading fields of ``Result`` and, in the same order, of the deprecated result types
#: (``core.spark.Solution``, ``compiled.runner.FastSolution``, ``ensemble.EnsembleResult``)
LEADING_FIELDS = ("t", "q", "v", "energy", "constraint", "psi")


@dataclass
class Result:
    """Trajectory, diagnostics and counters of one integration (or of an ensemble).

    Returned by `integrate` on every engine. For an ensemble of B members the arrays carry a
    leading batch axis and ``n_valid`` gives each member's number of valid samples.

    Parameters
    ----------
    t : ndarray, shape (S,)
        Output times.
    q, v : ndarray, shape (S, n)
        Positions and velocities at the output times.
    energy : ndarray, shape (S,)
        The energy (8), E = L_v v - L.
    constraint : ndarray, shape (S, m)
        k(t, q, v) of (1c) at the output times.
    psi : ndarray, shape (S - 1, s, m), optional
        The stage multipliers Psi_i of (21) of the step starting at each output time, in the
        sign of (1) (d/dt grad_v L = grad_q L - K^T psi: the negative of sympy's
        ``LagrangesMethod`` multipliers); None only for the semi-implicit kernel of (25) (the
        comparators give the multipliers of their own stage equations: module docstring).
    status : int
        0: t_end reached; 1: a terminal event; negative: a step failed (-1 Newton, -2 singular
        saddle matrix (4), -3 other, e.g. non-finite values or the energy monitor, -4 the
        step-acceptance guard found another root of (21), ``RootMismatchError``).
    message : str
        The reason for ``status`` in words.
    nfev, njev, nlu, newton_iterations : int
        Counters: the stage points of the residual evaluations (s + 1 each for (21)), Jacobian
        evaluations, LU factorisations, Newton iterations. On every engine and path they include the work of the failed step and of
        every retry and rescue of a step (module docstring); ``stats["steps"]`` counts the
        accepted steps.
    method, system, scene, engine : str
        What ran: method name, system name, scene name (or None), engine.
    h : float, str or mpf
        The step size as ``integrate`` was given it (a decimal text or an mpf keeps its digits
        at mpmath precision; ``float(h)`` is the float64 step).
    dps : int, optional
        Decimal digits of an mpmath run; None for float64.
    save_every : int
        The output stride of `integrate`.
    params : dict
        The parameter values the run used.
    stats : dict
        Engine statistics (Newton path, fallbacks, timings).
    sol : callable, optional
        Dense output ``sol(t) -> (q, v)`` when asked for.
    t_events, q_events, v_events : list
        Per event function, the located event times and states.
    n_valid : ndarray, optional
        Per ensemble member, the number of valid samples.
    members : list, optional
        Per ensemble member, status and message.
    error : Exception, optional
        The failure that ended the run (re-raised by `raise_for_status`).
    coordinate_names : list of str, optional
        The names of q's coordinates (the system's symbols), in order.

    Examples
    --------
    >>> import ldaspark
    >>> res = ldaspark.integrate("particle", "gauss-1", t_span=(0, 1), h=0.25, engine="generic")
    >>> res.success, res.q.shape[0], res.engine
    (True, 5, 'generic')
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    energy: np.ndarray
    constraint: np.ndarray
    psi: Optional[np.ndarray] = None
    status: Any = STATUS_SUCCESS
    message: Any = "The integration reached t_end."
    nfev: Any = 0
    njev: Any = 0
    nlu: Any = 0
    newton_iterations: Any = 0
    method: str = ""
    system: str = ""
    scene: Optional[str] = None
    engine: str = "generic"
    h: Any = None
    dps: Optional[int] = None
    save_every: int = 1
    params: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    sol: Optional[Callable] = None
    t_events: list = field(default_factory=list)
    q_events: list = field(default_factory=list)
    v_events: list = field(default_factory=list)
    n_valid: Optional[np.ndarray] = None
    members: Optional[list] = None
    error: Optional[BaseException] = field(default=None, repr=False)
    #: names of q_1..q_n (the system's coordinate symbols), the columns of q and v
    coordinate_names: Optional[list] = None

    @property
    def success(self) -> bool:
        """True when the run (every member of an ensemble) did not fail (status >= 0)."""
        return bool(np.all(np.asarray(self.status) >= 0))

    @property
    def batch(self) -> Optional[int]:
        """Number of ensemble members, None for a single run."""
        return None if self.members is None else len(self.members)

    @property
    def n(self) -> int:
        return int(np.shape(self.q)[-1])

    @property
    def m(self) -> int:
        return int(np.shape(self.constraint)[-1])

    def raise_for_status(self) -> "Result":
        """Re-raise the step failure that ended the run (no-op on success)."""
        if self.members is not None:
            for r in self.members:
                r.raise_for_status()
            return self
        if np.ndim(self.status):      # a batch without its members (a file of an earlier version)
            bad = np.flatnonzero(np.asarray(self.status) < 0)
            if len(bad):
                msg = self.message[bad[0]] if isinstance(self.message, list) else self.message
                raise _status_error(int(np.asarray(self.status)[bad[0]]))(f"ensemble member {int(bad[0])}: {msg}")
            return self
        if self.status < 0:
            if self.error is not None:
                raise self.error
            # a Result read from a file keeps status and message, not the exception: the class
            # of its status, so that ``except NewtonError`` catches it as it caught the run's
            raise _status_error(int(self.status))(self.message)
        return self

    def __iter__(self):
        """Unpacks like ``FastSolution``: (t, q, v, energy, constraint, stats)."""
        return iter((self.t, self.q, self.v, self.energy, self.constraint, self.stats))

    def __repr__(self) -> str:
        b = f"batch={self.batch}, " if self.members is not None else ""
        return (f"Result({b}system={self.system!r}, method={self.method!r}, engine={self.engine!r}, "
                f"points={np.shape(self.t)[-1]}, status={self.status!r}, message={self.message!r})")


def _status_error(status: int) -> type:
    """The exception class of a failure status (module docstring): -1 NewtonError, -2
    SingularSaddleError, -4 RootMismatchError; -3 (non-finite values, the energy monitor, other
    step failures) and anything else LdasparkError, their common base."""
    from .errors import NewtonError, SingularSaddleError
    from .guard import RootMismatchError
    return {STATUS_NEWTON: NewtonError, STATUS_SADDLE: SingularSaddleError,
            STATUS_GUARD: RootMismatchError}.get(status, LdasparkError)


def attach_counters(exc: BaseException, counters: Optional[dict]) -> BaseException:
    """``exc`` carrying ``counters`` (``FAILURE_COUNTERS``: the work of the call that failed with
    it, the failed step included, and its accepted steps); read back by ``failure_counters``.
    None leaves ``exc`` as it is."""
    if counters is not None:
        exc.counters = {c: int(counters.get(c, 0)) for c in FAILURE_COUNTERS}
    return exc


def failure_counters(exc: Optional[BaseException]) -> Optional[dict]:
    """The counters a step failure carries (``attach_counters``), or None."""
    hit = getattr(exc, "counters", None)
    return dict(hit) if isinstance(hit, dict) else None


def add_counters(a: Optional[dict], b: Optional[dict]) -> dict:
    """The sum of two ``FAILURE_COUNTERS`` dicts (None counts as zeros)."""
    return {c: int((a or {}).get(c, 0)) + int((b or {}).get(c, 0)) for c in FAILURE_COUNTERS}


def float_array(x: Any) -> np.ndarray:
    """float64 copy of a (possibly mpmath object) array."""
    a = np.asarray(x)
    if a.dtype == object:
        return np.vectorize(float, otypes=[float])(a) if a.size else a.astype(float)
    return a.astype(float)


def save_indices(n_steps: int, every: int) -> np.ndarray:
    """Indices of the saved points: 0, every, 2 every, ... and the last step (as the compiled
    kernels do)."""
    if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every <= 0:
        raise InputError(f"save_every must be a positive integer, got {every!r}")
    idx = list(range(0, int(n_steps) + 1, int(every)))
    if idx[-1] != n_steps:
        idx.append(int(n_steps))
    return np.array(idx, dtype=int)


class EnsembleDense:
    """The dense output of an ensemble: ``sol(t) -> (q, v)`` with a leading member axis, each
    member's own ``sol`` (``Result.members[j].sol``) evaluated at t."""

    def __init__(self, sols):
        self.sols = list(sols)

    def __call__(self, t):
        pairs = [s(t) for s in self.sols]
        return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])


def stack(members: list) -> Result:
    """An ensemble Result from member Results (same system, method and grid).

    Members that stopped early (failure or terminal event) are padded to the longest member by
    repeating their last state; ``n_valid`` records each member's own length."""
    if not members:
        raise InputError("an ensemble needs at least one member")
    S = max(len(r.t) for r in members)
    n_valid = np.array([len(r.t) for r in members], dtype=int)

    def pad(a, rows):
        a = np.asarray(a)
        if len(a) == rows:
            return a
        if len(a) == 0:
            raise InputError("cannot pad an empty member trajectory")
        return np.concatenate([a, np.repeat(a[-1:], rows - len(a), axis=0)])

    long_t = max(members, key=lambda r: len(r.t)).t
    out = {}
    for name in ("q", "v", "energy", "constraint"):
        out[name] = np.stack([pad(getattr(r, name), S) for r in members])
    t = np.stack([np.concatenate([r.t, long_t[len(r.t):]]) for r in members])
    psi = None
    # a member that failed in its first step has no multipliers (psi None on some paths): its
    # rows are zeros like any member's past its end (n_valid), not a reason to drop everyone's
    shaped = [r.psi for r in members if r.psi is not None and np.ndim(r.psi) == 3]
    if shaped and all(r.psi is not None or len(r.t) == 1 for r in members):     # S = 1: (B, 0, s, m)
        tail = np.shape(shaped[0])[1:]
        psi = np.stack([pad(r.psi, S - 1) if r.psi is not None and len(r.psi) else np.zeros((S - 1,) + tail)
                        for r in members])
    first = members[0]
    events, sol = batch_events_and_dense(members)
    return Result(t=t, psi=psi, status=np.array([r.status for r in members], dtype=int), **events,
                  message=[r.message for r in members],
                  **{c: np.array([getattr(r, c) for r in members]) for c in COUNTERS},
                  method=first.method, system=first.system, scene=first.scene, engine=first.engine,
                  h=first.h, dps=first.dps, save_every=first.save_every,
                  params={"members": [r.params for r in members]},
                  stats={"members": [r.stats for r in members]}, n_valid=n_valid, members=list(members),
                  coordinate_names=None if first.coordinate_names is None else list(first.coordinate_names), **out,
                  sol=sol)


def batch_events_and_dense(members: list) -> tuple:
    """The events and dense output of an ensemble from its members' (``stack``, and
    ``resultio`` for a file): per event function one list with each member's array (a terminal
    event that stopped a member is reported on the batched Result too, status 1 there), and an
    ``EnsembleDense`` when every member has dense output, else None."""
    n_ev = max((len(r.t_events) for r in members), default=0)
    events = {name: [[(getattr(r, name)[i] if i < len(getattr(r, name)) else np.zeros((0,) if name == "t_events"
                      else (0, np.shape(r.q)[-1]))) for r in members] for i in range(n_ev)]
              for name in ("t_events", "q_events", "v_events")}
    sol = EnsembleDense(r.sol for r in members) if all(r.sol is not None for r in members) else None
    return events, sol


def from_ensemble(ens: Any, **meta: Any) -> Result:
    """A batched Result from ``ldaspark.ensemble.EnsembleResult`` (t (S,), q (R, S, n),
    ...; one stats dict per run); ``meta`` sets method, system, h, ... ."""
    R = len(ens.stats)
    names = meta.pop("coordinate_names", getattr(ens, "coordinate_names", None))     # each member its own list
    counters = {c: np.array([int(st.get(c, 0)) for st in ens.stats]) for c in COUNTERS}
    psi = getattr(ens, "psi", None)
    members = [Result(np.asarray(ens.t), ens.q[r], ens.v[r], ens.energy[r], ens.constraint[r],
                      None if psi is None else psi[r], **{c: int(counters[c][r]) for c in COUNTERS}, stats=ens.stats[r],
                      engine="compiled" if ens.stats[r].get("path") == "fast" else "generic",
                      coordinate_names=None if names is None else list(names), **meta)
               for r in range(R)]
    for m in members:
        m.stats = {**m.stats, "engine": m.stats.get("engine", m.engine)}
    res = stack(members)
    res.stats["seconds"] = ens.seconds
    return res
