"""Work-precision of the SPARK methods against scipy's solve_ivp (DOP853, Radau, LSODA) on the
index-reduced ODE, with and without projection, and against the strongest peers (ode('dop853'),
ode('lsoda'), CVODE Adams when scikit-sundae is installed; the full peer study is
benchmarks/peers.py); writes reports/work_precision.md and reports/figures/wp_*.png and prints the
CPU-time ratios at equal accuracy.
Usage: python benchmarks/work_precision.py [--quick] [--outdir reports]"""
import argparse

from ldaspark.lab.reports.work_precision import ratios, run_study


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--outdir", default="reports")
    args = ap.parse_args()
    res = run_study(args.outdir, quick=args.quick)
    for st in res["studies"]:
        for key in ("error", "energy_error"):
            print(f"{st['scene']}: CPU-time ratio at equal {key.replace('_', ' ')} (scipy best / SPARK)")
            for r in ratios(st, key=key):
                f = r["scipy/spark-fast"]
                g = r["scipy/spark-generic"]
                p = r.get("peer/spark-fast")
                print(f"  {r['target']:.0e}: scipy/SPARK-fast = {'-' if f is None else f'{f:.0f}x'}, "
                      f"scipy/SPARK-generic = {'-' if g is None else f'{g:.2f}x'}, best peer "
                      f"({r.get('best peer name') or '-'})/SPARK-fast = {'-' if p is None else f'{p:.2g}x'}")
    le = res["long"]
    for k in ("spark", "dop853", "dop853_projected"):
        print(f"long run {le[k]['label']}: max|E-E0| first half {le[k]['max_first_half']:.2e}, "
              f"second half {le[k]['max_second_half']:.2e}, CPU {le[k]['cpu']:.2f} s")


if __name__ == "__main__":
    main()
