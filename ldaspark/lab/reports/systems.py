"""``ldaspark report systems``: the classic nonholonomic systems
(``ldaspark.models.systems_classic``), one table row each, and their invariant errors vs time.

Per system (one job each, on the compiled path):

* the first integrals (and the closed-form observable: the ball's distance from the axis)
  along T = 500 with h = 0.1 for the symmetric Gauss-2 and Lobatto IIIA-B 3 and the
  non-symmetric control Euler I (shorter where its Newton fails: ``CONTROL``), with the
  boundedness measure of ``reports.energy`` (max over the last quarter / the first quarter:
  bounded <= 1.5, drift >= 2; at round-off when <= 100 eps sqrt(N) (1 + |I0|));
* the observed orders of Gauss-2 (claimed 4) and Lobatto IIIA-B 2 / 3 (claimed 2 / 4) from
  N = 4, 8, 16, 32 steps over [0, 1] against the closed form where there is one, else scipy's
  DOP853 on (3a-b) at rtol 1e-13 (independent of SPARK; the 40-digit Taylor references are in
  ``verification/test_systems_*.py``);
* max |k| along the run and the compiled cost per step (Gauss-2, best of 3 runs of 2000 steps,
  compile time excluded and reported apart).

The Whipple bicycle has its own module: see ``BICYCLE_MODULE``.
"""
from __future__ import annotations

import importlib
import importlib.util
import math
import os
import sys
import time

import numpy as np

from ...core.io import atomic_save_figure, atomic_write_json, atomic_write_text
from .markdown import jsonable, num, sci, table, timing_line
from .plotting import colours, figure
from .timing import Clock

REPORT = "systems.md"
JSON = "systems.json"
REPORT_FILES = (REPORT, JSON)           # ``driver.check_report_files``
FIG = "systems_invariants.png"
SYSTEMS = ("chaplygin-sleigh", "tilted-disk", "chaplygin-sphere", "suslov", "contact-oscillator",
           "ball-turntable", "ball-turntable-rheonomic")
SYMMETRIC = ("gauss-2", "lobatto-iiia-iiib-3")
T_LONG, H_LONG = 500.0, 0.1
# the non-symmetric control (Euler I): (T, h) per system; shorter where its Newton fails later on
# longer runs where a slow drift needs them to show (Suslov: the symmetric methods drift too)
T_LONG_OF = {"suslov": 2000.0}
NOTES = {"suslov": "the Suslov flow has an attracting relative equilibrium (omega -> (0, W, 0)), so it is not"
                   " reversible-integrable, the property Modin-Verdier (Numer. Math. 2020) identify behind the"
                   " bounded energy errors of symmetric nonholonomic integrators; the symmetric methods drift"
                   " slowly here (Gauss-2's drift rate falls ~64-fold when h is halved:"
                   " verification/test_systems_suslov.py). The sleigh, also attracted to a relative equilibrium,"
                   " does not drift: an observation, not a proven cause"}
CONTROL = {"tilted-disk": (8.0, 0.02), "chaplygin-sphere": (80.0, 0.05), "suslov": (25.0, 0.05)}
ORDER_METHODS = (("gauss-2", 4), ("lobatto-iiia-iiib-2", 2), ("lobatto-iiia-iiib-3", 4))
ORDER_N = (4, 8, 16, 32)
BOUNDED_RATIO, DRIFT_RATIO = 1.5, 2.0
EPS = 2.0 ** -52

# --- the bicycle hook ---------------------------------------------------------------------------
# The Whipple bicycle has its own module, ldaspark/lab/reports/systems_bicycle.py, with
# ``bicycle_section(outdir) -> (markdown_str, json_dict)``: the section runs it as one more job
# (``bicycle_job``) and appends its markdown after the table and its data under the key "bicycle"
# of systems.json. A failure there is reported in systems.md and does not stop the main job.
BICYCLE_MODULE = "ldaspark.lab.reports.systems_bicycle"


def bicycle_available() -> bool:
    return importlib.util.find_spec(BICYCLE_MODULE) is not None


