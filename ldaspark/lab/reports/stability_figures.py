"""Figures of the stability report (``ldaspark.lab.reports.stability``): one-step error against h,
coefficient residuals against s, and the long-run energy / round-off panels."""
from __future__ import annotations

import numpy as np

from ...core.io import atomic_save_figure
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


def stiff(rows, methods, scenes, path):
    """Section 7: per method, dE against h omega on each stiff scene (failed runs drawn at the
    top as x), and the linear prediction rho(M(h omega)) - 1 where it exceeds 0."""
    cols = 4
    nr = (len(methods) + cols - 1) // cols
    fig, axes = figure(nr, cols, figsize=(4 * cols, 3.2 * nr))
    col = colours(len(scenes) + 1)
    for ax, m in zip(axes.flat, methods):
        for sc, c in zip(scenes, col):
            rr = sorted((r for r in rows if r["method"] == m and r["scene"] == sc), key=lambda r: r["hw"])
            ok = [r for r in rr if r["outcome"] == "ok"]
            ax.loglog([r["hw"] for r in ok], [max(r["max_rel_dE"], 1e-17) for r in ok], "o-", ms=3, color=c, label=sc)
            bad = [r["hw"] for r in rr if r["outcome"] != "ok"]
            if bad:
                ax.loglog(bad, [1e3] * len(bad), "x", ms=6, color=c, label=f"{sc}: failed")
        rr = sorted({r["hw"]: r["rho"] for r in rows if r["method"] == m}.items())
        un = [(hw, rho - 1) for hw, rho in rr if rho > 1 + 1e-9]
        if un:
            ax.loglog(*zip(*un), "k:", lw=1, label="rho(M) - 1 (linear)")
        ax.set_title(m, fontsize=9)
        ax.set_xlabel("h omega")
        ax.set_ylabel("max relative energy error")
        ax.legend(fontsize=6)
    for ax in list(axes.flat)[len(methods):]:
        ax.remove()
    save(fig, path)


def floor(rows, path):
    """Section 8: global error at t = 0.1 on the skate against h, plain and Kahan."""
    fig, axes = figure(1, len(rows), figsize=(4 * len(rows), 3.3))
    for ax, r in zip(axes.flat, rows):
        ax.loglog(r["h"], np.maximum(r["plain"], 1e-18), "o-", ms=3, label="plain")
        ax.loglog(r["h"], np.maximum(r["kahan"], 1e-18), "s--", ms=3, label="Kahan")
        ax.set_title(r["method"], fontsize=9)
        ax.set_xlabel("h (N = 0.1 / h)")
        ax.set_ylabel("error at t = 0.1")
        ax.legend(fontsize=7)
    save(fig, path)
