"""``ldaspark report convergence``: observed orders of q, v, Psi against the paper's claims
(section 7: Gauss s-stage order 2s, Lobatto IIIA-B and IIIA-B-D s-stage order 2s-2; 7.3-7.4:
the standard Gauss IRK has order 1 (s=1), 2 (s=2)), on the four scenes of section 8.

Writes reports/convergence.md, reports/convergence.json and log-log plots
reports/figures/convergence_<family>.png. Methods of claimed order >= 6 run in mpmath
(``MP_DPS`` digits) so that the float64 round-off floor does not hide the order.
"""
from __future__ import annotations

import os
import sys
import time

from ..theory.orders import claimed_order_of, verdict, make_reference, measure_errors, order_records
from ...core.errors import InputError
from ...core.io import atomic_save_figure, atomic_write_json, atomic_write_text
from ...models.scenes import GENERAL_SCENES, PAPER_SCENES, get_scene
from .markdown import sci, table, timing_line
from .plotting import colours, figure
from .timing import Clock

REPORT_DIR = "reports"
#: the files of the report in OUTDIR (``driver.check_report_files``)
REPORT_FILES = ("convergence.md", "convergence.json")
T_END = 1.0
MP_DPS = 25
REF_DPS = 40
TOLERANCE = 0.3          # |observed - claimed| allowed for the verdict "holds"

FAMILIES = {
    "gauss": [f"gauss-{s}" for s in range(1, 5)],
    "lobatto-iiia-iiib": [f"lobatto-iiia-iiib-{s}" for s in range(2, 6)],
    "lobatto-iiia-iiib-iiid": [f"lobatto-iiia-iiib-iiid-{s}" for s in range(2, 6)],
    "standard-gauss-irk": ["gauss-irk-1", "gauss-irk-2"],
    "comparators-8.4": ["lobatto-iiia-iiib-2-modified", "mp-lobatto-iiib-a-2"],
}


def plan_for(method):
    """(dps, list of N, newton) for a method: float64 and more steps for low orders; mpmath
    beyond, with the Newton matrix in float64 ("mixed": same fixed point, 2-5x cheaper)."""
    p = claimed_order_of(method) or 2
    if p <= 2:
        return None, [8, 16, 32, 64, 128], "full"
    if p <= 4:
        return None, [4, 8, 16, 32, 64], "full"
    return MP_DPS, [5, 10, 20, 40], "mixed"


_REFERENCES = {}     # per process: a scene's reference serves every method run on it here


def reference_for(scene_name, t_end=T_END, log=None):
    """The scene's reference, built once per process (``make_reference``) and evaluated at t_end
    first, so that its Taylor segments are laid out exactly as in a fresh run."""
    key = (scene_name, REF_DPS, float(t_end))
    if key not in _REFERENCES:
        t = time.time()
        ref = make_reference(get_scene(scene_name), REF_DPS)
        ref(t_end)
        _say(log, f"  {scene_name}: reference ({ref.kind}, {REF_DPS} digits) in {time.time() - t:.1f} s")
        _REFERENCES[key] = ref
    return _REFERENCES[key]


def run_scene(scene_name, methods, t_end=T_END, log=None):
    """All records of one scene for ``methods`` (one reference per scene and process)."""
    scene = get_scene(scene_name)
    ref = reference_for(scene_name, t_end, log)
    recs = []
    for meth in methods:
        if scene_name in GENERAL_SCENES and meth == "mp-lobatto-iiib-a-2":
            continue   # semi-implicit comparator: needs L = v^T M v/2 - U(q), k = K(q) v + b(q)
        why = not_of_its_form(meth, scene_name)
        if why:
            _say(log, f"  {scene_name} {meth:26s} skipped: {why}")
            continue
        dps, nl, newton = plan_for(meth)
        t = time.time()
        m = measure_errors(meth, scene, ref, t_end, nl, dps=dps, newton=newton)
        r = order_records(meth, scene_name, claimed_order_of(meth), m, dps, t_end, ref.kind)
        recs.extend(r)
        obs = ", ".join(f"{x['variable']} {_fmt(x['observed_order'])}" for x in r)
        _say(log, f"  {scene_name} {meth:26s} claimed {claimed_order_of(meth)}: {obs}  ({time.time() - t:.1f} s)")
    return recs


