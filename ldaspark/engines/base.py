"""The engine protocol: what ``ldaspark.integrate``'s one driver (``ldaspark.solve``) asks of an
engine, in the manner of scipy's ``OdeSolver`` under ``solve_ivp`` and of diffrax's solver objects.

An engine solves the stage equations (21a-f) of a method from a checked, consistent initial
point and reports counters; it knows nothing of the time grid's bookkeeping. The driver owns
the rest, the same for every engine: the options' checks, the one initial-point check
(``ldaspark.core.validate.initial_point``), the time grid and its chunks, ``save_every``, dense
output, events, the energy monitor (``energy_jump``), the step-acceptance guard
(``ldaspark.core.guard``), the prefix of a failed run, ensembles and executors, and the one
``Result``. The walk of a system is straight: driver -> engine -> kernels.

Two ways to hand steps to the driver (``Engine.mode``):

* ``"steps"``: ``steps(prepared, start, n)`` yields one ``Step`` at a time (the generic engine,
  float64 and mpmath: a Python loop over ``SparkMethod.step``); the driver keeps, watches and
  interpolates each step as it comes (the stage polynomial corrected to the grid, for dense
  output and events);
* ``"block"``: ``run(prepared, start, n, every)`` returns a block of n steps as a ``Result``
  (samples at 0, every, 2 every, ..., n; a failure raises with ``step`` set); the driver runs
  blocks of at most its chunk length (``chunked``), reruns the prefix of a failed block, and
  interpolates with the stage polynomial corrected to the grid, the stages of each step solved
  again from its saved start (``stage_solver``; the cubic Hermite for the comparators, which have
  none). ``samples`` says whether the engine can keep every ``every``-th step itself (else the
  driver asks for every step and slices).

Every engine receives the root finder (``ldaspark.Newton``) in ``prepare`` and honours each field
or refuses it in one line naming the engine and the field (``ldaspark.core.rootfinder.SUPPORT``,
``Newton.check_for``). ``resolve_step`` is the guard's hook: the safe root of one flagged step.
"""
from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import Any, Iterator, Optional

from ..core.errors import LdasparkError


@dataclass
class Step:
    """One step of a stepping engine from (t, q, v): the end point (q1, v1), its energy (8), the
    stage velocities V (s, n) and multipliers Psi (s, m) of (21), and the Newton iterations."""

    index: int
    t: Any
    q: Any
    v: Any
    q1: Any
    v1: Any
    V: Any
    Psi: Any
    energy: Any
    iterations: int


@dataclass
class Prepared:
    """What ``Engine.prepare`` returns: the system the engine integrates (a comparator's is the
    parameter-substituted one), the problem and options, the checked root finder with the name
    under which it is honoured (``stats["engine"]``), and the engine's own objects (``data``)."""

    system: Any
    prob: Any
    opts: Any
    root: Any
    support: str
    data: dict = field(default_factory=dict)