def bicycle_job(outdir="reports"):
    """{"markdown", "json"} of ``systems_bicycle.bicycle_section(outdir)``, or {"error"}: a failure
    of the other module is reported in systems.md, not hidden, and does not stop the main job."""
    try:
        mod = importlib.import_module(BICYCLE_MODULE)
        md, data = mod.bicycle_section(outdir)
    except Exception as exc:  # noqa: BLE001  (reported in the section, the rest of the job goes on)
        note = f"{type(exc).__name__}: {exc}"
        _log(f"bicycle section failed: {note}")
        return {"error": note}
    return {"markdown": md, "json": data}


def _log(msg):
    print(f"[systems] {msg}", file=sys.stderr, flush=True)


# --- measurements ----------------------------------------------------------------------------------
def _initial(name):
    """(scene, q0, v0) of the long runs: the scenes' data, the disk perturbed off its steady
    motion (theta' = 0.3) so that the run is quasi-periodic rather than a relative equilibrium."""
    from ...models.scenes import get_scene
    sc = get_scene(name)
    _, q0, v0 = sc.initial()
    if name == "tilted-disk":
        v0 = list(v0)
        v0[3] = 0.3
    return sc, q0, v0


def _observables(name, sc):
    obs = {}
    if name.startswith("ball-turntable"):
        rho = float(sc.params["rho"])
        obs["radius - rho (closed form)"] = lambda t, q, v: np.hypot(q[:, 0], q[:, 1]) - rho
    return obs


def _series(sc, res, extra):
    out, I0 = {}, {}
    for k, x in sc.invariant_values(res.t, res.q, res.v).items():
        out[k] = x - x[0]
        I0[k] = float(x[0])
    for k, f in extra.items():
        out[k] = np.asarray(f(res.t, res.q, res.v), float)
        I0[k] = 0.0
    return out, I0


def _bounded(t, e, n_steps, I0):
    from .energy import boundedness
    b = boundedness(t, e)
    rnd = b["max_abs_dE"] <= 100 * EPS * math.sqrt(n_steps) * (1 + abs(I0))
    r = b["last_over_first_quarter"]
    return {"max": b["max_abs_dE"], "quarters": b["max_quarters"], "ratio": r if math.isfinite(r) else None,
            "roundoff": bool(rnd), "bounded": bool(rnd or r <= BOUNDED_RATIO),
            "drift": bool(not rnd and r >= DRIFT_RATIO)}