def not_of_its_form(meth, scene_name):
    """Why comparator ``meth`` cannot run on the scene (``comparators.require_mechanical``: the
    semi-implicit ones need the mechanical form), else None. The bicycle ran every other method
    (5 minutes at --t-end 0.1), then mp-lobatto-iiib-a-2 raised and nothing was written."""
    from ...core.comparators import require_mechanical
    system = get_scene(scene_name).system       # an unknown scene: its own error
    try:
        require_mechanical(meth, system)
    except InputError as exc:
        return str(exc)
    return None


def _say(log, msg):
    print(msg, file=log or sys.stdout, flush=True)


def _fmt(x, nd=2):
    return "-" if x is None else f"{x:.{nd}f}"


def _scene_job(args):
    scene_name, methods, t_end = args
    return run_scene(scene_name, methods, t_end)


# the four paper scenes, the nonholonomic variant of 8.4 (the printed 8.4 constraint is integrable), general scenes
DEFAULT_SCENES = tuple(PAPER_SCENES) + ("mp-particles-nh",) + tuple(GENERAL_SCENES)


def compute(scenes=DEFAULT_SCENES, methods=None, t_end=T_END, workers=2):
    """Records for every (scene, method); scenes run in parallel processes (progress printed)."""
    methods = methods or [m for fam in FAMILIES.values() for m in fam]
    jobs = [(s, methods, t_end) for s in scenes]
    t = time.time()
    print(f"[convergence] {len(scenes)} scenes x {len(methods)} methods, t_end = {t_end}, "
          f"{workers} worker(s)", flush=True)
    if workers > 1 and len(jobs) > 1:
        from ...core.lifecycle import make_process_pool
        # no more workers than scenes: a fork pool starts all of them at once (--workers 24
        # forked 24 processes for 2 scenes)
        with make_process_pool(max_workers=min(workers, len(jobs))) as ex:   # workers die with this process
            parts = list(ex.map(_scene_job, jobs))
    else:
        parts = [_scene_job(j) for j in jobs]
    print(f"[convergence] done in {time.time() - t:.1f} s", flush=True)
    return [r for p in parts for r in p]




# --- output -------------------------------------------------------------------------------------
def plot_family(records, family, methods, path):
    """Log-log error against h, one row per scene, one column per variable with data (the
    comparators have no stage multipliers, so their figure has no Psi column)."""
    scenes = list(dict.fromkeys(r["scene"] for r in records))
    fam = [r for r in records if r["method"] in methods and any(e > 0 for e in r["errors"])]
    variables = [v for v in ("q", "v", "psi") if any(r["variable"] == v for r in fam)]
    scenes = [sc for sc in scenes if any(r["scene"] == sc for r in fam)]
    if not variables or not scenes:
        return
    fig, axes = figure(len(scenes), len(variables), figsize=(4.4 * len(variables), 3.2 * len(scenes)))
    col = dict(zip(methods, colours(len(methods))))
    for i, sc in enumerate(scenes):
        t_end = next((r["t_end"] for r in records if r["scene"] == sc), T_END)
        for j, var in enumerate(variables):
            ax = axes[i][j]
            for meth in methods:
                r = next((r for r in fam if r["scene"] == sc and r["method"] == meth and r["variable"] == var), None)
                if r is None:
                    continue
                pts = [(h, e) for h, e in zip(r["h"], r["errors"]) if e > 0]
                lab = f"{meth} (obs {_fmt(r['observed_order'])}" + (
                    f", claim {r['claimed_order']})" if r["claimed_order"] is not None else ")")
                ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-", ms=3, color=col[meth], label=lab)
            ax.set_xlabel("step size h")
            ax.set_ylabel(f"error in {var}" + (" (stages of last step)" if var == "psi" else f" at t = {t_end:g}"))
            ax.set_title(f"{sc}: {var}")
            # major decades only: the minor log ticks and their grid were a third of the cost of
            # drawing these 27-panel figures (6.5 -> 4.5 s CPU for one family)
            ax.minorticks_off()
            ax.grid(True, which="major", alpha=0.3)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=6)
    fig.suptitle(f"Global error vs step size: {family}")
    atomic_save_figure(fig, path, dpi=90)


