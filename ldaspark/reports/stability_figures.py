"""Figures of the stability report (``ldaspark.reports.stability``): one-step error against h,
coefficient residuals against s, and the long-run energy / round-off panels."""
from __future__ import annotations

import numpy as np

from ..core.io import atomic_save_figure
from .plotting import colours, figure


def save(fig, path):
    atomic_save_figure(fig, path, dpi=110)


def step_sweep(rows, path):
    n = len(rows)
    cols = 4
    nr = (n + cols - 1) // cols
    fig, axes = figure(nr, cols, figsize=(4 * cols, 3.3 * nr))
    col = colours(3)
    for ax, r in zip(axes.flat, rows):
        for k, (p, st) in enumerate((("float64", "o-"), ("30", "s--"), ("50", "^:"))):
            if p in r["err"]:
                e = np.maximum(np.array(r["err"][p]), 1e-80)
                ax.loglog(r["h"], e, st, ms=3, color=col[k], label=p if p == "float64" else f"mpmath {p} digits")
        ax.set_title(f"{r['method']} (order {r['order']})", fontsize=9)
        ax.set_xlabel("h")
        ax.set_ylabel("one-step error |(q1, v1) - exact|")
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[n:]:
        ax.remove()
    save(fig, path)


def stages(rows, path):
    fig, axes = figure(1, 3, figsize=(13, 3.6))
    axes = axes[0]
    fams = sorted({r["method"].rsplit("-", 1)[0] for r in rows}, key=len)
    col = colours(len(fams))
    for ax, cond in zip(axes, ("B", "C", "22b")):
        for fam, c in zip(fams, col):
            rr = [r for r in rows if r["method"].rsplit("-", 1)[0] == fam]
            s = [r["s"] for r in rr]
            ax.semilogy(s, [max(r["float64"][cond], 1e-80) for r in rr], "o-", ms=3, color=c, label=f"{fam} float64")
            ax.semilogy(s, [max(r["mp50"][cond], 1e-80) for r in rr], "x--", ms=3, color=c, label=f"{fam} 50 digits")
        ax.set_xlabel("stages s")
        ax.set_ylabel(f"max residual of {cond}")
        ax.set_title(f"{cond} residual of the coefficients")
    axes[0].legend(fontsize=6)
    save(fig, path)


def long_run(lr, rg, path):
    fig, axes = figure(1, 2, figsize=(11, 3.8))
    ax = axes[0][0]
    col = colours(4)
    st = np.array(lr["series"]["steps"][1:], float)
    ax.loglog(st, np.abs(lr["series"]["dE_kahan"][1:]), ".", ms=1, color=col[0], label="|E_n - E_0| Kahan")
    ax.loglog(st, np.abs(np.array(lr["series"]["dE_plain"][1:]) - np.array(lr["series"]["dE_kahan"][1:])),
              "-", lw=0.6, color=col[1], label=f"|E_plain - E_Kahan| (round-off, exponent {lr['gap_exponent']:.2f})")
    ax.loglog(st, np.array(lr["series"]["k_kahan"][1:]), ".", ms=1, color=col[2],
              label="|k(q_n, v_n)| (zeros not shown)")
    ax.loglog(st, 2.2e-16 * np.sqrt(st) * abs(lr["E0"]), "k:", label="eps sqrt(n) |E_0|")
    ax.set_xlabel("step n")
    ax.set_ylabel("energy error / constraint residual")
    ax.set_title(f"{lr['scene']}, {lr['method']}, h = {lr['h']}")
    ax.legend(fontsize=7, markerscale=8)
    ax = axes[0][1]
    N = np.array(rg["N"], float)
    for (k, e), c in zip(rg["rms"].items(), col):
        ax.loglog(N, e, color=c, label=f"{k} (exponent {rg['exponent'][k]:.2f})")
    ax.loglog(N, 2.2e-16 * np.sqrt(N), "k:", label="eps sqrt(N)")
    ax.set_xlabel("steps N")
    ax.set_ylabel("RMS round-off error in q")
    ax.set_title("round-off vs exact-arithmetic map (linear-3, Lobatto-2)")
    ax.legend(fontsize=7)
    save(fig, path)
