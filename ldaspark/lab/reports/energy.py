"""``ldaspark report energy``: the paper's Figs. 1-4 (section 8), energy error E - E0 vs t.

* Fig. 1: Gauss s = 1, 2, 3, h = 0.2, t in [0, 250], nonholonomic particle (8.1).
* Fig. 2: Lobatto IIIA-B s = 2, 3, 4, h = 0.1, t in [0, 100], skate (8.2).
* Fig. 3: Lobatto IIIA-B-D s = 2, 3, 4, h = 0.2, t in [0, 150], mobile robot (8.3).
* Fig. 4: McLachlan-Perlmutter particles (8.4), mu((E - E0)^2)/h^4 over J+1 = 10 initial
  conditions for Lobatto IIIA-B 2, its modified form and McLachlan-Perlmutter (26), from the
  compiled fast path ``ldaspark.lab.reports.fig4.figure4_data``.

"Bounded" (Figs. 1-3) is measured, not eyeballed: the maximum of |E - E0| over the last quarter
of the interval divided by that over the first quarter (a linear drift gives about 4, a
random walk about 2, a bounded error about 1) must be <= BOUNDED_RATIO; the max over the two
halves and the least-squares linear trend over the interval are reported too.
"""
from __future__ import annotations

import importlib
import importlib.util
import math
import os
import sys
import time

import numpy as np

from ...core.errors import InputError
from ...core.io import atomic_save_figure, atomic_write_json, atomic_write_text
from .markdown import cell, jsonable, num, sci, table, timing_line
from .plotting import colours, figure
from .timing import Clock

REPORT_DIR = "reports"
#: the files of the default report in OUTDIR (``driver.check_report_files``)
REPORT_FILES = ("energy.md", "energy.json")
BOUNDED_RATIO = 1.5
E0_PAPER = 3.06

FIGURES = {
    1: {"scene": "particle", "methods": ["gauss-1", "gauss-2", "gauss-3"], "h": 0.2, "t_end": 250.0,
        "caption": "s-stage Gauss SPARK, s = 1, 2, 3, h = 0.2, nonholonomic particle (8.1)"},
    2: {"scene": "skate", "methods": ["lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3", "lobatto-iiia-iiib-4"],
        "h": 0.1, "t_end": 100.0,
        "caption": "s-stage Lobatto IIIA-B SPARK, s = 2, 3, 4, h = 0.1, skate on an inclined plane (8.2)"},
    3: {"scene": "robot", "methods": ["lobatto-iiia-iiib-iiid-2", "lobatto-iiia-iiib-iiid-3",
                                      "lobatto-iiia-iiib-iiid-4"], "h": 0.2, "t_end": 150.0,
        "caption": "s-stage Lobatto IIIA-B-D SPARK, s = 2, 3, 4, h = 0.2, mobile robot (8.3)"},
}


#: Fig. 4's step, samples (one per FIG4_EVERY steps) and the fewest samples its growth fit over
#: [t_end / 100, t_end] takes (``fig4.fit_growth``)
FIG4_H, FIG4_EVERY, FIG4_MIN_SAMPLES = 0.05, 100, 3