def markdown(records, clock=None, identities=None, command="ldaspark report convergence", outdir=REPORT_DIR):
    # the run's own final time(s) and output directory (a run with --t-end 3 --outdir c3 said "T = 1"
    # and "reports/")
    ts = sorted({float(r["t_end"]) for r in records if r.get("t_end") is not None}) or [T_END]
    T = ", ".join(f"{t:g}" for t in ts)
    d = os.path.relpath(outdir) if os.path.isabs(str(outdir)) else str(outdir)
    d = d.replace(os.sep, "/").rstrip("/")
    L = ["# Convergence orders (paper, sections 7 and 7.3-7.4)", "",
         f"Generated by `ldaspark report convergence` (this file, `{d}/convergence.json` and"
         f" `{d}/figures/convergence_*.png`; records only: `ldaspark report convergence --json FILE`)."
         f" Every number below is in `{d}/convergence.json`.", "",
         f"**What is measured.** Global error at T = {T} for q and v (inf-norm) for steps h = 1/N; the"
         " observed order is the least-squares slope of log(error) vs log(h) over the *asymptotic"
         " window* (consecutive points above the round-off floor 1e3 x unit round-off x max(1,|ref|)"
         " whose errors strictly decrease); pairwise orders log(e_j/e_{j+1})/log(2) are listed too."
         " Psi is a stage quantity: its error is max over the stages of the last step of"
         " |Psi_i - psi(T - h + c_i h)| with psi of the reference. Methods of claimed order >= 6 run in"
         f" mpmath at {MP_DPS} digits, the others in float64.", "",
         "**References.** skate: the closed-form solution. particle, robot, mp-particles, mp-particles-nh (the"
         " nonholonomic variant of 8.4; the printed 8.4 constraint is integrable) and the general scenes"
         f" ({', '.join(GENERAL_SCENES)}: t in L and k, k nonlinear in v, b != 0, L not quadratic in v): the underlying"
         f" ODE (3a-b) integrated by mpmath's Taylor-series solver (`mpmath.odefun`) at {REF_DPS} digits"
         " (a method unrelated to any SPARK method); psi(t) from (3a-b) at the reference state.", "",
         f"**Verdict** `holds` when |observed - claimed| <= {TOLERANCE}.", ""]
    holds = [r for r in records if r["claimed_order"] is not None]
    for scope, title in (("variable", "Section 7 (SPARK: Gauss order 2s, Lobatto 2s-2; q and v each)"),
                         ("method", "Sections 7.3-7.4 (standard Gauss IRK: order 1 for s = 1, 2 for s = 2;"
                                    " method order = min over q, v)")):
        rs = [r for r in holds if r["claim_scope"] == scope]
        if not rs:
            continue
        n_ok = sum(verdict(r, records) == "holds" for r in rs)
        L += [f"**{title}:** {n_ok} of {len(rs)} (method, scene, variable) checks hold.", ""]
        fails = [r for r in rs if verdict(r, records) != "holds"]
        for r in fails:
            L.append(f"- {r['method']} on {r['scene']}, {r['variable']}: {verdict(r, records)}; claimed {r['claimed_order']},"
                     f" observed {_fmt(r['observed_order'])} (pairwise {', '.join(_fmt(p) for p in r['pairwise_orders'])})")
        if fails:
            L.append("")
    for fam, methods in FAMILIES.items():
        rows = []
        for r in records:
            if r["method"] not in methods:
                continue
            w = r["window"]
            win = f"{r['h'][w[0]]:.4g} .. {r['h'][w[1]]:.4g}" if w else "-"
            rows.append([r["method"], r["scene"], r["variable"], r["claimed_order"], _fmt(r["observed_order"]),
                         ", ".join(_fmt(p) for p in r["pairwise_orders"]), win, sci(min(r["errors"]), 2),
                         "float64" if r["dps"] is None else f"{r['dps']} digits", verdict(r, records)])
        L += [f"## {fam}", "", f"![{fam}](figures/convergence_{fam}.png)", ""]
        L += table(["method", "scene", "var", "claimed", "observed (LS)", "pairwise", "window (h)",
                    "smallest error", "precision", "verdict"], rows) + [""]
    L += _observations(records)
    if identities is not None:
        L += [""] + comparator_markdown(identities)
    if clock is not None:
        L += ["", timing_line(command, clock)]
    return "\n".join(L) + "\n"


