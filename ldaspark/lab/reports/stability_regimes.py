"""Sections of ``reports/stability.md`` on the extremes of h: the regimes table (top of the report),
the stiffness sweep (section 7) and whole runs at tiny h with the error curve's round-off floor
(section 8). Data from ``stability_stiff`` through the jobs of ``stability``."""
from __future__ import annotations

from .markdown import sci, table
from .stability_stiff import DE_BOUND, DE_GROWTH, HW, N_STIFF, OMEGA, STIFF_METHODS, STIFF_SCENES, TINY_H


def family(method):
    """(family, s) of a method name."""
    if method.startswith("euler"):
        return "euler-i/ii", 1
    fam, s = method.rsplit("-", 1)
    return fam, int(s)


def _records(d):
    """(engine, family, h, h omega, dps, s, N, worst) from every measurement of the report;
    worst = (rank, text): failures rank above errors, larger errors above smaller."""
    R = []

    def add(engine, method, h=None, hw=None, dps=None, N=None, worst=None):
        fam, s = family(method)
        R.append((engine, fam, h, hw, dps, s, N, worst))
    for r in d.get("tiny", []):
        w = ((2, f"{r['outcome']} at h = {r['h']:g} ({r['method']}, {r['scene']})") if r["outcome"] != "ok"
             else (0, r["max_dE"], f"max abs dE {sci(r['max_dE'])} ({r['method']}, {r['scene']}, h = {r['h']:g}, "
                                   f"N = {r['N']:.0e})"))
        add("compiled float64", r["method"], h=r["h"], N=r["N"], worst=w)
    for r in d.get("stiff", []):
        if r["outcome"] != "ok":
            w = (1, -r["hw"], f"{r['outcome']} from h omega = {r['hw']:g} ({r['method']}, {r['scene']}: {r['why']})")
        else:
            w = (0, 0.0, "")
        add("compiled float64", r["method"], h=r["h"], hw=r["hw"], N=r["N"], worst=w)
    for f in d.get("floor", []):
        for h, n, e in zip(f["h"], f["N"], f["kahan"]):
            add("compiled float64", f["method"], h=h, N=n, worst=(0, 0.0, ""))
    for lr in d.get("long", []):
        add("compiled float64", lr["method"], h=0.05, N=10 ** 6,
            worst=(0, 0.0, ""))
    for r in d.get("step", []):
        for prec in ("float64", "30", "50"):
            eng, dps = ("generic float64", None) if prec == "float64" else ("generic mpmath", int(prec))
            for h in r["h"]:
                add(eng, r["method"], h=h, dps=dps, N=1, worst=(0, 0.0, ""))
        for a, b in r["newton"]:
            if b is not None:
                add("generic float64", r["method"], h=b, N=1,
                    worst=(1, -b, f"NewtonError from h = {b:g} ({r['method']}, Newton limit, section 1)"))
            if a is not None:
                add("generic float64", r["method"], h=a, N=1, worst=(0, 0.0, ""))
    for o50, o64 in d.get("order", []):
        add("generic mpmath", o50["method"], dps=50, N=8, h=0.25, worst=(0, 0.0, ""))
        add("generic float64", o64["method"], N=8, h=0.25, worst=(0, 0.0, ""))
    for a, b in d.get("reversal", []):
        add("generic float64", a["method"], h=0.05, N=200, worst=(0, 0.0, ""))
        add("generic mpmath", b["method"], h=0.05, dps=30, N=2 * b["N"], worst=(0, 0.0, ""))
    for r in d.get("dps", []):
        add("generic mpmath", "gauss-2", h=0.1, dps=r["dps"], N=r["N"], worst=(0, 0.0, ""))
    return R


def _rng(vals, fmt):
    vals = [v for v in vals if v is not None]
    if not vals:
        return "-"
    lo, hi = min(vals), max(vals)
    return fmt(lo) if lo == hi else f"{fmt(lo)} .. {fmt(hi)}"


def regimes(d):
    """Rows {engine, family, h, hw, dps, s, N, worst} aggregated over ``_records``."""
    groups = {}
    for rec in _records(d):
        groups.setdefault((rec[0], rec[1]), []).append(rec)
    rows = []
    for (eng, fam), recs in sorted(groups.items()):
        worst = max((r[7] for r in recs), key=lambda w: w[:2])
        rows.append({"engine": eng, "family": fam,
                     "h": _rng([r[2] for r in recs], lambda x: f"{x:g}"),
                     "hw": _rng([r[3] for r in recs], lambda x: f"{x:g}"),
                     "dps": _rng([r[4] for r in recs], str) if eng == "generic mpmath" else "float64",
                     "s": _rng([r[5] for r in recs], str),
                     "N": _rng([r[6] for r in recs], lambda x: f"{x:.0e}" if x >= 1000 else str(x)),
                     "worst": worst[-1] or "no failure"})
    return rows