def _subsample(t, e, k=400):
    step = max(1, len(t) // k)
    return [float(x) for x in t[::step]], [float(abs(x)) for x in e[::step]]


def _reference(name, sc, t_end):
    if sc.exact is not None:
        from ..theory.orders import ExactReference
        return ExactReference(sc, 30), "closed form"
    from ..claims.claims_general import DOP853Reference
    t0, q0, v0 = sc.initial()
    return DOP853Reference(sc.system, t0, q0, v0, t_end), "DOP853 on (3a-b), rtol 1e-13"


def _orders(name, sc):
    """Observed orders (LS over the asymptotic window, q and v) of ORDER_METHODS on the compiled path."""
    from ...compiled.fast import fast_integrate
    from ..theory.orders import estimate_order, floor_for
    ref, kind = _reference(name, sc, 1.0)
    qr, vr, _ = ref(1.0)
    qr, vr = np.array([float(x) for x in qr]), np.array([float(x) for x in vr])
    t0, q0, v0 = sc.initial()
    out = {}
    for meth, p in ORDER_METHODS:
        hs, eq, ev = [], [], []
        for N in ORDER_N:
            sol = fast_integrate(sc, meth, h=1.0 / N, n_steps=N)
            hs.append(1.0 / N)
            eq.append(float(np.abs(sol.q[-1] - qr).max()))
            ev.append(float(np.abs(sol.v[-1] - vr).max()))
        oq = estimate_order(hs, eq, floor_for(None, float(np.abs(qr).max()))).observed_order
        ov = estimate_order(hs, ev, floor_for(None, float(np.abs(vr).max()))).observed_order
        out[meth] = {"claimed": p, "q": oq, "v": ov, "errors_q": eq, "errors_v": ev}
    return out, kind


def system_job(name, t_long=T_LONG):
    """Everything the report says about one system (JSON-able)."""
    from ...compiled.fast import compile_system, fast_integrate
    from ...solve import integrate
    tic, c0 = time.perf_counter(), time.process_time()
    sc, q0, v0 = _initial(name)
    S = sc.system
    t_build = time.perf_counter() - tic
    tc = time.perf_counter()
    cs = compile_system(S)
    cs.model  # noqa: B018  (build or load the model now, timed apart from the steps)
    t_compile = time.perf_counter() - tc
    extra = _observables(name, sc)
    runs = {}
    for meth in SYMMETRIC + ("euler-i",):
        T_sym = max(t_long, T_LONG_OF.get(name, 0.0)) if t_long == T_LONG else t_long
        T, h = (T_sym, H_LONG) if meth != "euler-i" else CONTROL.get(name, (t_long, H_LONG))
        n = int(round(T / h))
        sol = integrate(sc, meth, t_span=(0.0, T), h=h, q0=q0, v0=v0, engine="compiled")
        series, I0 = _series(sc, sol, extra)
        recs = {k: _bounded(sol.t, e, n, I0[k]) for k, e in series.items()}
        for k, e in series.items():
            recs[k]["t"], recs[k]["abs_err"] = _subsample(sol.t, e)
        runs[meth] = {"T": T, "h": h, "steps": n, "status": int(sol.status), "t_end_reached": float(sol.t[-1]),
                      "max_abs_k": float(np.abs(sol.constraint).max()),
                      "k_bound": float(100 * EPS * (1 + np.abs(sol.q).max()) * (1 + np.abs(sol.v).max())),
                      "invariants": recs}
    best = math.inf
    for _ in range(3):
        t1 = time.perf_counter()
        fast_integrate(sc, "gauss-2", 0.0, q0, v0, H_LONG, 2000)
        best = min(best, time.perf_counter() - t1)
    orders, ref_kind = _orders(name, sc)
    return {"name": name, "n": S.n, "m": S.m, "form": cs.form, "description": sc.description, "source": sc.source,
            "invariants": list(sc.invariants) + list(extra), "closed_forms": list(sc.closed_forms)
            + (["q(t), v(t), psi(t)"] if sc.exact is not None else []),
            "from_mechanics": name != "contact-oscillator", "t_build": t_build, "t_compile": t_compile,
            "us_per_step_gauss2": best / 2000 * 1e6, "runs": runs, "orders": orders, "order_reference": ref_kind,
            "cpu": time.process_time() - c0}


# --- report -------------------------------------------------------------------------------------------
def _ord(o):
    return "-" if o is None else f"{o:.2f}"


def _row(d):
    sym = [d["runs"][m] for m in SYMMETRIC]
    inv_names = list(d["runs"]["gauss-2"]["invariants"])
    long_cells = []
    for k in inv_names:
        rs = [r["invariants"][k] for r in sym]
        state = "round-off" if all(r["roundoff"] for r in rs) else ("bounded" if all(r["bounded"] for r in rs)
                                                                   else "NOT bounded")
        long_cells.append(f"{k}: {sci(max(r['max'] for r in rs))} ({state})")
    ctrl = d["runs"]["euler-i"]
    drift = [k for k, r in ctrl["invariants"].items() if r["drift"]]
    ctrl_cell = (f"drift in {', '.join(drift)} (ratio {', '.join(num(ctrl['invariants'][k]['ratio']) for k in drift)})"
                 if drift else "no drift (max " + ", ".join(sci(r["max"]) for r in ctrl["invariants"].values()) + ")")
    o = d["orders"]
    orders = "; ".join(f"{m.replace('lobatto-iiia-iiib', 'LobIIIA-B')} {_ord(o[m]['q'])}/{_ord(o[m]['v'])}"
                       f" ({o[m]['claimed']})" for m, _ in ORDER_METHODS)
    kmax = max(d["runs"][m]["max_abs_k"] for m in SYMMETRIC)   # Euler I's runs may blow up (relative k stays small)
    return [f"`{d['name']}`", f"{d['n']}, {d['m']}", d["form"], ", ".join(d["closed_forms"]) or "-",
            ", ".join(d["invariants"]), orders, d["order_reference"], sci(kmax),
            f"{d['us_per_step_gauss2']:.0f}", f"{d['t_compile']:.1f}", "; ".join(long_cells), ctrl_cell]


def plot(results, path):
    names = [n for n in SYSTEMS if n in results]
    fig, axes = figure(len(names), 1, figsize=(9, 2.1 * len(names)))
    for ax, name in zip(axes[:, 0], names):
        d = results[name]
        styles = {"gauss-2": "-", "lobatto-iiia-iiib-3": "--", "euler-i": ":"}
        keys = list(d["runs"]["gauss-2"]["invariants"])
        for k, c in zip(keys, colours(len(keys))):
            for m, ls in styles.items():
                r = d["runs"][m]["invariants"][k]
                y = np.maximum(np.asarray(r["abs_err"], float), 1e-17)
                ax.semilogy(r["t"], y, ls, color=c, lw=0.7, label=f"{k}, {m}")
        ax.set_title(f"{name}: |I(t) - I(0)| (solid Gauss-2, dashed Lobatto IIIA-B 3, dotted Euler I)", fontsize=8)
        ax.set_ylabel("error")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=3, loc="lower right")
    axes[-1, 0].set_xlabel("t")
    atomic_save_figure(fig, path, dpi=80)