def _observations(records):
    L = ["## Observations", ""]
    irk = [r for r in records if r["method"].startswith("gauss-irk-")]
    if irk:
        L.append("- **Standard Gauss IRK (7.3-7.4).** Observed orders q / v / psi, and the method order"
                 " min(q, v), per scene:")
        for meth in ("gauss-irk-1", "gauss-irk-2"):
            groups = {"holds": [], "HIGHER than claimed": [], "FAILS": [], "NO WINDOW": []}
            for sc in dict.fromkeys(r["scene"] for r in irk):
                rs = [r for r in irk if r["method"] == meth and r["scene"] == sc]
                if not rs:
                    continue
                o = {r["variable"]: r["observed_order"] for r in rs}
                qv = [o.get("q"), o.get("v")]
                mo = None if None in qv else min(qv)
                L.append(f"  - {meth}, {sc}: {_fmt(o.get('q'))} / {_fmt(o.get('v'))} / {_fmt(o.get('psi'))};"
                         f" method order {_fmt(mo)} (claimed {rs[0]['claimed_order']})")
                groups.setdefault(verdict(rs[0], records), []).append(sc)
            L.append(f"  - {meth}: claim holds on {', '.join(groups['holds']) or 'no scene'}; higher than claimed on"
                     f" {', '.join(groups['HIGHER than claimed']) or 'no scene'}.")
        psi1 = [r["scene"] for r in irk if r["method"] == "gauss-irk-1" and r["variable"] == "psi"
                and r["observed_order"] is not None and abs(r["observed_order"] - 1) <= TOLERANCE]
        L.append("  Reading: an order above the claim means the order reduction did not show (the claim is a"
                 " statement about general problems). Order 2 in v for s = 2 and order 2 in q and v for s = 1 agree"
                 " with the index-2 convergence results for Gauss methods (Hairer-Wanner, vol. II, VII.4: y-error"
                 " O(h^s) for even s, O(h^(s+1)) for odd s); for s = 1 order 1 is seen only in Psi,"
                 f" on {', '.join(psi1) or 'no scene'}. On the robot, q3 stays 0, so K(q) is constant along the solution, the stage"
                 " constraints imply k(t1, q1, v1) = 0 and nothing is lost. The constraint defect"
                 " k(t1, q1, v1) != 0 is tested in `verification/test_order_reduction_7_3_7_4.py`.")
    ps = [r for r in records if r["variable"] == "psi" and not r["method"].startswith("gauss-irk-")]
    if ps:
        L.append("- **Psi (no claim in the paper).** Observed stage-multiplier orders (min .. max over scenes):")
        for meth in dict.fromkeys(r["method"] for r in ps):
            os_ = [r["observed_order"] for r in ps if r["method"] == meth and r["observed_order"] is not None]
            exact = [r["scene"] for r in ps if r["method"] == meth and r["observed_order"] is None]
            if os_:
                L.append(f"  - {meth}: {min(os_):.2f} .. {max(os_):.2f}"
                         + (f" (at round-off on {', '.join(exact)})" if exact else ""))
    return L