def boundedness(t, dE):
    """Max |E - E0| overall, per half and per quarter; last/first quarter ratio; LS trend."""
    t = np.asarray(t, float)
    a = np.abs(np.asarray(dE, float))
    n = len(a)
    quarters = [float(a[i * n // 4:(i + 1) * n // 4 + 1].max()) for i in range(4)]
    halves = [float(a[:n // 2 + 1].max()), float(a[n // 2:].max())]
    slope = float(np.polyfit(t, np.asarray(dE, float), 1)[0])
    ratio = quarters[3] / quarters[0] if quarters[0] > 0 else float("inf")
    return {"max_abs_dE": float(a.max()), "max_first_half": halves[0], "max_second_half": halves[1],
            "max_quarters": quarters, "last_over_first_quarter": ratio,
            "trend_over_interval": slope * float(t[-1] - t[0]),
            "bounded": bool(ratio <= BOUNDED_RATIO)}


def figure_data(fig, t_end=None):
    """Integrate the methods of Fig. ``fig`` (1-3) in float64 on the compiled path
    (``ldaspark.compiled.fast``; the generic path if the scene cannot be compiled); returns a
    JSON-able dict."""
    from ...compiled.fast import fast_integrate
    from ...models.scenes import get_scene
    if fig not in FIGURES:
        raise InputError(f"figure must be 1, 2, 3 or 4, got {fig}")
    spec = FIGURES[fig]
    T = float(t_end) if t_end is not None else spec["t_end"]
    sc = get_scene(spec["scene"])
    t0, q0, v0 = sc.initial()
    n = int(round((T - float(t0)) / spec["h"]))
    if n <= 0:
        raise InputError(f"t_end = {T} gives no step of h = {spec['h']}")
    if abs(n * spec["h"] - (T - float(t0))) > 1e-9 * max(1.0, abs(T)):
        # rounded to the nearest step, the run ended elsewhere than the t_end it recorded
        # (--t-end 1.1 on Fig. 1 ran to 1.2); 1e-9 relative: decimal texts of multiples of h
        # (0.6 = 3 x 0.2 is 0.6000000000000001 in float64) are multiples, a tenth of a step is not
        raise InputError(f"t_end = {T:g} is not a multiple of Fig. {fig}'s step h = {spec['h']:g}")
    out = {"figure": fig, "scene": spec["scene"], "h": spec["h"], "t_end": T, "caption": spec["caption"],
           "bounded_ratio_threshold": BOUNDED_RATIO, "methods": {}}
    for m in spec["methods"]:
        tic = time.time()
        sol = fast_integrate(sc, m, h=spec["h"], n_steps=n)
        dE = sol.energy - sol.energy[0]
        rec = boundedness(sol.t, dE)
        rec.update({"E0": float(sol.energy[0]), "max_abs_constraint": float(np.abs(sol.constraint).max()),
                    "seconds": time.time() - tic, "stats": sol.stats,
                    "t": [float(x) for x in sol.t], "dE": [float(x) for x in dE]})
        out["methods"][m] = rec
        print(f"    Fig. {fig} {m}: {n} steps ({sol.stats.get('path', 'fast')} path) in {rec['seconds']:.1f} s",
              flush=True)
    return out


def plot_energy(data, path):
    ms = list(data["methods"].items())
    fig, axes = figure(len(ms), 1, figsize=(9, 2.4 * len(ms)), sharex=True)
    for ax, (m, rec), c in zip(axes[:, 0], ms, colours(len(ms))):
        ax.plot(rec["t"], rec["dE"], lw=0.6, color=c, label=f"{m} (max |E - E0| = {rec['max_abs_dE']:.2e})")
        ax.set_ylabel("E - E0")
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
    axes[-1, 0].set_xlabel("t")
    fig.suptitle(f"Fig. {data['figure']}: energy error, {data['caption']}", fontsize=9)
    _save(fig, path)


def _save(fig, path):
    atomic_save_figure(fig, path, dpi=90)


# --- Fig. 4 (data from the fast path of ldaspark.lab.reports.fig4) ------------------------------------------
def fig4_available() -> bool:
    return importlib.util.find_spec("ldaspark.lab.reports.fig4") is not None


def figure4(t_end=50000.0, h=FIG4_H, J=9, every=FIG4_EVERY, constraint="printed", executor=None):
    """Call ``ldaspark.lab.reports.fig4.figure4_data`` and add checks: E0 = 3.06 and an independent LS fit
    of log(mu/h^4) against log t over t >= t_end/100 (the paper: mu/h^4 ~ O(t))."""
    if not fig4_available():
        raise InputError("Fig. 4 needs ldaspark.lab.reports.fig4 (the compiled fast path), which is not installed")
    fig4 = importlib.import_module("ldaspark.lab.reports.fig4")
    tic = time.time()
    print(f"    Fig. 4: figure4_data(t_end={t_end}, h={h}, J={J}, every={every}, constraint={constraint!r}) ...",
          flush=True)
    d = fig4.figure4_data(t_end=t_end, h=h, J=J, every=every, constraint=constraint, executor=executor)
    out = {"figure": 4, "scene": d.get("scene", "mp-particles"), "constraint": constraint,
           "h": h, "t_end": t_end, "J": J, "every": every,
           "seconds": time.time() - tic, "t": [float(x) for x in d["t"]], "E0": float(d["E0"]),
           "E0_matches_paper": bool(abs(float(d["E0"]) - E0_PAPER) < 1e-12),
           "methods": list(d["methods"]), "mu_over_h4": {}, "fit": {}, "own_fit": {}}
    t = np.asarray(out["t"], float)
    for m in out["methods"]:
        y = np.asarray(d["mu_over_h4"][m], float)
        out["mu_over_h4"][m] = [float(x) for x in y]
        out["fit"][m] = {k: (float(v) if isinstance(v, (int, float, np.floating)) else v)
                         for k, v in dict(d["fit"][m]).items()}
        sel = (t >= t[-1] / 100) & (y > 0)
        out["own_fit"][m] = (float(np.polyfit(np.log(t[sel]), np.log(y[sel]), 1)[0])
                             if sel.sum() >= 2 else None)
    return out


def check_fig4_t_end(t_end) -> None:
    """Refuse, in words of the command line, a --t-end that Fig. 4 cannot take: a whole number of
    its sampling intervals (FIG4_EVERY steps of FIG4_H = 5 time units) and at least
    FIG4_MIN_SAMPLES of them (the fit). ``fig4.figure4_data`` refuses the same with its internal
    names ("n_steps = 240 must be a multiple of every = 100"), which no option of the command sets."""
    if t_end is None:
        return
    dt = FIG4_H * FIG4_EVERY
    k = round(t_end / dt)
    if abs(k * dt - t_end) > 1e-9 * max(1.0, abs(t_end)) or k < FIG4_MIN_SAMPLES:
        raise InputError(f"--t-end of Fig. 4 must be a multiple of {dt:g} (one sample every {FIG4_EVERY} steps of "
                         f"h = {FIG4_H:g}) and at least {FIG4_MIN_SAMPLES * dt:g} (the growth fit takes "
                         f"{FIG4_MIN_SAMPLES} samples), got {t_end:g}")


def plot_fig4(data, path):
    fig, axes = figure(1, 2, figsize=(12, 4.2))
    a1, a2 = axes[0]
    t = np.asarray(data["t"], float)
    for m, c in zip(data["methods"], colours(len(data["methods"]))):
        y = np.asarray(data["mu_over_h4"][m], float)
        ex = data["fit"][m].get("exponent")
        lab = f"{m} (fit exponent {ex:.3f})" if isinstance(ex, float) else m
        pos = (t > 0) & (y > 0)
        a1.loglog(t[pos], y[pos], lw=0.7, color=c, label=lab)
        a2.plot(t, y, lw=0.7, color=c, label=lab)
    tt = t[t > 0]
    if len(tt):
        ref = np.asarray(data["mu_over_h4"][data["methods"][0]], float)[t > 0]
        k = ref[-1] / tt[-1] if ref[-1] > 0 else 1.0
        a1.loglog(tt, k * tt, "k--", lw=0.8, label="slope 1 (paper: O(t))")
    for ax, title in ((a1, "log-log"), (a2, "linear")):
        ax.set_xlabel("t")
        ax.set_ylabel("mu((E - E0)^2) / h^4")
        ax.set_title(f"Fig. 4 ({title}), {data.get('constraint', 'printed')} constraint, h = {num(data['h'])}, "
                     f"J+1 = {data['J'] + 1}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    _save(fig, path)


# --- markdown -------------------------------------------------------------------------------------
def markdown(figs, fig4=None, fig4_note=None, clock=None, command="ldaspark report energy"):
    L = ["# Energy behaviour (paper, section 8, Figs. 1-4)", "",
         "Generated by `ldaspark report energy` (per figure: `ldaspark report energy --figure N --json FILE`)."
         " Same scenes, methods, step sizes and intervals as the paper, in float64 on the compiled path"
         " (`ldaspark.compiled.fast`). Data (subsampled arrays and all numbers) in `reports/energy.json`.", "",
         f"**Bounded** means: max |E - E0| over the last quarter of the interval / max over the first quarter"
         f" <= {BOUNDED_RATIO} (linear drift would give ~4, a random walk ~2). The least-squares linear"
         " trend of E - E0 over the whole interval is listed as a second, independent indicator.", ""]
    for d in figs:
        L += [f"## Fig. {d['figure']}: {d['caption']}, t in [0, {d['t_end']:g}]", "",
              f"![Fig. {d['figure']}](figures/energy_fig{d['figure']}.png)", ""]
        L += table(["method", "max abs(E - E0)", "max 1st half", "max 2nd half", "last/first quarter",
                    "linear trend over interval", "max abs(k)", "bounded"],
                   [[m, sci(r["max_abs_dE"], 3), sci(r["max_first_half"], 3), sci(r["max_second_half"], 3),
                     f"{r['last_over_first_quarter']:.3f}", sci(r["trend_over_interval"], 2),
                     sci(r["max_abs_constraint"]), "yes" if r["bounded"] else "NO"] for m, r in d["methods"].items()])
        L.append("")
    L += ["## Fig. 4: McLachlan-Perlmutter particles (8.4)", "",
          "The constraint printed in 8.4, v1 + sum_{i=m+2}^{n} q_i v_i = 0, is integrable: it is"
          " d/dt (q1 + sum_{i>=m+2} q_i^2 / 2) = 0, so the printed scene is a *holonomically* constrained"
          " Hamiltonian system. We therefore run Fig. 4 twice: on the printed scene (`mp-particles`) and"
          " on the nonholonomic variant v1 + sum_{i=m+2}^{n} q_{i-m} v_i = 0 (`mp-particles-nh`; the"
          " generalization of the nonholonomic particle v3 - q2 v1 = 0 of 8.1, which we take the printed"
          " q_i to be a typo for). Same methods, h, interval and initial data (E0 = 3.06 for both).", ""]
    f4s = fig4 if isinstance(fig4, list) else ([fig4] if fig4 is not None else [])
    for f in f4s:
        L += _fig4_markdown(f)
    if not f4s:
        L.append(fig4_note or "Fig. 4 was not generated.")
    if clock is not None:
        L += ["", timing_line(command, clock)]
    return "\n".join(L) + "\n"


def fig4_png_name(d):
    return "energy_fig4.png" if d.get("constraint", "printed") == "printed" else "energy_fig4_nh.png"


def _fig4_markdown(fig4):
    L = [f"### Fig. 4, {fig4.get('constraint', 'printed')} constraint (scene `{fig4.get('scene', 'mp-particles')}`)", "",
         f"h = {num(fig4['h'])}, t in [0, {fig4['t_end']:g}], J+1 = {fig4['J'] + 1} initial conditions, samples every"
         f" {fig4['every']} steps; data from `ldaspark.lab.reports.fig4.figure4_data` in {fig4['seconds']:.1f} s.", "",
         f"E0 = {fig4['E0']:.15g} (paper: 3.06; {'matches' if fig4['E0_matches_paper'] else 'DOES NOT MATCH'}).", "",
         f"![Fig. 4](figures/{fig4_png_name(fig4)})", ""]
    L += table(["method", "fitted exponent (fig4)", "own LS exponent, t >= t_end/100", "final mu/h^4"],
               [[m, _exp(fig4["fit"][m].get("exponent")), _exp(fig4["own_fit"][m]), sci(fig4["mu_over_h4"][m][-1], 3)]
                for m in fig4["methods"]])
    exps = {m: fig4["fit"][m].get("exponent") for m in fig4["methods"]}
    ok = [m for m, e in exps.items() if isinstance(e, float) and abs(e - 1) <= 0.3]
    t4 = np.asarray(fig4["t"], float)
    late = [float(np.mean(np.asarray(fig4["mu_over_h4"][m], float)[t4 >= t4[-1] / 2])) for m in fig4["methods"]]
    L += ["", "The paper reports mu((E - E0)^2)/h^4 ~ O(t) (a random walk), i.e. growth exponent 1, and that"
          " the three methods behave very similarly.", "",
          f"**Observed:** growth exponent within 0.3 of 1 for {len(ok)} of {len(exps)} methods"
          f" ({', '.join(f'{m}: {e:.3f}' for m, e in exps.items() if isinstance(e, float))}); "
          + ("the random-walk growth is reproduced." if len(ok) == len(exps) else
             "the O(t) growth is NOT reproduced (an exponent near 0 means no growth, near 1 a random walk).")
          + f" The means of mu/h^4 over the second half of the interval are within a factor"
          f" {max(late) / min(late):.2f} of each other"
          f" ({', '.join(f'{m}: {x:.3e}' for m, x in zip(fig4['methods'], late))}).", ""]
    return L


def _exp(x):
    return f"{x:.3f}" if isinstance(x, float) else cell(x)


def _strip(d, max_points=2000):
    """Subsample the arrays of a figure dict for the committed JSON."""
    d = dict(d)
    if "methods" in d and isinstance(d["methods"], dict):
        ms = {}
        for m, r in d["methods"].items():
            r = dict(r)
            n = len(r["t"])
            k = max(1, -(-n // max_points))
            r["t"], r["dE"] = r["t"][::k], r["dE"][::k]
            ms[m] = r
        d["methods"] = ms
    return d


def _strip4(d, max_points=1000):
    """Fig. 4 dict with its sample arrays subsampled (the plots use the full data)."""
    if d is None:
        return None
    d = dict(d)
    k = max(1, -(-len(d["t"]) // max_points))
    d["t"] = d["t"][::k]
    d["mu_over_h4"] = {m: v[::k] for m, v in d["mu_over_h4"].items()}
    d["subsampled_every"] = k
    return d


# --- section interface --------------------------------------------------------------------------
def add_arguments(p):
    p.add_argument("--figure", type=int, choices=(1, 2, 3, 4), default=None,
                   help="one figure (default: Figs. 1-3, and Fig. 4 when ldaspark.lab.reports.fig4 exists)")
    p.add_argument("--t-end", type=float, default=None, help="shorter interval (default: the paper's)")
    p.add_argument("--json", default=None, help="write the figure data (JSON) to FILE")
    p.add_argument("--outdir", default=None, help="also write the PNG(s) here (default: reports/ when no --json)")
    # default None (= printed with --figure 4): given with another figure, or without --figure
    # (which runs Fig. 4 for both constraints), it is refused, not ignored
    p.add_argument("--mp-constraint", choices=("printed", "nonholonomic"), default=None,
                   help="with --figure 4: the constraint as printed in 8.4 (integrable, the default) or its "
                        "nonholonomic variant")


def run(args) -> int:
    clock = Clock()
    if args.t_end is not None and not (math.isfinite(args.t_end) and args.t_end > 0):
        raise InputError(f"--t-end must be a finite positive number, got {args.t_end}")
    from ...core.io import check_destination
    check_destination(args.json)            # a directory at --json: refused now, not after the runs
    if args.outdir or not args.json:        # the PNGs go to OUTDIR/figures (reports/ by default)
        from .driver import check_figures_dir
        check_figures_dir(args.outdir or REPORT_DIR)
    if getattr(args, "mp_constraint", None) is not None and args.figure != 4:
        raise InputError("--mp-constraint chooses the scene of Fig. 4: give it with --figure 4 (without --figure "
                         "Fig. 4 runs with both constraints; Figs. 1-3 have no such scene)")
    if args.figure is None:
        if args.json:
            raise InputError("--json needs --figure N")
        if fig4_available():
            check_fig4_t_end(args.t_end)    # the default run's Fig. 4 is shortened too
        from .driver import check_report_files
        check_report_files(args.outdir or REPORT_DIR, REPORT_FILES)
        run_default(args.outdir or REPORT_DIR, t_end=args.t_end)
        return 0
    if args.figure == 4:
        check_fig4_t_end(args.t_end)
        d = figure4(t_end=args.t_end if args.t_end is not None else 50000.0, constraint=args.mp_constraint or "printed")
        if args.json:
            atomic_write_json(args.json, d)
        if args.outdir or not args.json:
            plot_fig4(d, os.path.join(args.outdir or REPORT_DIR, "figures", fig4_png_name(d)))
        print(f"Fig. 4: E0 = {d['E0']:.15g}; exponents: " + ", ".join(
            f"{m} {_exp(d['fit'][m].get('exponent'))}" for m in d["methods"]))
    else:
        d = figure_data(args.figure, args.t_end)
        if args.json:
            atomic_write_json(args.json, d)
            print(f"wrote {args.json}")
        if args.outdir or not args.json:
            plot_energy(d, os.path.join(args.outdir or REPORT_DIR, "figures", f"energy_fig{args.figure}.png"))
        for m, r in d["methods"].items():
            print(f"Fig. {args.figure} {m}: max |E - E0| = {r['max_abs_dE']:.3e}, last/first quarter "
                  f"{r['last_over_first_quarter']:.3f}, bounded: {r['bounded']}")
    print(f"[energy] {clock.summary()}", flush=True)
    return 0


# --- jobs of the main job (see ldaspark.lab.reports.jobs) -----------------------------------------
FIG4_CONSTRAINTS = ("printed", "nonholonomic")


def fig4_job(constraint, inline=True, t_end=None):
    """Fig. 4 for one constraint; ``inline``: its runs one after the other in this process (in
    the main job, which already keeps every core busy); ``t_end``: a shorter interval (default the
    paper's). A failure is reported in energy.md, not hidden."""
    from .jobs import InlineExecutor
    if not fig4_available():
        return {"note": "Fig. 4 pending: `ldaspark.lab.reports.fig4` (the compiled fast path) is not installed yet."}
    try:
        return figure4(t_end=50000.0 if t_end is None else t_end, constraint=constraint,
                       executor=InlineExecutor() if inline else None)
    except Exception as exc:  # the fast path is another module: report, do not hide
        note = f"Fig. 4 ({constraint}) failed: {type(exc).__name__}: {exc}"
        print(note, file=sys.stderr, flush=True)
        return {"note": note}


# jobs on the compiled path (started after the main job has compiled the kernels once)
COMPILED_JOBS = ("figure_data", "fig4_job")


def jobs(full=False, t_end=None):
    """Figs. 1-3 (``t_end``: a shorter interval) and Fig. 4 for both constraints."""
    return ([(("fig", n), "figure_data", (n, t_end), 3.0) for n in FIGURES]
            + [(("fig4", c), "fig4_job", (c,), 30.0) for c in FIG4_CONSTRAINTS])


def write(results, outdir=REPORT_DIR, full=False, clock=None, command="ldaspark report energy"):
    figs = [results[("fig", n)] for n in FIGURES]
    for d in figs:
        plot_energy(d, os.path.join(outdir, "figures", f"energy_fig{d['figure']}.png"))
    f4, notes = [], []
    for c in FIG4_CONSTRAINTS:
        d4 = results.get(("fig4", c))
        if d4 is None:
            continue
        if "note" in d4:
            notes.append(d4["note"])
            continue
        plot_fig4(d4, os.path.join(outdir, "figures", fig4_png_name(d4)))
        f4.append(d4)
    note = "; ".join(notes) or None
    atomic_write_text(os.path.join(outdir, "energy.md"), markdown(figs, f4, note, clock, command))
    atomic_write_json(os.path.join(outdir, "energy.json"),
                      jsonable({"figures": [_strip(d, 1000) for d in figs],
                                "figure4": _strip4(f4[0]) if f4 else None,
                                "figure4_nonholonomic": _strip4(f4[1]) if len(f4) > 1 else None,
                                "figure4_note": note}))
    print(f"wrote {os.path.join(outdir, 'energy.md')}, energy.json, figures/energy_fig*.png", flush=True)


def run_default(outdir=REPORT_DIR, t_end=None, with_fig4=True):
    clock = Clock()
    results = {}
    for key, fn, args, _ in jobs(False, t_end):
        if key[0] == "fig4" and not with_fig4:
            continue
        print(f"[energy] {key[0]} {key[1]} ...", flush=True)
        # --t-end shortens Fig. 4 too (it ran the paper's 1e6 steps per run whatever --t-end said)
        results[key] = fig4_job(args[0], inline=False, t_end=t_end) if key[0] == "fig4" else figure_data(*args)
    write(results, outdir, clock=clock)
