"""Wall and CPU time of a report section, workers included.

CPU time is ``getrusage`` of this process plus its reaped children (the worker processes of a
``ProcessPoolExecutor`` count once the pool has shut down), so a section that fans out over both
cores reports the CPU it used, not only the parent's share.
"""
from __future__ import annotations

import resource
import time


def _cpu() -> float:
    s = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


class Clock:
    """``Clock()`` starts; ``wall`` / ``cpu`` are the seconds since then."""

    def __init__(self):
        self.t0 = time.perf_counter()
        self.c0 = _cpu()

    @property
    def wall(self) -> float:
        return time.perf_counter() - self.t0

    @property
    def cpu(self) -> float:
        return _cpu() - self.c0

    def summary(self) -> str:
        return f"{self.wall:.1f} s wall, {self.cpu:.1f} s CPU"
