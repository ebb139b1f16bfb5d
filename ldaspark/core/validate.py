"""Argument validation shared by the generic and the compiled paths: every bad option becomes an
InputError (one line at the command line) before any work is done, never a TypeError,
UnboundLocalError or MemoryError from deep inside a loop."""
from __future__ import annotations

import math
import numbers
import os

from .errors import InputError

#: Newton iteration caps above this are certainly mistakes (each iteration costs a factorisation)
MAX_NEWTON_ITER = 10 ** 6
#: fraction of the physical memory a run may plan to hold (the trajectory arrays)
MEMORY_FRACTION = 0.5


def check_newton_options(tol, max_iter, what: str = "Newton tolerance") -> None:
    """tol: None or a finite positive real number; max_iter: an integer in [1, MAX_NEWTON_ITER]."""
    if tol is not None:
        try:
            ok = not isinstance(tol, (bool, str, bytes)) and math.isfinite(float(tol)) and float(tol) > 0
        except (TypeError, ValueError, OverflowError):
            ok = False
        if not ok:
            raise InputError(f"{what} must be a finite positive number, got {tol!r}")
    if isinstance(max_iter, bool) or not isinstance(max_iter, numbers.Integral) or not 1 <= max_iter <= MAX_NEWTON_ITER:
        raise InputError(f"max_iter must be an integer between 1 and {MAX_NEWTON_ITER}, got {max_iter!r}")


def check_system_and_tableau(system, tableau) -> None:
    """The integrators' first two arguments have the right types (a clear error, not an
    AttributeError several calls deep). Duck-typed, so that subclasses and variants of
    LagrangianSystem / SparkTableau pass."""
    if not all(hasattr(system, a) for a in ("n", "m", "stage", "momentum", "energy", "saddle_matrix")):
        raise InputError(f"system must be a LagrangianSystem, got {type(system).__name__}")
    if not (hasattr(tableau, "arrays") and isinstance(getattr(tableau, "s", None), int)):
        raise InputError(f"tableau must be a SparkTableau (see ldaspark.core.families.get_method), "
                         f"got {type(tableau).__name__}")


def physical_memory() -> int | None:
    """Bytes of physical memory, or None where the platform does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def check_storage(n_points: int, floats_per_point: int, mp: bool = False, what: str = "the trajectory") -> None:
    """Refuse a run whose stored samples cannot fit in memory (before allocating them): an
    InputError naming the size, instead of a MemoryError or swapping. mpmath numbers cost ~100
    bytes each, float64 8 bytes plus list overhead."""
    per = 120 if mp else 40
    need = int(n_points) * int(floats_per_point) * per
    mem = physical_memory()
    limit = MEMORY_FRACTION * mem if mem else 64 * 2 ** 30
    if need > limit:
        raise InputError(f"storing {what} ({n_points:.3g} points x {floats_per_point} numbers) needs about "
                         f"{need / 2 ** 30:.3g} GiB, more than {limit / 2 ** 30:.3g} GiB: use fewer steps "
                         "(a larger h or a shorter t_end)")
