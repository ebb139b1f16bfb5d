"""The integration options of ``ldaspark.integrate`` as one frozen object, checked once at the API
boundary (``IntegrationOptions.checked``, with the checks of ``ldaspark.core.validate``) and then
carried unchanged to every engine path (generic, compiled, comparators, ensembles): the engine
functions read their options from it instead of a dozen loose arguments.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Optional

from . import validate
from .errors import InputError

ENGINES = ("auto", "compiled", "generic")


@dataclass(frozen=True)
class IntegrationOptions:
    """How to integrate (not what): engine, arithmetic, Newton, output, monitors, where members run.

    engine: "auto", "compiled" or "generic"; dps: mpmath digits (None: float64); newton: the
    root finder (``ldaspark.core.rootfinder.Newton``, every engine receives it; the old kind
    names are mapped to it); tol: Newton tolerance (None: the engine's default; = newton.tol);
    guard: the step-acceptance guard (``ldaspark.core.guard``, on by default);
    save_every: keep every k-th step and the last; dense_output; events: the checked events
    (``ldaspark.core.dense.Event``); energy_jump: the energy monitor's relative jump (None: off);
    executor: where ensemble members (and a single run, one member) run (None: here); max_stages: the stage limit of
    built-in method names; project: project v0 onto k = 0; raise_on_failure."""

    engine: str = "auto"
    dps: Optional[int] = None
    newton: Any = None
    tol: Optional[float] = None
    guard: bool = True
    save_every: int = 1
    dense_output: bool = False
    events: tuple = ()
    energy_jump: Optional[float] = None
    executor: Any = None
    max_stages: Optional[int] = None
    project: bool = False
    raise_on_failure: bool = False

    @classmethod
    def checked(cls, *, engine="auto", dps=None, newton="auto", tol=None, save_every=1, dense_output=False,
                energy_jump=None, executor=None, max_stages=None, project=False,
                raise_on_failure=False, guard=True) -> "IntegrationOptions":
        """The options after the checks of ``ldaspark.core.validate`` (one InputError naming the
        first wrong value, in this order: engine, dps, newton, executor, save_every, max_stages,
        tol, energy_jump, the flags, dps with the compiled engine). Events are checked apart
        (``with_events``), after the system and the method, as ``integrate`` always has.

        Options of plain values (str, int, float, bool, None; no executor) that passed are
        remembered per process (``_CHECKED_OPTIONS``, keyed with their types: ``save_every=True``
        is not 1), so a repeated call checks them once; the options object is frozen and shared."""
        key = (engine, dps, newton, tol, save_every, dense_output, energy_jump, executor, max_stages, project,
               raise_on_failure, guard)
        types = tuple(map(type, key))
        key = key + types if _PLAIN.issuperset(types) else None
        hit = _CHECKED_OPTIONS.get(key) if key is not None else None
        if hit is not None:
            return hit
        opts = cls._checked(engine=engine, dps=dps, newton=newton, tol=tol, save_every=save_every,
                            dense_output=dense_output, energy_jump=energy_jump, executor=executor,
                            max_stages=max_stages, project=project, raise_on_failure=raise_on_failure, guard=guard)
        if key is not None:
            if len(_CHECKED_OPTIONS) >= 256:      # bounded: a sweep over tol makes a key per value
                _CHECKED_OPTIONS.clear()
            _CHECKED_OPTIONS[key] = opts
        return opts

    @classmethod
    def _checked(cls, *, engine, dps, newton, tol, save_every, dense_output, energy_jump, executor, max_stages,
                 project, raise_on_failure, guard) -> "IntegrationOptions":
        """``checked`` without the memory."""
        validate.check_choice(engine, "engine", ENGINES)
        dps = validate.check_dps(dps)
        from .rootfinder import Newton
        if not isinstance(newton, Newton):
            # "quasi": the compiled engine's multiplier-only root finder (``compiled.quasi``)
            validate.check_choice(newton, "newton", validate.NEWTON_VARIANTS + ("quasi",))
        validate.check_executor(executor)
        validate.count(save_every, "save_every")
        validate.check_max_stages(max_stages)
        validate.check_newton_options(tol, 1)
        newton = Newton.coerce(newton, tol)
        tol = newton.tol
        validate.check_tol_resolvable(tol, dps)     # every engine: float64's, or dps digits'
        if energy_jump is not None:
            validate.check_newton_options(energy_jump, 1, what="energy_jump")
        for flag, val in (("dense_output", dense_output), ("raise_on_failure", raise_on_failure),
                          ("project", project), ("guard", guard)):
            if not validate._is_bool(val):
                raise InputError(f"{flag} must be True or False, got {validate._describe(val)}")
        if dps is not None and engine == "compiled":
            raise InputError("the compiled engine is float64 only; dps needs engine='generic' (or 'auto')")
        if (engine == "generic" or dps is not None) and newton == "quasi":     # (Newton.__eq__ is not cheap)
            raise InputError("newton='quasi' runs on the compiled engine only (float64, engine='compiled' or 'auto')")
        return cls(engine=engine, dps=dps, newton=newton, tol=tol, save_every=save_every,
                   dense_output=dense_output, energy_jump=energy_jump, executor=executor,
                   max_stages=max_stages, project=project, raise_on_failure=raise_on_failure,
                   guard=bool(guard))

    def with_events(self, events) -> "IntegrationOptions":
        """These options with ``events`` (None, a callable or a sequence of them) checked and
        normalised (``ldaspark.core.dense.check_events``)."""
        if events is None and self.events == ():
            return self               # nothing to check, nothing changes (the options are frozen)
        from .dense import check_events
        evs = tuple(check_events(events))
        # members sent to a process pool carry the events: a local function or a lambda does not
        # pickle, refused here by name rather than as a PicklingError from inside the pool
        validate.check_picklable(self.executor, evs, "the event function")
        return dataclasses.replace(self, events=evs)

    def replace(self, **changes) -> "IntegrationOptions":
        """A copy with ``changes`` (values already checked by the caller)."""
        return dataclasses.replace(self, **changes)

    @property
    def every_step(self) -> bool:
        """Whether an engine that can keep every ``save_every``-th point must keep every step
        instead: dense output, events and the energy monitor look at each step."""
        return bool(self.dense_output or self.events or self.energy_jump is not None)


#: the value types whose options ``IntegrationOptions.checked`` remembers (hashable, immutable,
#: equal values validate alike)
_PLAIN = frozenset((str, int, float, bool, type(None)))
#: (the options' values, their types) -> the checked ``IntegrationOptions``
_CHECKED_OPTIONS: dict = {}