def long_intervals(results) -> dict:
    """{system: the T of its long symmetric runs}, as they ran: ``--t-long`` or the defaults
    (T_LONG, T_LONG_OF). The report and the JSON state these, not the defaults (``report systems
    --t-long 1`` said "over [0, 500]" and ``"t_long": 500`` about runs over [0, 1])."""
    return {n: float(d["runs"]["gauss-2"]["T"]) for n, d in results.items()}


def _t_long_text(results) -> str:
    T = long_intervals(results)
    rest = sorted({t for n, t in T.items() if n != "suslov"})
    text = ", ".join(f"[0, {t:g}]" for t in rest)
    if "suslov" in T and T["suslov"] not in rest:
        text += f" (Suslov: [0, {T['suslov']:g}])" if rest else f"[0, {T['suslov']:g}] (Suslov)"
    return text or f"[0, {T_LONG:g}]"


def markdown(results, bicycle=None, clock=None, command="ldaspark report systems"):
    names = [n for n in SYSTEMS if n in results]
    L = ["# Classic nonholonomic systems: a benchmark set with reference solutions", "",
         "Generated by `ldaspark report systems`. The scenes are in `ldaspark.models.systems_classic` (each runs by"
         " name on both engines: `ldaspark.integrate(name, method, ...)`; `engine=\"auto\"` compiles every one of"
         " them); their checks, with negative controls and the 40-digit references, are"
         " `verification/test_systems_*.py`. Data in `reports/systems.json`.", "",
         "Columns: **orders** observed (least squares over the asymptotic window, q / v) from N = 4, 8, 16, 32"
         " steps over [0, 1] on the compiled engine, claimed in parentheses (Gauss s: 2s, Lobatto IIIA-B s: 2s - 2);"
         " **max abs(k)**: over the long runs of the symmetric methods;"
         f" **long-time**: the largest error of each invariant over {_t_long_text(results)}"
         f" with h = {H_LONG} for Gauss-2 and"
         " Lobatto IIIA-B 3, *bounded* when max over the last quarter / max over the first quarter <= 1.5,"
         " *round-off* when <= 100 eps sqrt(N) (1 + |I(0)|); **control**: the non-symmetric Euler I (drift: ratio"
         " >= 2); **us/step**: compiled Gauss-2, best of 3 x 2000 steps; **compile**: generating and compiling (or"
         " loading from the cache) the system's model, in this run.", ""]
    L += table(["system", "n, m", "compiled form", "closed form", "invariants", "orders q/v (claimed)",
                "order reference", "max abs(k)", "us/step", "compile [s]", "long-time (symmetric)",
                "control (Euler I)"], [_row(results[n]) for n in names])
    L += ["", "![invariant errors](figures/" + FIG + ")", "", "## Systems and sources", ""]
    for n in names:
        d = results[n]
        how = "sympy.physics.mechanics via `LagrangianSystem.from_mechanics`" if d["from_mechanics"] else "L and k"
        L.append(f"* `{n}` ({how}): {d['description']}. Source: {d['source']}.")
    L += ["", "## Observations", ""]
    L += _observations(results, names)
    L += ["", "## The Whipple bicycle", ""]
    if bicycle is None:
        L.append("Pending: `ldaspark.lab.reports.systems_bicycle` (the benchmark bicycle of Meijaard, Papadopoulos,"
                 " Ruina and Schwab 2007) is not installed in this tree; the section appends its"
                 " `bicycle_section(outdir)` here when it is.")
    elif "error" in bicycle:
        L.append(f"The bicycle section failed: {bicycle['error']}")
    else:
        L.append(bicycle["markdown"])
    if clock is not None:
        L += ["", timing_line(command, clock)]
    return "\n".join(L) + "\n"


