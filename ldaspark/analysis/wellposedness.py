"""Well-posedness of Theorem 1's boundary-value solve (t0, q0, t1, q1) -> (V, Lambda, v0, v1):
rank decided at two precisions and two step sizes; gauge directions and the gauge invariance of
L_d (see ``ldaspark.analysis.discrete`` for the bordered gauge-fixed solve)."""
from __future__ import annotations

import math
import re
from fractions import Fraction

import mpmath
import numpy as np

from ..core.backend import Backend
from ..models import arguments
from .discrete import (GAUGE, SINGULAR, UNDECIDED, WELLPOSED, DiscreteBVP, _null_support, _rank_info, _svd,
                       base_point, discrete_lagrangian, entries_undecided)

NEWTON = "mixed"     # the IVP step to the point where J is classified


#: a step factor's text: "p/q" or a decimal with an exponent of at most _FACTOR_EXPONENT digits'
#: magnitude (Fraction("1e999999999") builds 10^999999999: minutes of CPU for one argument)
_FACTOR_TEXT = re.compile(r"\s*(?:[+-]?\d{1,20}\s*/\s*\d{1,20}|[+-]?(?:\d{1,20}(?:\.\d{0,20})?|\.\d{1,20})"
                          r"(?:[eE][+-]?\d{1,3})?)\s*")


def _step_factor(f):
    """A step factor of ``classify_wellposedness`` as an exact Fraction (None: not a finite
    rational): integers, finite floats (their shortest repr: 0.5 is 1/2, 0.1 is 1/10), Fractions,
    and strings "p/q" or decimals, parsed within bounds (digits and exponent) so that no text makes
    the conversion itself run long; whether the value is a usable factor is the caller's check."""
    from ..core.validate import _is_bool
    if _is_bool(f):
        return None
    if isinstance(f, Fraction):
        return f
    if isinstance(f, (int, np.integer)):
        return Fraction(int(f))
    if isinstance(f, (float, np.floating)):
        return Fraction(repr(float(f))) if math.isfinite(f) else None
    if isinstance(f, str) and _FACTOR_TEXT.fullmatch(f):
        try:
            return Fraction(f.strip().replace(" ", ""))
        except (ValueError, ZeroDivisionError):
            return None
    return None