def section_regimes(d):
    L = ["## Regimes run here", "",
         "For each engine and family: the ranges of step size h, stiffness h omega (section 7), working "
         "precision, stage count s and number of steps N of the runs in this report, and the worst failure "
         "seen (a failure of the stage equations on every engine, or NaN; 'no failure': every run finished). "
         "Errors of the finished runs are in the sections named.", ""]
    L += table(["engine", "family", "h", "h omega", "dps", "s", "N", "worst seen"],
               [[r["engine"], r["family"], r["h"], r["hw"], r["dps"], r["s"], r["N"], r["worst"]] for r in regimes(d)])
    return L + [""]


# --- section 7: stiffness --------------------------------------------------------------------
def stiff_summary(d):
    """Per (scene, method): the largest h omega with every run up to it bounded, the first
    h omega that is not (class and why), the largest h omega with rho(M) <= 1, Newton
    iterations per step at h omega = 1, 10, 100, and the steps taken by the generic engine."""
    out = []
    for sc in STIFF_SCENES:
        for m in STIFF_METHODS:
            rows = sorted((r for r in d["stiff"] if r["scene"] == sc and r["method"] == m), key=lambda r: r["hw"])
            if not rows:
                continue
            ok_to, first = None, None
            for r in rows:
                if r["class"] == "bounded" and first is None:
                    ok_to = r["hw"]
                elif first is None:
                    first = r
            lin = max((r["hw"] for r in rows if r["rho"] <= 1 + 1e-9), default=None)
            it = {r["hw"]: r.get("iterations") for r in rows}
            out.append({"scene": sc, "method": m, "bounded_to": ok_to,
                        "first": None if first is None else {"hw": first["hw"], "class": first["class"],
                                                             "why": first["why"], "outcome": first["outcome"]},
                        "linear_stable_to": lin, "unstable_linear": [r["hw"] for r in rows if r["rho"] > 1 + 1e-9],
                        "iterations": {k: it.get(k) for k in (1.0, 10.0, 100.0)},
                        "generic_steps": sum(r.get("generic_steps") or 0 for r in rows),
                        "full_newton_steps": sum(r.get("full_newton_steps") or 0 for r in rows)})
    return out


def _cell(r):
    if r["outcome"] != "ok":
        b = r.get("dE_before")
        return f"failed step {r.get('step')} ({r['why']}" + ("" if b is None else f", dE before {sci(b, 1)}") + ")"
    return f"{r['class'][0]} {sci(r['max_rel_dE'], 1)} ({r['iterations']:.1f})"


def section_stiff(d):
    S = stiff_summary(d)
    L = ["## 7. Stiff forces: h omega from 1e-2 to 1e4", "",
         f"Two stiff nonholonomic oscillators with omega = {OMEGA}: the skate of 8.2 in U = omega^2 |q|^2 / 2 "
         "(stiff-skate: the blade angle q3 oscillates too, so the constraint direction turns at the stiff "
         "frequency; q0 = (1, 0, 1/2), v0 = (0, 0, omega/2)) and the particle of 8.1 in U = omega^2 (q1^2 + q2^2) "
         "/ 2 (stiff-particle; q0 = (1, 0, 0), v0 = (0, omega, 0)). Whole runs of N = "
         f"{N_STIFF} steps of h = (h omega) / omega on the compiled engine with its Newton fallbacks (fresh matrix, "
         "full Newton, the generic full-Newton step). Energy (8) is conserved by the exact flow; dE = max_n "
         "abs(E_n - E_0) / E_0. Class: b = bounded (the maximum of dE over the second half of the run is at most "
         f"{DE_GROWTH:g} times that over the first half), g = growing, failed = the stage equations were not "
         "solved by any engine (or NaN). Why: 'linear instability' where rho(M(h omega)) > 1 for the step matrix "
         "of (21) on the unconstrained oscillator (computed from the tableau, "
         "`ldaspark.lab.reports.stability_stiff.linear_stability`; for Gauss its eigenvalues are R(+-i h omega), "
         "abs(R(i h omega)) = 1: A-stable); 'energy growth' where rho <= 1 but the energy grew (the nonlinear "
         "coupling through the constraint); 'Newton' where a run failed while dE was still below "
         f"{DE_BOUND:g} (dE before = the same run stopped one step before the failure).", "",
         "![stiffness sweep](figures/stability_stiff.png)", ""]
    L += table(["scene", "method", "bounded up to h omega", "first not bounded", "linear theory: rho <= 1 up to",
                "Newton it./step at h omega = 1 / 10 / 100", "steps by full Newton / generic step"],
               [[r["scene"], r["method"], "-" if r["bounded_to"] is None else f"{r['bounded_to']:g}",
                 "-" if r["first"] is None else f"{r['first']['hw']:g}: {r['first']['class']} ({r['first']['why']})",
                 "-" if r["linear_stable_to"] is None else (f"{r['linear_stable_to']:g}" if not r["unstable_linear"]
                                                           else f"{r['linear_stable_to']:g} (rho > 1 from "
                                                                f"{min(r['unstable_linear']):g})"),
                 " / ".join("-" if v is None else f"{v:.1f}" for v in r["iterations"].values()),
                 f"{r['full_newton_steps']} / {r['generic_steps']}"] for r in S])
    for sc in STIFF_SCENES:
        L += ["", f"{sc}: class, dE and Newton iterations per step, per h omega:", ""]
        rows = [r for r in d["stiff"] if r["scene"] == sc]
        L += table(["h omega"] + list(STIFF_METHODS),
                   [[f"{hw:g}"] + [next((_cell(r) for r in rows if r["method"] == m and r["hw"] == hw), "-")
                                   for m in STIFF_METHODS] for hw in HW])
    return L + [""]


