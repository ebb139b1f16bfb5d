"""High precision at speed: the claims ledger and the generic path's step, before and after.

Prints, in one run (CPU seconds from ``time.process_time``, so other jobs on the machine
inflate them less than wall time; every ratio is measured side by side):

1. LU solves at 30/50/100 digits: python-flint (arb) inverse + product vs the pure-mpmath LU
   (``ldaspark.core.backend``), 20x20 and 40x40, and the agreement of the two solutions.
2. The generic SPARK step (robot, gauss-2; MP particles, lobatto-iiia-iiib-3) at float64 /
   dps 30 / dps 50: the previous assembly (einsum over identity blocks, kept below as
   ``_einsum_jacobian``, with the pure-mpmath LU) against the block assembly with the arb LU,
   full Newton in both; and newton="auto" against "full", with max |q_auto - q_full|.
3. The claims ledger: a representative subset (``--ledger subset``, default: every method with
   s <= 2 on the particle and the robot, ~1/10 of the full ledger), the ledger's units alone
   (``--ledger full``), or everything ``ldaspark verify`` runs (``--ledger verify``: the units
   and the claim groups' pieces in one pool), wall and CPU seconds (workers included), against
   the baselines measured before these changes (``BEFORE``, ``BEFORE_VERIFY``). With
   ``--compare BEFORE.json`` the records are compared with a ledger written before
   (``benchmarks/ledger_compare.py``: same verdicts, residual ratios).

    python benchmarks/ledger_speed.py [--ledger subset|full|verify|none] [--jobs N] [--steps 20]
                                      [--compare BEFORE.json]
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from ldaspark.core import backend as B                      # noqa: E402
from ldaspark.core.families import get_method               # noqa: E402
from ldaspark.models.scenes import get_scene                  # noqa: E402
from ldaspark.core.spark import SparkMethod, integrate      # noqa: E402

# the full ledger (ldaspark verify, 936 records) before these changes, same code as commit 87cb774:
# 192 s wall on an idle machine (reports/claims.md of that commit); 386 s CPU / 2421 s wall
# measured on 2026-12-01 on the shared 2-core machine at load 8-12 (docs/performance.md)
BEFORE = {"idle_wall": 192.0, "loaded_cpu": 386.5, "loaded_wall": 2421.0}
# ``ldaspark verify --jobs 2`` (1094 records) at commit 665b343, before the claim groups joined the
# pool, the per-unit memo and the reuse of the first Newton iterate: 82.5 s wall / 136 s CPU on the
# 2-core machine at load 0.1-1.6 (after: 66.7 s / 132.5 s, same conditions, one run after the
# other); 108 s / 177 s measured earlier on the idle machine (ledger units 66 s in the pool, then
# claims_general 23 s and claims_paper 11.5 s serially in the parent); serial (--jobs 1, before and
# after side by side, one core each): 143 s CPU before, 114 s after; at load 5-7: 187 s CPU, 481 s wall
BEFORE_VERIFY = {"idle_wall": 82.5, "idle_cpu": 136.4, "loaded_cpu": 187.0, "loaded_wall": 481.0}


def cpu():
    """CPU seconds of this process and its finished children (ledger workers)."""
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def _einsum_jacobian(self, h, st, fin):
    """The Newton matrix as assembled before at every precision (einsum over identity blocks)."""
    return SparkMethod._jacobian_einsum(self, h, st, fin)


def lu_table():
    print("1. LU solve, python-flint (arb) vs pure mpmath (one factorisation + one solve)")
    print(f"{'N':>4} {'dps':>4} {'mpmath ms':>10} {'flint ms':>9} {'ratio':>6} {'|x_f - x_m|/|x|':>16}")
    rng = np.random.default_rng(1)
    for N in (20, 40):
        M = rng.standard_normal((N, N))
        r = rng.standard_normal(N)
        for dps in (30, 50, 100):
            bk = B.Backend(dps)
            with bk.context():
                J, rhs = bk.array(M.tolist()), bk.array(r.tolist())
                times, sols = {}, {}
                for use in (False, True):
                    B.USE_FLINT = use
                    t = time.process_time()
                    for _ in range(3):
                        x = bk.solve(J, rhs)
                    times[use], sols[use] = (time.process_time() - t) / 3, x
                B.USE_FLINT = B._flint is not None
                d = bk.norm_inf(sols[True] - sols[False]) / bk.norm_inf(sols[False])
            print(f"{N:>4} {dps:>4} {times[False] * 1e3:>10.2f} {times[True] * 1e3:>9.2f} "
                  f"{times[False] / times[True]:>6.1f} {d:>16.1e}")


def _run(sc, tab, dps, steps, newton):
    t0, q0, v0 = sc.initial(dps or 30)
    h = "0.05"
    if dps is None:
        t0, q0, v0, h = float(t0), [float(x) for x in q0], [float(x) for x in v0], 0.05
    t = time.process_time()
    sol = integrate(sc.system, tab, t0, q0, v0, h, n_steps=steps, dps=dps, newton=newton)
    return (time.process_time() - t) / steps, sol


def step_table(steps):
    print(f"\n2. generic SPARK step, CPU ms per step ({steps} steps, h = 0.05)")
    print(f"{'scene':>13} {'method':>20} {'dps':>4} {'before':>8} {'after':>8} {'ratio':>6} "
          f"{'auto':>8} {'full/auto':>9} {'|q_auto-q_full|':>15}")
    new_jac = SparkMethod._jacobian
    for scn, meth in (("robot", "gauss-2"), ("mp-particles", "lobatto-iiia-iiib-3")):
        sc, tab = get_scene(scn), get_method(meth)
        for dps in (None, 30, 50):
            n = steps if dps is None else max(3, steps // 4)
            _run(sc, tab, dps, 1, "full")             # compile the lambdified functions
            SparkMethod._jacobian, B.USE_FLINT = _einsum_jacobian, False
            before, ref = _run(sc, tab, dps, n, "full")
            SparkMethod._jacobian, B.USE_FLINT = new_jac, B._flint is not None
            after, full = _run(sc, tab, dps, n, "full")
            auto, sa = _run(sc, tab, dps, n, "auto")
            dq = max(float(abs(x)) for x in (sa.q - full.q).reshape(-1))
            dref = max(float(abs(x)) for x in (ref.q - full.q).reshape(-1))
            print(f"{scn:>13} {meth:>20} {str(dps or 'f64'):>4} {before * 1e3:>8.2f} {after * 1e3:>8.2f} "
                  f"{before / after:>6.2f} {auto * 1e3:>8.2f} {after / auto:>9.2f} {dq:>15.1e}"
                  f"   (before vs after q: {dref:.1e})")


def ledger(kind, jobs, compare=None):
    from ldaspark.lab.claims.ledger import CLAIM_GROUPS, run_ledger
    print(f"\n3. claims ledger ({kind}), {jobs or 'default'} worker process(es)")
    w, c = time.time(), cpu()
    if kind == "full":
        recs = run_ledger(max_s=3, jobs=jobs)
    elif kind == "verify":
        recs = run_ledger(max_s=3, jobs=jobs, groups=CLAIM_GROUPS)
    else:
        recs = run_ledger(max_s=2, scenes=("particle", "robot"), controls=False, jobs=jobs)
    w, c = time.time() - w, cpu() - c
    print(f"{len(recs)} records in {w:.1f} s wall, {c:.1f} s CPU (load average {os.getloadavg()[0]:.1f})")
    if kind == "full":
        print(f"before: {BEFORE['idle_wall']:.0f} s wall idle, {BEFORE['loaded_cpu']:.0f} s CPU at load 8-12: "
              f"CPU ratio {BEFORE['loaded_cpu'] / c:.1f}x")
    if kind == "verify":
        b = BEFORE_VERIFY
        print(f"before: {b['idle_wall']:.0f} s wall / {b['idle_cpu']:.0f} s CPU idle, {b['loaded_cpu']:.0f} s CPU "
              f"loaded: CPU ratio {b['loaded_cpu'] / c:.2f}x; projected idle wall on 2 cores ~ CPU / 2 = "
              f"{c / 2:.0f} s (+ the longest unit's tail)")
    if compare:
        import json
        from ledger_compare import compare as cmp
        with open(compare) as f:
            r = cmp(json.load(f), recs)
        print(f"against {compare}: {len(r['verdict_diffs'])} verdict differences, max residual ratio "
              f"{r['max_ratio']:.3g}, moved > 10x: {len(r['moved'])}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ledger", choices=("subset", "full", "verify", "none"), default="subset")
    ap.add_argument("--compare", default=None, help="a claims.json written before, to compare the records with")
    ap.add_argument("--jobs", type=int, default=None)
    ap.add_argument("--steps", type=int, default=20)
    a = ap.parse_args(argv)
    print(f"python-flint: {'yes' if B._flint is not None else 'no (pure mpmath)'}; "
          f"load average {os.getloadavg()[0]:.1f}\n")
    lu_table()
    step_table(a.steps)
    if a.ledger != "none":
        ledger(a.ledger, a.jobs, a.compare)


if __name__ == "__main__":
    main()
