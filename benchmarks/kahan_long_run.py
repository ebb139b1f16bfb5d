"""Round-off over 1e6 steps with and without compensated (Kahan) summation: 2-stage Lobatto
IIIA-B SPARK on a linear constrained system, float64 fast path against the same map in 40-digit
mpmath. Prints growth exponents (sqrt(N) = 0.5) and plain/compensated ratios for h = 1/16 (exact
products with h) and h = 0.05; plots reports/figures/wp_kahan.png.
Usage: python benchmarks/kahan_long_run.py [--steps 1e6] [--ics 16]"""
import argparse
import os

import numpy as np

from ldaspark.compiled.fast import growth_exponent, roundoff_errors

# the generic kernel is timed, as in the reports: no specialised kernel built in the background
# mid-run (ldaspark.compiled.specialised; benchmarks/quasi_step.py times both)
os.environ.setdefault("LDASPARK_SPECIALISE", "0")


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--steps", type=float, default=1e6)
    ap.add_argument("--ics", type=int, default=16)
    ap.add_argument("--plot", default="reports/figures/wp_kahan.png")
    args = ap.parse_args()
    N = int(args.steps)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), sharey=True)
    for ax, h in zip(axes, (1 / 16, 0.05)):
        d = roundoff_errors(n_steps=N, every=N // 100, n_ics=args.ics, h=h)
        Ns = np.array(d["N"])
        for key, lab in (("rms", "max_i |q_i - q_i^ref|"), ("rms_neutral", "along q1+q2+q3")):
            c, p = d[key]["compensated"], d[key]["plain"]
            print(f"h = {h:g}, {lab:22s}: compensated {c[-1]:.2e} (exponent {growth_exponent(Ns, c):.2f}), "
                  f"plain {p[-1]:.2e} (exponent {growth_exponent(Ns, p):.2f}), plain/compensated = {p[-1] / c[-1]:.1f}")
            ax.loglog(Ns, c, "-" if key == "rms" else ":", label=f"compensated, {lab}")
            ax.loglog(Ns, p, "--" if key == "rms" else "-.", label=f"plain, {lab}")
        ax.loglog(Ns, 2.0 ** -52 * np.sqrt(Ns), "k:", lw=0.8, label="eps sqrt(N)")
        ax.set_title(f"h = {h:g}")
        ax.set_xlabel("steps N")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel(f"RMS round-off over {args.ics} initial data")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    os.makedirs(os.path.dirname(args.plot), exist_ok=True)
    fig.savefig(args.plot, dpi=110)
    print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
