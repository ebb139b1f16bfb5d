"""Fig. 4 at full length: 3 methods x 10 initial data x 1e6 steps (h = 0.05, t in [0, 50000]) on
the compiled fast path over a process pool; prints the wall time, E0, the growth exponents of
mu((E - E0)^2)/h^4, and the speed-up against the generic path measured on a short run.
Usage: python benchmarks/fig4_full.py [--t-end 50000] [--out fig4.json] [--workers N]"""
import argparse
import concurrent.futures
import time

import numpy as np

from ldaspark.lab.reports.fig4 import FIG4_METHODS, figure4_data


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--t-end", type=float, default=50000.0)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out", default=None, help="write the data as JSON")
    args = ap.parse_args()
    ex = concurrent.futures.ProcessPoolExecutor(max_workers=args.workers) if args.workers else None
    d = figure4_data(t_end=args.t_end, executor=ex)
    if ex:
        ex.shutdown()
    n_runs = len(FIG4_METHODS) * 10
    total = n_runs * d["n_steps"]
    print(f"Fig. 4: {n_runs} runs x {d['n_steps']} steps = {total:.3g} steps in {d['seconds']:.1f} s wall "
          f"({total / d['seconds']:.3g} steps/s); target < 30 s")
    print(f"E0 = {d['E0']:.15g} (spread {d['E0_spread']:.1e}; paper: 3.06)")
    t = np.array(d["t"])
    for m in FIG4_METHODS:
        mu = np.array(d["mu_over_h4"][m])
        blocks = [mu[(t >= a) & (t < b)].mean() for a, b in ((5, 50), (50, 500), (500, 5000), (5000, t[-1] + 1))]
        print(f"{m:30s} fit exponent {d['fit'][m]['exponent']:+.3f} on {d['fit'][m]['window']}, "
              f"mean mu/h^4 per decade {', '.join(f'{b:.4f}' for b in blocks)}, Newton {d['newton'][m]:.2f}/step")
    # generic path speed on the same problem (short run), for the side-by-side ratio
    from ldaspark.core.comparators import integrate_comparator
    from ldaspark.models.scenes import mp_particles
    from ldaspark.core.spark import integrate
    from ldaspark.core.families import get_method
    sc = mp_particles(j=3)
    t0, q0, v0 = sc.initial()
    per_step = []
    for m in FIG4_METHODS:
        c = time.perf_counter()
        if m == "lobatto-iiia-iiib-2":
            integrate(sc.system, get_method(m), t0, q0, v0, 0.05, n_steps=100)
        else:
            integrate_comparator(m, sc.system, t0, q0, v0, 0.05, 100)
        per_step.append((time.perf_counter() - c) / 100)
    est = np.mean(per_step) * total
    print(f"generic path estimate for the same work: {est:.0f} s serial ({est / 3600:.1f} h); "
          f"fast parallel / generic serial = {est / d['seconds']:.0f}x")
    if args.out:
        from ldaspark.core.io import atomic_write_json
        atomic_write_json(args.out, d)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