# --- section 8: tiny steps, whole runs ----------------------------------------------------------
def section_tiny(d):
    tiny, floor = d["tiny"], d["floor"]
    fails = [r for r in tiny if r["outcome"] != "ok"]
    N = max(r["N"] for r in tiny)
    L = ["## 8. Tiny steps along whole runs, and the round-off floor of the error curve", "",
         f"Every family with s <= 3 on the paper scenes, whole runs of N = {N:.0e} steps at h = "
         + ", ".join(f"{h:g}" for h in TINY_H) + " on the compiled engine (`fast_integrate`; "
         "lobatto-iiia-iiib-2 on the semi-implicit kernel of (25)); 1e5 steps with `--full` and in "
         "tests/core/test_newton_stopping.py --exhaustive. Before this rule the kernels' Newton limit was a multiple of h, "
         "below the rounding of the stage values V_i = v0 + Z_i at small h: the skate with gauss-2 stopped at step "
         "25808 at h = 1e-5 and 88513 at h = 1e-6. Now the limit is tol (abs(x) + abs(v0)), and: "
         f"{len(tiny) - len(fails)} of {len(tiny)} runs finish.", ""]
    hdr = ["scene", "method"] + [f"h = {h:g}" for h in TINY_H]
    rows = []
    for sc in dict.fromkeys(r["scene"] for r in tiny):
        for m in dict.fromkeys(r["method"] for r in tiny if r["scene"] == sc):
            cells = []
            for h in TINY_H:
                r = next((x for x in tiny if x["scene"] == sc and x["method"] == m and x["h"] == h), None)
                if r is None:
                    cells.append("-")
                elif r["outcome"] != "ok":
                    cells.append(f"{r['outcome']}: `{r['message']}`")
                else:
                    extra = "".join(f", {r[k]} {lab}" for k, lab in (("full_newton_steps", "full"),
                                                                     ("generic_steps", "generic")) if r.get(k))
                    cells.append(f"{r['iterations']:.2f} it.{extra}, dE {sci(r['max_dE'], 1)}")
            rows.append([sc, m] + cells)
    L += ["Per run: Newton iterations per step (full = steps that needed the kernel's full-Newton fallback, "
          "generic = steps taken by the generic engine), max abs(E_n - E_0).", ""]
    L += table(hdr, rows)
    L += ["", "Global error of the skate at t = 0.1 against its closed form (8.2) as h decreases (N = 0.1 / h steps, "
          "up to 1e6), plain and compensated (Kahan) summation of the q, v updates: the truncation error C h^p "
          "until the round-off floor, which then grows with N.", "",
          "![error against h down to 1e-7](figures/stability_floor.png)", ""]
    L += table(["method", "min error plain (at h)", "min error Kahan (at h)", "error at h = 1e-7 plain / Kahan"],
               [[f["method"], f"{sci(min(f['plain']))} ({f['h'][f['plain'].index(min(f['plain']))]:g})",
                 f"{sci(min(f['kahan']))} ({f['h'][f['kahan'].index(min(f['kahan']))]:g})",
                 f"{sci(f['plain'][-1])} / {sci(f['kahan'][-1])}"] for f in floor])
    dps = d["dps"]
    L += ["", "Extreme precision (generic engine, mpmath): the skate, gauss-2, h = 1/10, "
          + ", ".join(f"dps = {r['dps']}: {r['N']} steps in {r['seconds']:.2f} s, {r['iterations']:.1f} Newton "
                      f"it./step, difference to the run at {r.get('ref_dps', r['dps'] + 40)} digits "
                      f"1e{r['log10_diff']:.0f}" if r["log10_diff"] is not None
                      else f"dps = {r['dps']}: identical to the run at {r.get('ref_dps', r['dps'] + 40)} digits"
                      for r in dps)
          + " (earlier, dps >= 324 raised ZeroDivisionError: the unit round-off was a float and "
          "underflowed to 0).", ""]
    return L


