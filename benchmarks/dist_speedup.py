"""Speed-up of the quick claims ledger (``ldaspark verify --quick``'s units) with 1, 2 and 4 workers,
on the local process pool and on a Dask ``LocalCluster`` (processes, one thread each), measured
side by side in one run; the records of every run are compared with the serial run's field by
field (``seconds`` aside). Needs the dist extra.

    python benchmarks/dist_speedup.py [--workers 1,2,4] [--repeat 1]

On a machine with 2 cores, 4 workers cannot beat 2: the row shows the cost of oversubscription.
"""
import argparse
import os
import time


def _strip(recs):
    return [{k: v for k, v in r.items() if k != "seconds"} for r in recs]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", default="1,2,4")
    ap.add_argument("--repeat", type=int, default=1)
    a = ap.parse_args()
    import distributed
    from ldaspark.lab.claims.ledger import CLAIM_GROUPS, run_ledger
    kw = dict(max_s=2, scenes=("particle", "skate"), perturbed=False, holonomic=False, groups=CLAIM_GROUPS,
              quick=True)
    t = time.perf_counter()
    ref = run_ledger(jobs=1, **kw)
    serial = time.perf_counter() - t
    print(f"cores {os.cpu_count()}, load {os.getloadavg()[0]:.1f}; serial (in process): {serial:.1f} s, "
          f"{len(ref)} records")
    print("| workers | local pool [s] | speed-up | LocalCluster [s] | speed-up | records equal |")
    print("|---|---|---|---|---|---|")
    for n in map(int, a.workers.split(",")):
        best_l = best_d = float("inf")
        same = True
        for _ in range(a.repeat):
            t = time.perf_counter()
            recs = run_ledger(jobs=n, **kw) if n > 1 else ref
            best_l = min(best_l, time.perf_counter() - t if n > 1 else serial)
            same &= _strip(recs) == _strip(ref)
            with distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                          dashboard_address=None, silence_logs=50) as cluster, \
                    distributed.Client(cluster) as client:
                t = time.perf_counter()
                recs = run_ledger(where=client, **kw)
                best_d = min(best_d, time.perf_counter() - t)
            same &= _strip(recs) == _strip(ref)
        print(f"| {n} | {best_l:.1f} | {serial / best_l:.2f}x | {best_d:.1f} | {serial / best_d:.2f}x | {same} |")


if __name__ == "__main__":
    main()