def comparator_identities(h=0.1, n=30):
    """Max differences |q|, |v| between comparators and the SPARK method (7.5, 8.4), and grad U
    evaluations per step; float64, n steps of h from each scene's initial data."""
    from ...core.comparators import integrate_comparator
    from ...core.spark import integrate
    from ...core.families import get_method
    pairs = [("lobatto-iiia-iiib-2-leapfrog", "lobatto-iiia-iiib-2"),
             ("euler-i-ii-composition", "lobatto-iiia-iiib-2"),
             ("euler-ii-i-composition", "lobatto-iiia-iiib-2"),
             ("euler-i-ii-composition", "lobatto-iiia-iiib-2-modified"),
             ("euler-ii-i-composition", "mp-lobatto-iiib-a-2"),
             ("lobatto-iiia-iiib-2-modified", "lobatto-iiia-iiib-2"),
             ("lobatto-iiia-iiib-2-modified", "lobatto-iiia-iiib-2-modified-leapfrog"),
             ("mp-lobatto-iiib-a-2", "lobatto-iiia-iiib-2")]
    scenes = list(PAPER_SCENES) + ["rolling-disk"]
    rows, counts = [], {}
    for sc_name in scenes:
        sc = get_scene(sc_name)
        t0, q0, v0 = sc.initial()
        sols = {}
        for name in dict.fromkeys([x for p in pairs for x in p]):
            if name == "lobatto-iiia-iiib-2":
                sols[name] = integrate(sc.system, get_method(name), t0, q0, v0, h, n_steps=n)
            else:
                sols[name] = integrate_comparator(name, sc.system, t0, q0, v0, h, n)
        for a, b in pairs:
            d = max(float(abs(sols[a].q - sols[b].q).max()), float(abs(sols[a].v - sols[b].v).max()))
            rows.append({"scene": sc_name, "a": a, "b": b, "max_diff": d})
        counts[sc_name] = {k: sols[k].stats.get("n_grad_U", sols[k].stats.get("nfev")) / n for k in sols}
    defect = {}
    for sc_name in PAPER_SCENES:
        sc = get_scene(sc_name)
        t0, q0, v0 = sc.initial()
        defect[sc_name] = {}
        for s in (1, 2):
            irk = integrate_comparator(f"gauss-irk-{s}", sc.system, t0, q0, v0, h, n)
            spk = integrate(sc.system, get_method(f"gauss-{s}"), t0, q0, v0, h, n_steps=n)
            defect[sc_name][f"gauss-irk-{s}"] = float(abs(irk.constraint).max())
            defect[sc_name][f"gauss-{s}"] = float(abs(spk.constraint).max())
    return {"h": h, "n_steps": n, "rows": rows, "grad_U_per_step": counts, "constraint_defect": defect}