def _observations(results, names):
    out = []
    bad = [(n, m, k) for n in names for m in SYMMETRIC for k, r in results[n]["runs"][m]["invariants"].items()
           if not r["bounded"]]

    def quarters(n, m, k):
        return ", ".join(sci(x) for x in results[n]["runs"][m]["invariants"][k]["quarters"])
    out.append("* Symmetric methods, long-time: " + ("every invariant bounded or at round-off." if not bad else
               "NOT bounded: " + ", ".join(f"{n} {m} {k} over [0, {results[n]['runs'][m]['T']:g}] (max per quarter"
                                          f" {quarters(n, m, k)})" for n, m, k in bad) + "."))
    for n in sorted({b[0] for b in bad} & set(NOTES)):
        out.append(f"  `{n}`: {NOTES[n]}.")
    nodrift = [n for n in names if not any(r["drift"] for r in results[n]["runs"]["euler-i"]["invariants"].values())]
    out.append("* Control (Euler I) drifts on " + ", ".join(f"`{n}`" for n in names if n not in nodrift)
               + (f"; no drift on {', '.join(f'`{n}`' for n in nodrift)}: there the flow is attracted to a"
                  " relative equilibrium (the sleigh: u -> 2 a omega0, omega -> 0) or the invariant is kept to"
                  " round-off by every method, and Euler I's error stays O(h) instead." if nodrift else "."))
    offs = [(n, m, o[k]) for n in names for m, o in results[n]["orders"].items() for k in ("q", "v")
            if o[k] is None or abs(o[k] - o["claimed"]) > 0.3]
    out.append("* Orders: " + ("every observed order within 0.3 of 2s (Gauss) / 2s - 2 (Lobatto IIIA-B)." if not offs
               else "off by more than 0.3: " + ", ".join(f"{n} {m} {_ord(x)}" for n, m, x in offs) + "."))
    kb = [n for n in names for r in results[n]["runs"].values() if r["max_abs_k"] > r["k_bound"]]
    out.append("* Constraint: max |k| " + ("below 100 eps (1 + max|q|)(1 + max|v|) on every run." if not kb else
                                           "ABOVE the round-off bound on " + ", ".join(sorted(set(kb))) + "."))
    costs = {n: results[n]["us_per_step_gauss2"] for n in names}
    lo, hi = min(costs, key=costs.get), max(costs, key=costs.get)
    out.append(f"* Compiled cost per Gauss-2 step from {costs[lo]:.0f} us (`{lo}`) to {costs[hi]:.0f} us (`{hi}`);"
               " measured on a shared machine, so only the ratios within this run mean something.")
    return out