def classify_wellposedness(system, tableau, t0, q0, v0, h, dps=(30, 50), h_factors=(1, "1/2")):
    """Rank of the BVP Jacobian at the IVP base point, decided at high precision.

    For each dps in ``dps`` and each step h f, the singular values of J. A structurally zero
    sigma sits at the precision floor (sigma / sigma_max ~ 10^-dps: it moves with dps); a
    genuinely small one scales like a power of h and does not move with dps. The lowest and the
    highest precision given are compared (in any order): a sigma is structural when it drops by
    more than 10^-(gap / 2) between them, gap = their difference in digits (half the drop of a
    floor sigma; a genuine one agrees to many more digits).

    Parameters
    ----------
    system : LagrangianSystem, Scene or str
        The system (1); a Scene or a scene name also gives the initial data (q0, v0 None).
    tableau : SparkTableau
        The SPARK method (21).
    t0 : float
        Initial time.
    q0, v0 : array_like or None
        The base point; None with a scene.
    h : float
        Step size (nonzero).
    dps : tuple of int, optional
        The precisions compared, lowest against highest (default (30, 50)).
    h_factors : tuple, optional
        Factors f of the steps h f (default (1, "1/2")).

    Returns
    -------
    dict
        ``class`` ("well-posed" or the kind of deficiency), ``rank_deficiency``, the singular
        values per (dps, h), the smallest nonzero one's observed power of h, the floor per dps.

    Examples
    --------
    >>> import ldaspark
    >>> sc = ldaspark.get_scene("skate")
    >>> ldaspark.classify_wellposedness(sc.system, ldaspark.gauss(2), sc.t0, sc.q0, sc.v0, 0.1)["class"]
    'well-posed'
    """
    from ..core import validate
    from ..core.errors import InputError
    if isinstance(dps, (list, tuple)):
        for d in dps:
            validate.check_dps(d)
    if not isinstance(dps, (list, tuple)) or len(dps) < 2 or len(set(map(int, dps))) != len(dps):
        raise InputError(f"classify_wellposedness: dps must be two or more distinct precisions, got "
                         f"{validate._describe(dps)}")
    system, tableau, t0, q0, v0 = arguments.theory_args(system, tableau, t0, q0, v0, h, dps, "classify_wellposedness",
                                                         several=True)
    if not isinstance(h_factors, (list, tuple)) or len(h_factors) < 2 or len(set(map(str, h_factors))) != len(h_factors):
        raise InputError(f"classify_wellposedness: h_factors must be two or more distinct step factors, got "
                         f"{validate._describe(h_factors)}")
    factors = {}
    for f in h_factors:
        fr = _step_factor(f)
        if fr is None or fr <= 0 or fr.denominator > 10 ** 6 or fr.numerator > 10 ** 6:
            raise InputError(f"classify_wellposedness: h_factors must be positive rationals such as 1 or \"1/2\", "
                             f"got {validate._describe(f)}")
        factors[str(f)] = fr
    if len(set(factors.values())) != len(factors):    # 1 and 1.0, "1/2" and 0.5: one step twice
        raise InputError(f"classify_wellposedness: h_factors must be two or more distinct step factors, got "
                         f"{validate._describe(h_factors)} (equal values)")
    d_lo, d_hi = min(dps), max(dps)
    out = {"sigma": {}, "deficiency": {}}
    nz = {}
    sig_rel = {}
    support = None
    for d in dps:
        for f in h_factors:
            bk = Backend(d)
            with bk.context():
                fr = factors[str(f)]
                hf = bk.scalar(h) * fr.numerator / fr.denominator
                # mixed Newton (float64 Newton matrix, residual at d digits): the same point to
                # the step's tolerance; only J there is used (its rank and sigma to a few digits)
                t1, q1, xg = base_point(system, tableau, t0, q0, v0, hf, d, newton=NEWTON)
                bvp = DiscreteBVP(system, tableau, d)
                t0_ = bk.scalar(t0)
                G, J, _, _ = bvp.evaluate(t0_, bk.array(q0), t1, q1, xg)
                sig, r, U, Vh = _rank_info(bk, J, d)
                # sigma / sigma_max in mpmath: a floor sigma ~10^-d is below float64's range from
                # d ~ 324 (dps goes to 2000), where float64 ratios became 0.0 at both precisions
                rel = [mpmath.mpf(x) / sig[0] for x in sig]
                sig_rel[(d, f)] = rel
                key = f"dps={d},h={float(hf):.4g}"
                out["sigma"][key] = [float(x) for x in rel[-min(len(rel), 3):]]
                out["deficiency"][key] = r
                nz[(d, f)] = (float(hf), rel[len(rel) - 1 - r])
                if d == d_hi and f == h_factors[0]:
                    keep = (bvp, J, Vh, bk)
    # structural zeros follow the precision: index-wise (from the bottom), sigma at the highest dps
    # is below sigma at the lowest dps by more than half their digit gap (a floor sigma ~ c 10^-d
    # drops by ~10^-gap, c within a few orders of 1); genuine small sigma agree to many digits
    drop = mpmath.mpf(10) ** (mpmath.mpf(-(int(d_hi) - int(d_lo))) / 2)
    struct = {}
    for f in h_factors:
        lo, hi = sig_rel[(d_lo, f)][::-1], sig_rel[(d_hi, f)][::-1]   # ascending
        k = 0
        while k < len(lo) and hi[k] < drop * lo[k]:
            k += 1
        struct[f] = k
    out["structural"] = {str(f): k for f, k in struct.items()}
    r = max(struct.values())
    for f in h_factors:   # the smallest genuine sigma per h
        nz[(d_lo, f)] = (nz[(d_lo, f)][0], sig_rel[(d_lo, f)][len(sig_rel[(d_lo, f)]) - 1 - r])
        nz[(d_hi, f)] = (nz[(d_hi, f)][0], sig_rel[(d_hi, f)][len(sig_rel[(d_hi, f)]) - 1 - r])
    (h1, s1), (h2, s2) = nz[(d_lo, h_factors[0])], nz[(d_lo, h_factors[1])]
    p = math.log(s1 / s2) / math.log(h1 / h2) if s1 > 0 and s2 > 0 else float("nan")
    stable = abs(float(nz[(d_lo, h_factors[0])][1] / nz[(d_hi, h_factors[0])][1]) - 1) < 1e-10   # a ratio ~1
    tracks = r > 0
    bvp, J, Vh, bk = keep
    if r and r < len(sig_rel[(d_hi, h_factors[0])]) and sig_rel[(d_hi, h_factors[0])][-1 - r] < 1e-12:
        # a genuine sigma below float64 resolution: float64 vectors would mix it into the null space
        with bk.context():
            Vh = _svd(bk, J)[2]
    fr = factors[str(h_factors[0])]
    bk_hi = Backend(d_hi)
    with bk_hi.context():     # the step of sig_rel[(d_hi, h_factors[0])], at its precision
        undecided = entries_undecided(system, tableau, t0, q0, v0, bk_hi.scalar(h) * fr.numerator / fr.denominator,
                                      d_hi, sig_rel[(d_hi, h_factors[0])], r)
    support = _null_support(bvp, Vh, r)
    if undecided is not None:
        # a sigma the entries' uncertainty can move to zero: the rank is not decided at their digits;
        # the class it would have as zero is reported beside
        r0 = r + undecided["count"]
        sup0 = _null_support(bvp, Vh, r0)
        undecided["class_if_zero"] = GAUGE if sup0["V"] <= 1e-8 and sup0["v1"] <= 1e-8 else SINGULAR
        out["entries_undecided"] = undecided
    if undecided is not None:
        cls = UNDECIDED
    elif len(set(struct.values())) > 1:
        cls = SINGULAR      # structural rank changes with h: not a clean property
    elif r == 0:
        cls = WELLPOSED
    else:
        small = 1e-8
        cls = GAUGE if support["V"] <= small and support["v1"] <= small else SINGULAR
    out.update({"class": cls, "rank_deficiency": r, "sigma_min_nonzero_rel": float(s1),
                "sigma_min_power_of_h": p, "sigma_stable_across_dps": stable,
                "floor_tracks_precision": tracks, "null_support": support})
    return out