class Engine(abc.ABC):
    """One engine behind ``ldaspark.integrate``'s driver (module docstring)."""

    #: the engine's name (the key of ``ENGINES``)
    name: str = ""
    #: what ``Result.engine`` says of its runs ("generic" for the comparators, as before)
    label: str = ""
    #: what ``Result.stats["path"]`` says of its runs (a run that failed at its first step too)
    path: str = "generic"
    #: the key of ``ldaspark.core.rootfinder.SUPPORT`` whose fields this engine honours
    support: str = ""
    #: "steps" (``steps``) or "block" (``run``)
    mode: str = "block"
    #: a block engine that keeps every ``every``-th sample itself (else it returns every step)
    samples: bool = False
    #: a block engine whose long runs the driver cuts into blocks of ``COMPILED_CHUNK`` steps
    chunked: bool = False

    def root_finder(self, newton, prob):
        """The root finder ``newton`` (``ldaspark.Newton``) checked for this engine: (the Newton,
        the engine's name in ``SUPPORT`` that honours it); one InputError naming the engine and the
        field otherwise."""
        return newton.check_for(self.support), self.support

    def unavailable(self, system, prob) -> Optional[str]:
        """None when this engine can run ``system`` with the method of ``prob``, else why not (the
        driver's "auto" choice falls back on it, an explicit choice is refused with it)."""
        return None

    @abc.abstractmethod
    def prepare(self, system, prob, opts) -> Prepared:
        """What this engine needs for ``prob`` (``solve._Problem``: method, t0, h, N) with the
        options ``opts`` (``IntegrationOptions``): method objects, kernel options; the root
        finder checked (``root_finder``). Refusals are InputErrors raised here, before any step."""

    def backend(self, prepared, opts):
        """The arithmetic of the initial-point check and of the returned arrays."""
        from ..core.backend import Backend
        return Backend(opts.dps)

    def point_model(self, prepared):
        """``model(t, q, v) -> (S, k)`` for the initial-point check (None: the system's own)."""
        return None

    def check_block(self, prepared, n_steps: int, every: int) -> None:
        """Refuse a block the engine cannot store or run (before any step)."""

    def run(self, prepared, start, n_steps: int, every: int):
        """A block engine: n_steps steps from ``start`` = (t0, q0, v0) as a ``Result`` with samples
        at 0, every, ..., n_steps (every step when not ``samples``) and the counters; a step
        failure raises its LdasparkError with ``step`` set (local to this block)."""
        raise NotImplementedError(f"engine {self.name!r} runs steps, not blocks")

    def steps(self, prepared, start, n_steps: int) -> Iterator[Step]:
        """A stepping engine: yield ``Step`` i = 0..n_steps-1 from ``start``; a failing step raises."""
        raise NotImplementedError(f"engine {self.name!r} runs blocks, not steps")

    def nodes(self, prepared):
        """A stepping engine's stage nodes c_i (the collocation polynomial of dense output)."""
        raise NotImplementedError

    def stats(self, prepared) -> dict:
        """A stepping engine's counters after its steps (nfev, njev, nlu, newton_iterations, ...)."""
        return {}

    def resolve_step(self, prepared, n: int, state, prev=None, before=None):
        """The step-acceptance guard's hook: (label, (q1, v1, E1)) of the safe root of step n from
        ``state`` = (t, q, v), or (None, None) when no safe start converges. ``prev`` = (V, Psi, h)
        of the previous step (stepping engines), ``before`` = its start (t, q, v) (block engines,
        which keep no stages). The engine's ``safe_root(prepared)`` is built at the first flagged
        step and kept with the prepared run."""
        hit = prepared.data.get("safe")
        if hit is None:
            hit = prepared.data["safe"] = self.safe_root(prepared)
        return (None, None) if hit is None else hit(n, state, prev, before)

    def safe_root(self, prepared):
        """The guard's safe root of this engine's steps, a callable (n, state, prev, before) ->
        (label, (q1, v1, E1)) or (None, None) (``ldaspark.core.guard.SparkSafeRoot``); None: the
        engine has none, and its flagged steps count as unverified."""
        return None

    def stage_solver(self, prepared):
        """A block engine's stage velocities for dense output and events (it keeps none): an object
        with ``c`` (the SPARK tableau's nodes) that is called as ``(t, q, v, q1, v1)`` -> V (s, n)
        of the step from (t, q, v) whose saved end is (q1, v1), or None where no root agreeing with
        that end is found (that step's dense output is the cubic Hermite of its ends); None: the
        engine has no SPARK stages (the comparators), its dense output is the cubic Hermite."""
        return None

    def explain(self, prepared, exc: LdasparkError, prefix, start) -> LdasparkError:
        """The error that ends a run which failed with ``exc`` after the prefix ``prefix`` (a
        Result, or None: at the first step) from ``start``: ``exc`` itself unless the engine can say
        more."""
        return exc

    def __repr__(self) -> str:
        return f"<ldaspark engine {self.name!r}>"


#: the registered engines by name (``register``); the driver reaches an engine only through this
#: protocol
ENGINES: dict = {}


def register(engine: Engine) -> Engine:
    """Add ``engine`` (an ``Engine`` instance) to ``ENGINES`` under its name."""
    if not isinstance(engine, Engine) or not engine.name:
        raise TypeError(f"an engine must be a named Engine instance, got {engine!r}")
    if engine.mode not in ("steps", "block"):
        raise TypeError(f"engine {engine.name!r}: mode must be 'steps' or 'block', got {engine.mode!r}")
    ENGINES[engine.name] = engine
    return engine


def get_engine(name: str) -> Engine:
    """The registered engine ``name``."""
    hit = ENGINES.get(name)
    if hit is None:
        from ..core.errors import InputError
        raise InputError(f"unknown engine {name!r}; registered: {', '.join(sorted(ENGINES))}")
    return hit
