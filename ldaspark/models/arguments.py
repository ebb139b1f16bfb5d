"""Arguments that name a model: the resolution of a system given as a LagrangianSystem, a Scene
or a scene name, and of a method given as a SparkTableau or a built-in name, for the exported
functions outside ``integrate`` (``flow_jacobian``, the Theorem 1 checks, ``RunSpec``).

They sit with the models, not in ``core.validate``: resolving a scene name needs the scenes,
and a method name the tableau families, which themselves use the validation layer.
"""
from __future__ import annotations

from ..core.errors import InputError
from ..core.validate import _describe, _rational_string, check_dps, check_max_stages, point, real_number, step_advances


def as_system(system, what: str = "system"):
    """(LagrangianSystem, Scene or None) from a LagrangianSystem, a Scene or a scene name (the
    same three forms ``integrate`` takes)."""
    from .scenes import Scene, get_scene
    from ..core.system import LagrangianSystem
    if isinstance(system, str):
        system = get_scene(system)
    if isinstance(system, Scene):
        return system.system, system
    if isinstance(system, LagrangianSystem):
        return system, None
    raise InputError(f"{what} must be a LagrangianSystem, a Scene or a scene name, got {_describe(system)}")


def as_tableau(method, what: str = "method", max_stages=None):
    """A SparkTableau from a SparkTableau or a built-in SPARK method name (not a comparator)."""
    from ..core.families import get_method
    from ..core.tableau import SparkTableau
    if isinstance(method, SparkTableau):
        return method
    if not isinstance(method, str) or len(method) > 100:
        raise InputError(f"{what} must be a SPARK method name (gauss-S, ...) or a SparkTableau, got {_describe(method)}")
    from ..core.errors import TableauError
    try:
        return get_method(method, max_stages=check_max_stages(max_stages))
    except TableauError as exc:
        raise InputError(f"{what}: {exc}") from None


def theory_args(system, tableau, t0, q0, v0, h, dps, what: str, several: bool = False,
                consistent: bool = False):
    """The common arguments of the Theorem 1 checks (``theorem1_residuals``,
    ``classify_wellposedness``, ``check_symmetry``, ``gauge_invariance``): system a
    LagrangianSystem, a Scene or a scene name (q0, v0 None: the scene's initial data), tableau a
    SparkTableau or a SPARK method name, t0 / h real (h nonzero, advancing t at every precision in
    ``dps``), q0 / v0 n real numbers; with ``consistent`` also k(t0, q0, v0) = 0 to the working
    precision (``check_symmetry``: the step ends on k = 0, so (23)'s round trip and reversed BVP
    cannot return to data off it; a residual would measure |k|, not the method). Returns
    (system, tableau, t0, q0, v0)."""
    if isinstance(dps, (list, tuple)) and not several:
        raise InputError(f"{what}: dps must be one integer number of digits, got {_describe(dps)}")
    dlist = list(dps) if isinstance(dps, (list, tuple)) else [dps]
    if not dlist:
        raise InputError(f"{what}: dps must name at least one precision")
    for d in dlist:
        if d is None:
            raise InputError(f"{what}: dps must be an integer number of digits (these checks run in mpmath)")
        check_dps(d)
    sysm, scene = as_system(system, f"{what}: system")
    tab = as_tableau(tableau, f"{what}: tableau")
    # a t0 given with a scene's initial data is used (the scene's own t0 only for t0 = None)
    t0, q0, v0 = point(sysm, t0, q0, v0, f"{what}: ", scene, max(dlist))
    hf = _rational_string(h)           # "1/10": the mpmath checks take exact fractions as text
    real_number(h if hf is None else hf, f"{what}: h", nonzero=True)
    for d in dlist:
        step_advances(t0, h if hf is None else hf, 1, int(d), what=f"{what}: h", s=tab.s, n=sysm.n, m=sysm.m)
    if consistent:
        from ..core.backend import Backend
        from ..core.errors import InconsistentInitialDataError
        bk = Backend(max(int(d) for d in dlist))
        with bk.context():
            try:
                sysm.check_consistent(bk, bk.scalar(t0), bk.array(q0), bk.array(v0))
            except InconsistentInitialDataError as exc:
                found = str(exc).split(" (pass ")[0]          # the numbers, not integrate's project hint
                raise InconsistentInitialDataError(f"{what}: {found}; the symmetry (23) is checked on consistent "
                                                   "data (project v0 onto k = 0 first: system.project_velocity)") from None
    return sysm, tab, t0, q0, v0
