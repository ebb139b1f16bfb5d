"""The root finder of the stage equations (21a-f) as one option object every engine receives,
as diffrax's ``root_finder``: ``integrate(..., newton=Newton(kind="full", max_iter=20))``.

``Newton`` holds what a user may choose about the Newton iteration of a step: its ``kind``, the
tolerance, the iteration limit, the predictor (the start of a step's iteration), the linear
solver of the Newton matrix and the reuse of that matrix across steps. Each engine declares in
``SUPPORT`` what it honours; ``Newton.check_for(engine)`` refuses the rest in one line naming
the engine and the field, so that nothing is accepted and ignored. ``Newton.describe()`` is
what ``Result.stats["root_finder"]`` records.

Kinds (``KINDS``): "auto" (each engine's default: simplified Newton, continued as full Newton
when it contracts slowly; on the compiled engine the quasi-Newton iteration where
``ldaspark.compiled.runner.auto_runs_quasi`` says it pays), "full" (the Newton matrix at every
iterate), "simplified" (one matrix per step), "mixed" (at mpmath precision: the Newton matrix in
float64, the residual at full precision; in float64 it is "full"), "quasi" (the compiled
engine's multiplier-only quasi-Newton iteration of issue 48, ``ldaspark.compiled.quasi``). A new
kind is added to ``KINDS`` and to the ``SUPPORT`` of the engines that run it; the compiled engine
dispatches such kinds through ``ldaspark.compiled.runner.KIND_RUNNERS``. What ran is
``Result.stats["root_finder"]["runs"]`` on the compiled engine.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Optional

from . import validate
from .errors import InputError

#: the root finder's kinds (``Newton.kind``); see the module docstring ("quasi": the compiled
#: engine only, refused by the others)
KINDS = ("auto", "full", "simplified", "mixed", "quasi")
#: predictors: "auto" (the engine's default), "extrapolate" (linear extrapolation of the last
#: two steps' unknowns), "previous" (the last step's unknowns, shifted by the last velocity
#: increment on the generic engine), "zero" (zero increments: V_i = v1 = v0, Psi = 0, i.e. the
#: explicit Euler predictor Q_i = q0 + c_i h v0 of the positions)
PREDICTORS = ("auto", "extrapolate", "previous", "zero")
#: the compiled kernels' predictor codes (``runner.run_compiled(predictor=...)``)
PREDICTOR_CODES = {"auto": 2, "extrapolate": 2, "previous": 1, "zero": 0}
LINEAR_SOLVERS = ("auto", "dense", "sparse")
REUSE = ("auto", True, False)

#: engine -> field -> the values it honours (any other value is refused, naming engine and
#: field). tol and max_iter: None means every valid value. "compiled" is the SPARK kernels
#: (mechanical and general form, dense and block LU); "compiled-lf2" the semi-implicit kernel
#: of (25), 8.4 and (26) (Newton on the multipliers only); "comparator" the generic comparators.
SUPPORT = {
    "generic": {"kind": ("auto", "full", "simplified", "mixed"), "tol": None, "max_iter": None,
                "predictor": ("auto", "previous", "zero"), "linear_solver": ("auto", "dense"),
                "reuse": ("auto", False)},
    "compiled": {"kind": ("auto", "full", "simplified", "mixed", "quasi"), "tol": None, "max_iter": None,
                 "predictor": PREDICTORS, "linear_solver": LINEAR_SOLVERS, "reuse": REUSE},
    "compiled-lf2": {"kind": ("auto",), "tol": None, "max_iter": None,
                     "predictor": PREDICTORS, "linear_solver": ("auto", "dense"), "reuse": ("auto", False)},
    "comparator": {"kind": ("auto",), "tol": None, "max_iter": None, "predictor": ("auto",),
                   "linear_solver": ("auto", "dense"), "reuse": ("auto", False)},
}
#: why an engine refuses a field (the one-line message's reason)
_WHY = {
    ("generic", "predictor"): "the generic engine starts from the previous step's unknowns or from zero increments",
    ("generic", "linear_solver"): "the generic engine factors the dense Newton matrix",
    ("generic", "reuse"): "the generic engine forms a Newton matrix in every step",
    ("compiled-lf2", "kind"): "the semi-implicit kernel runs its own simplified Newton on the multipliers",
    ("compiled-lf2", "linear_solver"): "the semi-implicit kernel solves an m x m system",
    ("compiled-lf2", "reuse"): "the semi-implicit kernel factors its m x m matrix in every step",
    ("comparator", "kind"): "a comparator runs its own Newton iteration",
    ("comparator", "predictor"): "a comparator starts each step from its own guess",
    ("comparator", "linear_solver"): "a comparator factors the dense Newton matrix",
    ("comparator", "reuse"): "a comparator forms a Newton matrix in every step",
}
#: the engines' iteration limit when ``max_iter`` is None
MAX_ITER_DEFAULT = 50


@dataclass(frozen=True)
class Newton:
    """The root finder of the stage equations (21): one value, checked when built.

    Parameters
    ----------
    kind : {"auto", "full", "simplified", "mixed", "quasi"}
        The Newton variant (module docstring); "auto" is the default of every engine; "quasi"
        (the multiplier-only quasi-Newton iteration) runs on the compiled engine only.
    tol : float, optional
        The increment tolerance (relative); None: the round-off of the stage values. A
        larger tol trades accuracy for speed: on the compiled quasi-Newton step a step may then
        stop after one increment, on the rate carried from the previous steps (RADAU5's test;
        ``Result.stats["rate_first_steps"]``). Where the iteration contracts slowly a loose tol
        makes the step unsymmetric and the energy drifts: keep tol at or below the target error
        (docs/performance.md, "Trading accuracy for speed"). A tol below the unit round-off of
        the arithmetic (2^-52 in float64, 10^-dps with dps digits) cannot be reached and is refused
        by every engine with an InputError (``core.validate.smallest_tol``).
    max_iter : int, optional
        Iterations of one Newton attempt before it gives up (None: 50). The generic engine makes
        one attempt per step, so its step fails after max_iter iterations. The compiled engine
        makes up to four, each limited to max_iter (the quasi-Newton iteration to at most 30):
        the kernel's first root finder, simplified Newton from the predictor, full Newton from
        zero increments, then the generic engine's full Newton step (``compiled.rescue``); its
        step fails only where the last fails, so near the Newton limit a step the generic engine
        gives up on can converge there (counted in ``stats["rescued_steps"]``, on every compiled
        run; ``stats["generic_steps"]`` only where the rescue ran).
    predictor : {"auto", "extrapolate", "previous", "zero"}
        Where a step's iteration starts (``PREDICTORS``); the compiled kernels also take the
        codes 2, 1, 0.
    linear_solver : {"auto", "dense", "sparse"}
        The Newton matrix's factorisation: "sparse" is the compiled engine's block LU
        (mechanical form).
    reuse : {"auto", True, False}
        Start a step from the previous step's factored Newton matrix (compiled engine, kinds
        "auto" and "simplified"; full Newton forms its matrix at every iteration and refuses
        True).

    Examples
    --------
    >>> import ldaspark
    >>> res = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.1, engine="generic",
    ...                          newton=ldaspark.Newton(kind="full", max_iter=20))
    >>> res.stats["root_finder"]["kind"], res.njev == res.newton_iterations
    ('full', True)
    """

    kind: str = "auto"
    tol: Optional[float] = None
    max_iter: Optional[int] = None
    predictor: Any = "auto"
    linear_solver: str = "auto"
    reuse: Any = "auto"

    def __post_init__(self):
        validate.check_choice(self.kind, "Newton kind", KINDS)
        validate.check_newton_options(self.tol, 1 if self.max_iter is None else self.max_iter)
        pred = self.predictor
        if isinstance(pred, int) and not isinstance(pred, bool) and pred in (0, 1, 2):
            object.__setattr__(self, "predictor", {2: "extrapolate", 1: "previous", 0: "zero"}[pred])
        elif not (isinstance(pred, str) and pred in PREDICTORS):
            raise InputError(f"Newton predictor must be one of {', '.join(PREDICTORS)} (or 2, 1, 0), "
                             f"got {validate._describe(pred)}")
        validate.check_choice(self.linear_solver, "Newton linear_solver", LINEAR_SOLVERS)
        if not (validate._is_bool(self.reuse) or (isinstance(self.reuse, str) and self.reuse == "auto")):
            raise InputError(f"Newton reuse must be True, False or 'auto', got {validate._describe(self.reuse)}")
        object.__setattr__(self, "reuse", self.reuse if isinstance(self.reuse, str) else bool(self.reuse))

    @classmethod
    def coerce(cls, newton, tol=None) -> "Newton":
        """``integrate``'s ``newton`` (a Newton, or a kind name as before) with its ``tol``: one
        Newton. A tol given both ways must agree."""
        if isinstance(newton, Newton):
            if tol is not None and newton.tol is not None and float(tol) != float(newton.tol):
                raise InputError(f"tol = {tol!r} and Newton(tol={newton.tol!r}) disagree; give one of them")
            return newton if tol is None or newton.tol is not None else dataclasses.replace(newton, tol=tol)
        if isinstance(newton, str) and newton in KINDS:
            return cls(kind=newton, tol=tol)
        validate.check_choice(newton, "newton", validate.NEWTON_VARIANTS)   # the old message
        raise InputError(f"newton must be a Newton(...) or one of {', '.join(validate.NEWTON_VARIANTS)}")

    @property
    def iterations(self) -> int:
        """The iteration limit (``MAX_ITER_DEFAULT`` when None)."""
        return MAX_ITER_DEFAULT if self.max_iter is None else int(self.max_iter)

    def check_for(self, engine: str) -> "Newton":
        """Self when ``engine`` (a key of ``SUPPORT``) honours every field's value, else one
        InputError naming the engine, the field and the values it takes."""
        support = SUPPORT[engine]
        for field in ("kind", "predictor", "linear_solver", "reuse"):
            val = getattr(self, field)
            if val not in support[field]:
                why = _WHY.get((engine, field), f"the {engine} engine does not run it")
                ok = ", ".join(repr(x) for x in support[field])
                raise InputError(f"engine {engine!r} refuses Newton {field}={val!r} ({why}); it takes {ok}")
        return self

    def __eq__(self, other):
        """A Newton equals another with the same fields, and a kind name when its other fields are
        the defaults (``newton="full"`` and ``Newton("full")`` are one option)."""
        if isinstance(other, str):
            return self == Newton(kind=other) if other in KINDS else False
        if not isinstance(other, Newton):
            return NotImplemented
        return dataclasses.astuple(self) == dataclasses.astuple(other)

    def __hash__(self):
        return hash(dataclasses.astuple(self))

    def describe(self) -> dict:
        """The fields as a plain dict (``Result.stats["root_finder"]``)."""
        return {"kind": self.kind, "tol": self.tol, "max_iter": self.iterations, "predictor": self.predictor,
                "linear_solver": self.linear_solver, "reuse": self.reuse}


#: the default root finder (``integrate``'s ``newton="auto"``)
DEFAULT = Newton()