def findings_lines(d):
    """The issue-22 bullets of the findings."""
    S = stiff_summary(d)
    tiny = d["tiny"]
    nfail = sum(r["outcome"] != "ok" for r in tiny)
    gauss = [r for r in S if r["method"].startswith("gauss")]
    fmt = lambda r: ("all" if r["first"] is None else f"{r['first']['hw']:g} ({r['first']['why']})")  # noqa: E731
    out = [f"* Tiny steps: {len(tiny) - nfail} of {len(tiny)} whole runs (s <= 3, 4 paper scenes, h = 1e-4 .. 1e-7) "
           "finish on the compiled engine (section 8); the Newton limit is the round-off of the stage values, not a "
           "multiple of h. Error floor of the skate at t = 0.1: "
           + "; ".join(f"{f['method']} {sci(min(f['plain']))} plain, {sci(min(f['kahan']))} Kahan" for f in d["floor"])
           + "."]
    def first(m, sc):
        r = next((x for x in S if x["method"] == m and x["scene"] == sc), None)
        return None if r is None else r

    def lim(m):
        return " / ".join(fmt(r) for sc in STIFF_SCENES for r in [first(m, sc)] if r is not None)
    big = [r for r in d["stiff"] if r["method"].startswith("gauss") and r["class"] == "bounded" and r["hw"] >= 3]
    newton = sorted({(r["method"], r["scene"], r["hw"]) for r in d["stiff"] if r["why"] == "Newton"})
    its = [r["iterations"] for r in d["stiff"] if r["outcome"] == "ok" and r["hw"] == 1.0]
    small = [r["iterations"] for r in d["stiff"] if r["outcome"] == "ok" and r["hw"] <= 0.1]
    unst = {m: min((x for r in S if r["method"] == m for x in r["unstable_linear"]), default=None)
            for m in ("lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3")}
    out.append("* Stiff forces (section 7; first h omega not bounded, stiff-skate / stiff-particle): "
               + "; ".join(f"{m}: {lim(m)}" for m in STIFF_METHODS) + ". "
               f"Gauss (rho(M) = abs(R(i h omega)) = 1 at every h omega, {len(gauss)} scene-method pairs): the "
               "energy error stays bounded far beyond h omega = 1"
               + (f", but at O(1) ({sci(min(r['max_rel_dE'] for r in big), 1)} .. "
                  f"{sci(max(r['max_rel_dE'] for r in big), 1)} relative for h omega >= 3: the stiff motion is not "
                  "resolved, only kept bounded)" if big else "")
               + "; where they stop it is Newton, with the energy error still small ("
               + ", ".join(f"{m} {sc} at {hw:g}" for m, sc, hw in newton)
               + ": the Newton matrix, with entries from 1 to (h omega)^2, is numerically singular, pivot ratio "
               "1e-18 .. 1e-20, on both engines), or (gauss-1) "
               "an energy growth through the constraint coupling although rho = 1. Lobatto IIIA-B: the linear "
               "theory gives rho > 1 from h omega = "
               + " (s = 2, Stormer-Verlet: bound 2) and ".join(f"{v:g}" for v in unst.values() if v is not None)
               + " (s = 3); the 3-stage runs stop exactly there (linear instability), the 2-stage runs already "
               "from h omega ~ 1 (the nonlinear coupling through the constraint lowers the limit). Newton "
               f"iterations per step: {min(small):.1f} .. {max(small):.1f} at h omega <= 0.1, "
               f"{min(its):.1f} .. {max(its):.1f} at h omega = 1 (the extrapolating predictor misses an unresolved "
               "oscillation), ~5 beyond.")
    return out
