"""Equal-error cost: the CPU time a set of runs needs to reach an error target, on their lower
envelope. Shared by the work-precision study (``work_precision``) and the peers' comparison
(``peers``), which both import it from here (``work_precision.cpu_at`` stays importable).
"""
from __future__ import annotations

import numpy as np


def cpu_at(rows, target, key="error"):
    """CPU time to reach ``target`` (log-log interpolation on the cheapest runs), None if out of range."""
    pts = sorted((r[key], r["cpu"]) for r in rows if r[key] > 0 and np.isfinite(r[key]))
    if not pts or target < pts[0][0] or target > pts[-1][0]:
        return None
    # C(e) = cheapest run with error <= e (non-increasing in e), interpolated log-log
    errs = np.array([p[0] for p in pts])
    cpus = np.array([p[1] for p in pts])
    keep = cpus <= np.minimum.accumulate(cpus)                   # drop runs a more accurate one beats
    return float(10 ** np.interp(np.log10(target), np.log10(errs[keep]), np.log10(cpus[keep])))