def comparator_markdown(ci):
    scenes = list(ci["grad_U_per_step"])
    L = ["## Comparators of 7.5 and 8.4: identities and differences", "",
         f"max(|q_a - q_b|, |v_a - v_b|) over {ci['n_steps']} steps of h = {ci['h']} (float64); tested in"
         " `verification/test_comparators_7_5_8_4.py`. rolling-disk is not a paper scene: its K(q) is"
         " nonlinear in q, which separates the mean-of-K constraint (25) from the midpoint constraint of 8.4.", "",
         ]
    pairs = list(dict.fromkeys((r["a"], r["b"]) for r in ci["rows"]))
    rows = []
    for a, b in pairs:
        vals = {r["scene"]: r["max_diff"] for r in ci["rows"] if (r["a"], r["b"]) == (a, b)}
        rows.append([a, b] + [sci(vals[s]) for s in scenes])
    L += table(["method a", "method b"] + scenes, rows)
    def mx(a, b, only=None, skip=None):
        v = [r["max_diff"] for r in ci["rows"] if (r["a"], r["b"]) == (a, b)
             and (only is None or r["scene"] in only) and (skip is None or r["scene"] not in skip)]
        return max(v) if v else float("nan")

    paper = [s for s in scenes if s != "rolling-disk"]
    L += ["", "Findings (each a test): the leapfrog form equals the SPARK method (max difference"
          f" {mx('lobatto-iiia-iiib-2-leapfrog', 'lobatto-iiia-iiib-2'):.1e}); Euler II then I (h/2 each) differs"
          f" from it (min {min(r['max_diff'] for r in ci['rows'] if (r['a'], r['b']) == ('euler-ii-i-composition', 'lobatto-iiia-iiib-2')):.1e})"
          f" and is McLachlan-Perlmutter's (26) (max {mx('euler-ii-i-composition', 'mp-lobatto-iiib-a-2'):.1e});"
          f" Euler I then II is the modified method of 8.4 (max {mx('euler-i-ii-composition', 'lobatto-iiia-iiib-2-modified'):.1e}),"
          f" which on the four paper scenes cannot be told from Lobatto IIIA-B (max"
          f" {mx('lobatto-iiia-iiib-2-modified', 'lobatto-iiia-iiib-2', only=paper):.1e}: there the mean-of-K"
          " constraint (25) and the midpoint constraint have the same zero set) but on the rolling disk can"
          f" ({mx('lobatto-iiia-iiib-2-modified', 'lobatto-iiia-iiib-2', only=['rolling-disk']):.1e}).", "",
          "grad U (or grad_q L for the Newton-solved forms) evaluations per step:", ""]
    L += table(["method"] + scenes, [[m] + [f"{ci['grad_U_per_step'][s][m]:.2f}" for s in scenes]
                                     for m in ci["grad_U_per_step"][scenes[0]]])
    if "constraint_defect" in ci:
        cd = ci["constraint_defect"]
        sc_d = list(cd)
        L += ["", f"Constraint defect max_n |k(t_n, q_n, v_n)| over {ci['n_steps']} steps of h = {ci['h']}: the"
              " standard Gauss IRK (7.3-7.4) against the SPARK method with the same coefficients:", ""]
        L += table(["method"] + sc_d, [[m] + [sci(cd[s][m]) for s in sc_d] for m in cd[sc_d[0]]])
    L += ["", "The semi-implicit forms (leapfrog, modified-leapfrog, McLachlan-Perlmutter) evaluate grad U once"
          " per step (plus one at the end for the leapfrog forms' output velocity); the Newton-solved"
          " SPARK forms evaluate grad_q L at every stage point of every iteration.", ""]
    return L


def write_outputs(records, outdir, clock=None, identities=None, command="ldaspark report convergence"):
    figdir = os.path.join(outdir, "figures")
    for fam, methods in FAMILIES.items():
        if any(r["method"] in methods for r in records):
            plot_family(records, fam, methods, os.path.join(figdir, f"convergence_{fam}.png"))
    ident = comparator_identities() if identities is None else identities
    atomic_write_text(os.path.join(outdir, "convergence.md"), markdown(records, clock, ident, command, outdir))
    atomic_write_json(os.path.join(outdir, "convergence.json"), records)
    print(f"wrote {os.path.join(outdir, 'convergence.md')}, convergence.json, figures/convergence_*.png", flush=True)


# --- jobs of the main job (see ldaspark.lab.reports.jobs): one per scene, and the comparator table ---
def all_methods():
    return [m for fam in FAMILIES.values() for m in fam]


# rough CPU seconds of a scene's job on an idle core (to start the longest first)
_SCENE_COST = {"mp-particles": 16.0, "mp-particles-nh": 15.0, "relativistic": 15.0, "constant-speed": 15.0,
               "turntable": 10.0, "rheonomic-skate": 9.0, "particle": 8.0, "robot": 8.0, "skate": 4.0}


