"""Steps per second of each method on each scene, generic path vs compiled fast path, measured
side by side in one run (h = 0.05). Usage: python benchmarks/steps_per_second.py [--quick]"""
import argparse
import os

from ldaspark.lab.reports.work_precision import steps_per_second

# the generic kernel is timed, as in the reports: no specialised kernel built in the background
# mid-run (ldaspark.compiled.specialised; benchmarks/quasi_step.py times both)
os.environ.setdefault("LDASPARK_SPECIALISE", "0")

METHODS = ("gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3",
           "lobatto-iiia-iiib-iiid-2", "lobatto-iiia-iiib-iiid-3", "euler-i", "euler-ii")


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    rows = steps_per_second(methods=METHODS, n_generic=10 if args.quick else 40,
                            n_fast=2000 if args.quick else 20000)
    # the Fig. 4 comparators on their scene, generic (ldaspark.core.comparators) vs fast
    import time
    from ldaspark.core.comparators import integrate_comparator
    from ldaspark.compiled.fast import fast_integrate
    from ldaspark.models.scenes import mp_particles
    sc = mp_particles(j=3)
    t0, q0, v0 = sc.initial()
    for m in ("lobatto-iiia-iiib-2-modified", "mp-lobatto-iiib-a-2"):
        n_g, n_f = (10, 20000) if args.quick else (100, 200000)
        t = time.process_time()
        integrate_comparator(m, sc.system, t0, q0, v0, 0.05, n_g)
        cg = time.process_time() - t
        fast_integrate(sc, m, h=0.05, n_steps=2)
        t = time.process_time()
        r = fast_integrate(sc, m, h=0.05, n_steps=n_f)
        cf = time.process_time() - t
        rows.append({"scene": "mp-particles", "method": m, "generic": n_g / cg, "fast": n_f / cf,
                     "ratio": (n_f / cf) / (n_g / cg), "kernel": r.stats["kernel"], "note": ""})
    print(f"{'scene':14s} {'method':30s} {'kernel':6s} {'generic/s':>10s} {'fast/s':>10s} {'ratio':>7s}")
    for r in rows:
        print(f"{r['scene']:14s} {r['method']:30s} {r['kernel']:6s} {r['generic']:10.3g} {r['fast']:10.3g} "
              f"{r['ratio']:7.0f} {r['note']}")
    ratios = sorted(r["ratio"] for r in rows)
    print(f"fast / generic: median {ratios[len(ratios) // 2]:.0f}x, range {ratios[0]:.0f}x - {ratios[-1]:.0f}x")


if __name__ == "__main__":
    main()
