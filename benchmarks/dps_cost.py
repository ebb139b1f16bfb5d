"""The cost of precision: CPU time per step of the mpmath path at dps 16, 30, 50, 100 against
float64 (generic and fast path), particle, gauss-2, h = 0.1. Usage: python benchmarks/dps_cost.py"""
from ldaspark.lab.reports.work_precision import dps_cost


def main():
    rows = dps_cost(n_steps=8)
    base = [r for r in rows if r["precision"] == "float64 generic"][0]["seconds_per_step"]
    fast = [r for r in rows if r["precision"] == "float64 fast"][0]["seconds_per_step"]
    print(f"{'precision':18s} {'s/step':>10s} {'x generic f64':>14s} {'x fast f64':>11s}")
    for r in rows:
        s = r["seconds_per_step"]
        it = r.get("mean_iterations")
        print(f"{r['precision']:18s} {s:10.3g} {s / base:14.3g} {s / fast:11.3g}  Newton {'-' if it is None else f'{it:.2f}'}/step")


if __name__ == "__main__":
    main()