def gauge_invariance(system, tableau, t0, q0, v0, h, dps=40, shift="1e-3"):
    """For a rank-deficient J: re-solve with the gauge pinned at x + shift * n (n a right null
    vector of J) and report how L_d, p0 + f_d^- and p1 - f_d^+ (= -dL_d/dq0, dL_d/dq1 by
    Theorem 1; gauge-invariant) move, next to how p0 itself moves (the gauge is real).
    Returns None when J has full rank.

    Parameters
    ----------
    system, tableau, t0, q0, v0, h
        As for ``classify_wellposedness``.
    dps : int, optional
        Working digits (default 40).
    shift : str or float, optional
        The gauge shift along the null vector (default "1e-3"; nonzero)."""
    from ..core import validate
    system, tableau, t0, q0, v0 = arguments.theory_args(system, tableau, t0, q0, v0, h, dps, "gauge_invariance")
    validate.real_number(shift, "gauge_invariance: shift", nonzero=True)
    bk = Backend(dps)
    with bk.context():
        t1, q1, xg = base_point(system, tableau, t0, q0, v0, h, dps)
        t0_, q0_ = bk.scalar(t0), bk.array(q0)
        a = discrete_lagrangian(system, tableau, t0_, q0_, t1, q1, dps=dps, x_guess=xg)
        if a.rank_deficiency == 0:
            return None
        xs = a.x + bk.scalar(shift) * a.extra["gauge"].C[0]
        b = discrete_lagrangian(system, tableau, t0_, q0_, t1, q1, dps=dps, x_guess=xs, gauge_ref=xs)
        sc = max(bk.norm_inf(a.p0), bk.norm_inf(a.p1), 1e-300)
        return {"wellposed": a.wellposed,
                "dL_d": float(abs(a.L_d - b.L_d) / max(abs(a.L_d), 1e-300)),
                "d(p0+f_d_minus)": float(bk.norm_inf((a.p0 + a.f_d_minus) - (b.p0 + b.f_d_minus)) / sc),
                "d(p1-f_d_plus)": float(bk.norm_inf((a.p1 - a.f_d_plus) - (b.p1 - b.f_d_plus)) / sc),
                "dp0": float(bk.norm_inf(a.p0 - b.p0) / sc),
                "dV": float(bk.norm_inf(a.V - b.V)),
                "shift": float(shift), "dps": dps}