def _thin(d, points=100):
    """A system record with its error series cut to ~``points`` samples (the figure uses them all)."""
    import copy
    d = copy.deepcopy(d)
    for run in d["runs"].values():
        for r in run["invariants"].values():
            k = max(1, -(-len(r["t"]) // points))
            r["t"], r["abs_err"] = r["t"][::k], r["abs_err"][::k]
    return d


def _json(results, bicycle):
    T = long_intervals(results)
    rest = sorted({t for n, t in T.items() if n != "suslov"})
    # "t_long": the interval of the long runs of every system but Suslov (one value: --t-long or
    # T_LONG); "t_long_of": each system's, as run
    d = {"systems": {n: _thin(results[n]) for n in SYSTEMS if n in results},
         "t_long": rest[0] if len(rest) == 1 else (T["suslov"] if not rest and "suslov" in T else T_LONG),
         "t_long_of": {n: T[n] for n in SYSTEMS if n in T}, "h_long": H_LONG,
         "bounded_ratio": BOUNDED_RATIO, "drift_ratio": DRIFT_RATIO,
         "bicycle": None if bicycle is None else bicycle.get("json", bicycle)}
    return jsonable(d)


# --- section interface -----------------------------------------------------------------------------
COMPILED_JOBS = ("system_job",)


def jobs(full=False, systems=SYSTEMS, t_long=T_LONG):
    out = [((n,), "system_job", (n, t_long), 4.0) for n in systems]
    if bicycle_available():
        out.append((("bicycle",), "bicycle_job", ("reports",), 30.0))
    return out


def write(results, outdir="reports", full=False, clock=None, command="ldaspark report systems"):
    sys_res = {k[0]: v for k, v in results.items() if k[0] != "bicycle"}
    bicycle = results.get(("bicycle",))
    plot(sys_res, os.path.join(outdir, "figures", FIG))
    atomic_write_text(os.path.join(outdir, REPORT), markdown(sys_res, bicycle, clock, command))
    atomic_write_json(os.path.join(outdir, JSON), _json(sys_res, bicycle))
    _log(f"wrote {os.path.join(outdir, REPORT)}, {JSON}, figures/{FIG}")


def build(outdir="reports", systems=SYSTEMS, t_long=T_LONG):
    clock = Clock()
    results = {}
    for key, fn, args, _ in jobs(False, systems, t_long):
        _log(f"{key[0]} ...")
        results[key] = bicycle_job(outdir) if fn == "bicycle_job" else system_job(*args)
    write(results, outdir, clock=clock)
    print(f"[systems] {clock.summary()}", flush=True)
    return results


def add_arguments(p):
    p.add_argument("--outdir", default="reports", help="report directory (figures go to OUTDIR/figures)")
    p.add_argument("--systems", default=None, help="comma-separated subset of " + ", ".join(SYSTEMS))
    p.add_argument("--t-long", type=float, default=T_LONG, help=f"length of the long runs (default {T_LONG:g})")


def run(args) -> int:
    from ...core.errors import InputError
    systems = SYSTEMS
    if args.systems is not None:
        # an empty subset is refused, not read as "all" ('' ran every system, ',' none); a name
        # given twice runs once (its second run replaced the first)
        systems = tuple(dict.fromkeys(s.strip() for s in args.systems.split(",") if s.strip()))
        if not systems:
            raise InputError(f"--systems {args.systems[:40]!r} names no system; choose from {', '.join(SYSTEMS)}")
        unknown = [s for s in systems if s not in SYSTEMS]
        if unknown:
            raise InputError(f"unknown system(s) {', '.join(unknown)}; choose from {', '.join(SYSTEMS)}")
    if not (math.isfinite(args.t_long) and args.t_long >= 10 * H_LONG):
        raise InputError(f"--t-long must be finite and >= {10 * H_LONG:g}, got {args.t_long}")
    from ...core.validate import MAX_STEPS
    if args.t_long / H_LONG > MAX_STEPS:
        # refused by the first run too, but after a system's set-up and a progress line on stderr
        raise InputError(f"--t-long {args.t_long:g} is {args.t_long / H_LONG:.3g} steps of h = {H_LONG:g}, "
                         f"more than the limit {MAX_STEPS:.0e}")
    from .driver import check_report_files
    check_report_files(args.outdir, REPORT_FILES)
    build(args.outdir, systems, args.t_long)
    return 0


def run_default(outdir="reports") -> None:
    build(outdir)
