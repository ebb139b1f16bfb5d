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


def probe_cpu(repeats: int = 3) -> float:
    """CPU seconds of a fixed reference computation (the minimum of ``repeats``; ~0.1 s on the
    machine of the committed reports): interpreted Python float arithmetic, the kind of work
    that dominates the main job (the mpmath references and the ledger run in the interpreter).
    The main job's CPU time divided by it is a machine-independent size of the job (probe units),
    recorded in report_timing.json ("probe", "cpu_over_probe"); a machine twice as fast halves
    both. Deterministic work: 2000000 steps of a logistic-map recurrence."""
    best = float("inf")
    for _ in range(repeats):
        c = time.process_time()
        x, acc = 0.3, 0.0
        for _ in range(2000000):
            x = 3.7 * x * (1.0 - x)
            acc += x
        best = min(best, time.process_time() - c)
        if not 0.0 < acc < 2000000.0:       # keeps the loop's result live; never true
            raise AssertionError(acc)
    return best