def jobs(full=False):
    """One job per scene: its reference (an mpmath Taylor solution of (3a-b), the most expensive
    single piece for several scenes) is built once and serves all methods; the comparator table."""
    J = [(("scene", sc), "_scene_job", ((sc, all_methods(), T_END),), _SCENE_COST.get(sc, 15.0))
         for sc in DEFAULT_SCENES]
    return J + [(("identities",), "comparator_identities", (), 4.0)]


def write(results, outdir=REPORT_DIR, full=False, clock=None, command="ldaspark report convergence"):
    recs = []
    for sc in DEFAULT_SCENES:                 # the order of a serial run: scene, then method
        part = [r for k, v in results.items() if k[0] == "scene" and k[1] == sc for r in v]
        recs += [r for m in all_methods() for r in part if r["method"] == m]
    write_outputs(recs, outdir, clock, results[("identities",)], command)
    return recs


# --- section interface --------------------------------------------------------------------------
def add_arguments(p):
    p.add_argument("--json", default=None, help="write the records (JSON list) to FILE")
    p.add_argument("--scenes", nargs="+", default=list(DEFAULT_SCENES),
                   help="scenes (default: the four of section 8 and mp-particles-nh)")
    p.add_argument("--methods", nargs="+", default=None,
                   help="method names (default: Gauss 1-4, Lobatto IIIA-B and IIIA-B-D 2-5, gauss-irk-1,2)")
    p.add_argument("--t-end", type=float, default=T_END)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--outdir", default=None,
                   help="also write convergence.md and figures here (default: only when --json is not given)")


#: the longest --t-end: the references are mpmath Taylor solutions of (3a-b) at REF_DPS digits,
#: seconds per unit of time on the section 8 scenes (1e308 computed until killed)
T_END_MAX = 100.0


def run(args) -> int:
    if not 0 < args.t_end <= T_END_MAX:
        raise InputError(f"--t-end must be in (0, {T_END_MAX:g}] (the references are mpmath Taylor solutions, "
                         f"seconds per unit of time), got {args.t_end:g}")
    from ...core.io import check_destination, check_distinct_outputs
    from ...solve import resolve_method
    # a scene or method named twice runs once (it ran twice: its records twice in the JSON, the
    # table and the figures, and its reference computed twice)
    args.scenes = list(dict.fromkeys(args.scenes))
    args.methods = list(dict.fromkeys(args.methods)) if args.methods else args.methods
    for m in args.methods or ():
        resolve_method(m)               # an unknown method is one line before any reference is built
        for sc in args.scenes:          # one it cannot run: refused now, not skipped in silence
            why = not_of_its_form(m, sc)
            if why:
                raise InputError(f"--methods {m} cannot run on the scene {sc}: {why}")
    check_destination(args.json)
    if args.outdir or not args.json:
        from .driver import check_figures_dir, check_report_files
        check_report_files(args.outdir or REPORT_DIR, REPORT_FILES)      # convergence.json too
        md = os.path.join(args.outdir or REPORT_DIR, "convergence.md")
        check_distinct_outputs(("the report OUTDIR/convergence.md", md), ("--json", args.json))
        check_figures_dir(args.outdir or REPORT_DIR)
    clock = Clock()
    recs = compute(args.scenes, args.methods, args.t_end, args.workers)
    if args.json:
        atomic_write_json(args.json, recs)
        print(f"wrote {args.json} ({len(recs)} records)")
    if args.outdir or not args.json:
        write_outputs(recs, args.outdir or REPORT_DIR, clock)
    bad = [r for r in recs if verdict(r, recs) not in ("holds", "no claim")]
    for r in bad:
        print(f"{verdict(r, recs)}: {r['method']} {r['scene']} {r['variable']}: claimed "
              f"{r['claimed_order']}, observed {_fmt(r['observed_order'])}")
    print(f"[convergence] {clock.summary()}", flush=True)
    return 0


def run_default(outdir=REPORT_DIR):
    clock = Clock()
    recs = compute()
    write_outputs(recs, outdir, clock)
