"""Report section "work-precision": what the SPARK methods cost against what a user would pick
instead, ``scipy.integrate.solve_ivp`` (DOP853, Radau, LSODA) on the index-reduced ODE (3a-b)
(``system.ode_rhs``), with and without projection of v onto k = 0.

Scenes: the particle (8.1) on [0, 250] against a 6th-order reference (gauss-3 SPARK at a 40x
smaller step, cross-checked against DOP853 at rtol 1e-13), and the skate (8.2) on [0, 100]
against its closed-form solution. For every run: CPU time (``time.process_time``, best of
repeats for the compiled runs), final error max|q - q_ref|, maximum energy error max|E - E0|.
The ratio of CPU time at equal accuracy is read off the lower envelopes (log-log interpolation).
Also: steps per second generic vs fast path, the cost of precision (time per step against dps)
and the energy error at long times. ``ldaspark report work-precision`` writes
reports/work_precision.md and reports/figures/wp_*.png.
"""
from __future__ import annotations

import os
import time

import numpy as np

from ...core.backend import Backend
from ...core.io import atomic_save_figure, atomic_write_json, atomic_write_text
from .envelope import cpu_at
from .markdown import jsonable, sci, table, timing_line
from .peer import peer_section
from .plotting import colours, figure
from .timing import Clock

#: the compiled SPARK runs of each study: the low orders, and gauss-4/6/8 (orders 8, 12, 16) which a
#: user picks for tight targets at large steps; the tables read the cheapest run at each target
SPARK_FAST = ("gauss-1", "gauss-2", "gauss-3", "gauss-4", "gauss-6", "gauss-8", "lobatto-iiia-iiib-2",
              "lobatto-iiia-iiib-3")
SPARK_GENERIC = ("gauss-2",)
SCIPY = ("DOP853", "Radau", "LSODA")
#: the strongest peers (``ldaspark.lab.reports.peers``) beside solve_ivp in the main job's studies: cheap
#: (compiled solvers, milliseconds per run): CyRK's compiled step loop ``nbsolve2_ivp`` (DOP853, Vern8;
#: the peers a speed-minded user picks) when CyRK is installed, Hairer's Fortran DOP853 and LSODA, and
#: CVODE when scikit-sundae is installed (both in the ``bench`` extra)
PEERS_MAIN = ("cyrk-nbsolve2-DOP853", "cyrk-nbsolve2-Vern8", "ode-dop853", "ode-lsoda", "cvode-adams")
TARGETS = (1e-3, 1e-6, 1e-9)


# --- one run of each kind ---------------------------------------------------------------------
def _cpu(fn, repeats=1):
    best = float("inf")
    out = None
    for _ in range(repeats):
        t = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t)
    return best, out


def run_fast(scene, method, h, t_end, repeats=3):
    from ...compiled.fast import fast_integrate
    n = int(round(t_end / h))
    fast_integrate(scene, method, h=h, n_steps=2)                       # compile outside the clock
    cpu, r = _cpu(lambda: fast_integrate(scene, method, h=h, n_steps=n), repeats)
    return cpu, r.t, r.q, r.energy, r.constraint


def run_generic(scene, method, h, t_end):
    from ...core.spark import integrate
    from ...core.families import get_method
    t0, q0, v0 = scene.initial()
    tab = get_method(method)
    cpu, sol = _cpu(lambda: integrate(scene.system, tab, t0, q0, v0, h, n_steps=int(round(t_end / h))))
    return cpu, sol.t, sol.q, sol.energy, sol.constraint


def python_ode_fun(system):
    """y = (q, v), y' = (v, dv/dt) with dv/dt from the saddle system (4) (``system.ode_rhs``,
    lambdified numpy: what a user gets without compiling)."""
    bk = Backend(None)
    n = system.n

    def f(t, y):
        a, _ = system.ode_rhs(bk, t, y[:n], y[n:])
        return np.concatenate([y[n:], a])
    return f


def ode_fun(system):
    """The right-hand side scipy gets: (3a-b) compiled by numba from the same sympy expressions
    as the SPARK model (``ldaspark.compiled.ode.compiled_rhs``), the strongest baseline a user
    would set up; the lambdified ``system.ode_rhs`` only where numba cannot compile it."""
    try:
        from ...compiled.ode import compiled_rhs
        f = compiled_rhs(system)
        f(0.0, np.zeros(2 * system.n) + 0.5)            # compile / load outside the clock
        return f
    except Exception as exc:   # noqa: BLE001  (any numba or codegen failure: the uncompiled baseline)
        import sys
        print(f"ldaspark.lab.reports.work_precision: {type(exc).__name__}: {exc}; scipy gets the lambdified "
              "system.ode_rhs", file=sys.stderr)
        return python_ode_fun(system)


def rhs_call_cost(scene, calls=2000):
    """CPU seconds per call of the compiled and of the lambdified right-hand side at the initial point."""
    t0, q0, v0 = scene.initial()
    y = np.array(list(q0) + list(v0), float)
    out = {}
    for name, f in (("compiled", ode_fun(scene.system)), ("python", python_ode_fun(scene.system))):
        f(float(t0), y)
        cpu, _ = _cpu(lambda: [f(float(t0), y) for _ in range(calls)], 3)
        out[name] = cpu / calls
    return out


def run_scipy(scene, method, rtol, t_end, project=False, segment=1.0, t_eval=None):
    """solve_ivp on (3a-b); with ``project`` the run restarts every ``segment`` time units after
    projecting v onto k = 0 (``system.project_velocity``). atol = rtol * 1e-3."""
    from scipy.integrate import solve_ivp
    system = scene.system
    n = system.n
    bk = Backend(None)
    f = ode_fun(system)
    t0, q0, v0 = scene.initial()
    y0 = np.array(list(q0) + list(v0), float)

    def go():
        if not project:
            r = solve_ivp(f, (t0, t_end), y0, method=method, rtol=rtol, atol=rtol * 1e-3,
                          t_eval=t_eval, dense_output=False)
            ts = r.t if t_eval is not None else np.array([t0, t_end])
            ys = r.y.T if t_eval is not None else np.array([y0, r.y[:, -1]])
            return ts, ys, r.nfev
        edges = np.arange(t0, t_end + 0.5 * segment, segment)
        edges[-1] = t_end
        y = y0.copy()
        ts, ys, nfev = [t0], [y0.copy()], 0
        for a, b in zip(edges[:-1], edges[1:]):
            ev = None if t_eval is None else [t for t in t_eval if a < t <= b]
            r = solve_ivp(f, (a, b), y, method=method, rtol=rtol, atol=rtol * 1e-3, t_eval=ev or None)
            nfev += r.nfev
            y = r.y[:, -1].copy()
            y[n:] = system.project_velocity(bk, b, y[:n], y[n:])
            if ev:
                ts.extend(r.t[:-1])
                ys.extend(r.y.T[:-1])
            ts.append(b)
            ys.append(y.copy())
        return np.array(ts), np.array(ys), nfev

    cpu, (ts, ys, nfev) = _cpu(go)
    E = np.array([system.energy(bk, t, y[:n], y[n:]) for t, y in zip(ts, ys)])
    K = np.array([system.constraint(bk, t, y[:n], y[n:]) for t, y in zip(ts, ys)])
    return cpu, ts, ys[:, :n], E, K, nfev


# --- the study ------------------------------------------------------------------------------------
def reference_final(scene_name, scene, t_end):
    """q(t_end): closed form for the skate, else gauss-3 SPARK (order 6) at h = 0.0025."""
    if scene.exact is not None:
        return scene.exact_solution(t_end)[0], "closed-form solution"
    _, _, q, _, _ = run_fast(scene, "gauss-3", 0.0025, t_end, repeats=1)
    return q[-1], "gauss-3 SPARK, h = 0.0025 (fast path)"


def _E0(scene):
    t0, q0, v0 = scene.initial()
    return scene.system.energy(Backend(None), t0, q0, v0)


def _row(kind, method, param, cpu, q, E, K, E0, nfev=None):
    """One run; its final error is added by ``finish_study`` (the reference may come from another job)."""
    return {"kind": kind, "method": method, "param": float(param), "cpu": float(cpu),
            "q_final": [float(x) for x in np.asarray(q[-1], float)],
            "energy_error": float(np.max(np.abs(np.asarray(E, float) - E0))),
            "constraint": float(np.max(np.abs(np.asarray(K, float)))), "nfev": nfev}


def scene_runs(scene_name, t_end, kind, method, params):
    """The runs of one (kind, method) on a scene: h values for the SPARK paths, rtol values for scipy."""
    from ...models.scenes import get_scene
    scene = get_scene(scene_name)
    E0 = _E0(scene)
    rows = []
    for p in params:
        if kind == "spark-fast":
            cpu, t, q, E, K = run_fast(scene, method, p, t_end)
            rows.append(_row(kind, method, p, cpu, q, E, K, E0))
        elif kind == "spark-generic":
            cpu, t, q, E, K = run_generic(scene, method, p, t_end)
            rows.append(_row(kind, method, p, cpu, q, E, K, E0))
        elif kind == "peer":
            from .peers import PeerFailure, run_peer
            try:
                rows.append(run_peer(scene, method, p, t_end))
            except PeerFailure:           # a peer that stops early has no point at this tolerance
                continue
        else:
            cpu, t, q, E, K, nfev = run_scipy(scene, method, p, t_end, project=(kind == "scipy-projected"))
            rows.append(_row(kind, method, p, cpu, q, E, K, E0, nfev))
    return rows


def scene_reference(scene_name, t_end):
    """(q_ref at t_end, label, DOP853 rtol 1e-13 final q or None for a closed-form reference)."""
    from ...models.scenes import get_scene
    scene = get_scene(scene_name)
    q_ref, label = reference_final(scene_name, scene, t_end)
    check = None
    if scene.exact is None:
        check = [float(x) for x in run_scipy(scene, "DOP853", 1e-13, t_end)[2][-1]]
    return [float(x) for x in np.asarray(q_ref, float)], label, check, rhs_call_cost(scene)


def _steps_for(method, hs):
    """The steps of a compiled SPARK method's runs: all of ``hs``, but only the four largest for
    s >= 6 (orders 12 and 16 are at round-off there already; smaller steps only cost time)."""
    hs = tuple(hs)
    if method.startswith("gauss-") and int(method.split("-")[1]) >= 6:
        return tuple(sorted(hs, reverse=True)[:4])
    return hs


def study_plan(scene_name, t_end, hs_fast, hs_generic, rtols, rtols_radau):
    """[(kind, method, params)] of one scene's study."""
    plan = [("spark-fast", m, _steps_for(m, hs_fast)) for m in SPARK_FAST]
    plan += [("spark-generic", m, tuple(hs_generic)) for m in SPARK_GENERIC]
    plan += [(kind, m, tuple(rtols_radau if m == "Radau" else rtols)) for m in SCIPY
             for kind in ("scipy", "scipy-projected")]
    from .peers import available_peers
    plan += [("peer", p, tuple(rtols)) for p in available_peers(PEERS_MAIN)[0]]
    return plan


def finish_study(scene_name, t_end, reference, rows):
    """The study dict of one scene: final errors against the reference, the reference check."""
    from ...models.scenes import get_scene
    q_ref, label, check_q = reference[:3]
    q_ref = np.asarray(q_ref, float)
    out = []
    for r in rows:
        r = dict(r)
        r["error"] = float(np.max(np.abs(np.asarray(r.pop("q_final"), float) - q_ref)))
        out.append(r)
    check = None if check_q is None else float(np.max(np.abs(np.asarray(check_q) - q_ref)))
    return {"scene": scene_name, "t_end": t_end, "reference": label, "reference_check": check,
            "E0": float(_E0(get_scene(scene_name))), "rows": out,
            "rhs_seconds_per_call": reference[3] if len(reference) > 3 else None}


def study_scene(scene_name, t_end, hs_fast, hs_generic, rtols, rtols_radau, progress=print):
    """One scene's study in this process (the main job runs the same pieces as separate jobs)."""
    ref = scene_reference(scene_name, t_end)
    rows = []
    for kind, m, params in study_plan(scene_name, t_end, hs_fast, hs_generic, rtols, rtols_radau):
        rows += scene_runs(scene_name, t_end, kind, m, params)
        progress(f"  {scene_name}: {kind} {m} done")
    return finish_study(scene_name, t_end, ref, rows)


def ratios(study, targets=TARGETS, key="error"):
    rows = study["rows"]
    groups = {
        "spark-fast": [r for r in rows if r["kind"] == "spark-fast"],
        "spark-generic": [r for r in rows if r["kind"] == "spark-generic"],
        "scipy (best of 3)": [r for r in rows if r["kind"] == "scipy"],
        "scipy + projection (best of 3)": [r for r in rows if r["kind"] == "scipy-projected"],
    }
    peer_rows = [r for r in rows if r["kind"] == "peer"]
    out = []
    for tgt in targets:
        c = {g: cpu_at(rs, tgt, key) for g, rs in groups.items()}
        sc = [x for x in (c["scipy (best of 3)"], c["scipy + projection (best of 3)"]) if x is not None]
        best_scipy = min(sc) if sc else None
        # the best peer: the cheapest at this target among the strongest peers and solve_ivp
        from .peers import best_peer
        pm, pc = best_peer(peer_rows, tgt, key)
        if best_scipy is not None and (pc is None or best_scipy < pc):
            pm, pc = "solve_ivp", best_scipy
        out.append({"target": tgt, **c,
                    "scipy/spark-fast": best_scipy / c["spark-fast"] if best_scipy and c["spark-fast"] else None,
                    "scipy/spark-generic": best_scipy / c["spark-generic"] if best_scipy and c["spark-generic"] else None,
                    "best peer": pc, "best peer name": pm,
                    "peer/spark-fast": pc / c["spark-fast"] if pc and c["spark-fast"] else None})
    return out


def steps_per_second(scenes=("particle", "skate", "robot", "mp-particles"),
                     methods=("gauss-1", "gauss-2", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3",
                              "lobatto-iiia-iiib-iiid-2", "euler-i"), n_generic=40, n_fast=20000, h=0.05):
    """Steps per second generic vs fast path, measured side by side in one run."""
    from ...core.errors import NewtonError, NonFiniteError
    from ...compiled.fast import fast_integrate
    from ...models.scenes import get_scene
    from ...core.spark import integrate
    from ...core.families import get_method
    rows = []
    for sname in scenes:
        sc = get_scene(sname)
        t0, q0, v0 = sc.initial()
        for m in methods:
            fast_integrate(sc, m, h=h, n_steps=2)
            cg, _ = _cpu(lambda: integrate(sc.system, get_method(m), t0, q0, v0, h, n_steps=n_generic))
            nf, note = n_fast, ""
            try:
                cf, r = _cpu(lambda: fast_integrate(sc, m, h=h, n_steps=nf), 3)
            except (NewtonError, NonFiniteError) as exc:   # e.g. euler-i leaves the MP particles' energy surface
                why = "NaN / inf" if isinstance(exc, NonFiniteError) else "Newton fails"
                nf, note = max(exc.step - 10, 10), f"diverges: {why} at t = {exc.time:.4g}"
                cf, r = _cpu(lambda: fast_integrate(sc, m, h=h, n_steps=nf), 3)
            rows.append({"scene": sname, "method": m, "generic": n_generic / cg, "fast": nf / cf,
                         "ratio": (nf / cf) / (n_generic / cg), "kernel": r.stats["kernel"], "note": note})
    return rows


def dps_cost(dps_list=(16, 30, 50, 100, 200), n_steps=8, method="gauss-2", scene_name="particle", h="0.1"):
    """Time per step of the mpmath path against dps, with float64 generic and fast for scale."""
    from ...compiled.fast import fast_integrate
    from ...models.scenes import get_scene
    from ...core.spark import integrate
    from ...core.families import get_method
    sc = get_scene(scene_name)
    tab = get_method(method)
    rows = []
    t0, q0, v0 = sc.initial()
    fast_integrate(sc, method, h=float(h), n_steps=2)
    cf, _ = _cpu(lambda: fast_integrate(sc, method, h=float(h), n_steps=20000), 3)
    rows.append({"precision": "float64 fast", "seconds_per_step": cf / 20000})
    cg, sol = _cpu(lambda: integrate(sc.system, tab, t0, q0, v0, float(h), n_steps=n_steps * 5))
    rows.append({"precision": "float64 generic", "seconds_per_step": cg / (n_steps * 5),
                 "mean_iterations": sol.stats["mean_iterations"]})
    t0, q0, v0 = sc.initial(20)
    integrate(sc.system, tab, t0, q0, v0, h, n_steps=2, dps=20)          # one-time mpmath/lambdify set-up
    for d in dps_list:
        t0, q0, v0 = sc.initial(d)
        integrate(sc.system, tab, t0, q0, v0, h, n_steps=1, dps=d)        # per-dps tableau cache
        c, sol = _cpu(lambda: integrate(sc.system, tab, t0, q0, v0, h, n_steps=n_steps, dps=d), 2)
        rows.append({"precision": f"mpmath dps={d}", "dps": d, "seconds_per_step": c / n_steps,
                     "mean_iterations": sol.stats["mean_iterations"]})
    for d in dps_list:     # the Newton matrix in float64, the residual at dps digits (same solution)
        t0, q0, v0 = sc.initial(d)
        c, sol = _cpu(lambda: integrate(sc.system, tab, t0, q0, v0, h, n_steps=n_steps, dps=d, newton="mixed"), 2)
        rows.append({"precision": f"mpmath dps={d}, mixed Newton", "dps_mixed": d, "seconds_per_step": c / n_steps,
                     "mean_iterations": sol.stats["mean_iterations"]})
    return rows


LONG_RUNS = ("spark", "dop853", "dop853_projected")


#: the long-time energy run's horizon: default, with --quick; the DOP853 runs' sampling interval
#: (``long_part``: t_eval every 5) and the SPARK run's step
T_LONG, T_LONG_QUICK, LONG_SAMPLE, LONG_H = 2500.0, 250.0, 5.0, 0.1


def long_part(which, t_long=2500.0, h=LONG_H, rtol=1e-6, every=10):
    """One run of ``long_energy``: "spark" (gauss-2 SPARK fast), "dop853" or "dop853_projected"."""
    from ...compiled.fast import fast_integrate
    from ...models.scenes import get_scene
    sc = get_scene("particle")
    E0 = _E0(sc)
    if which == "spark":
        n = int(round(t_long / h))
        cpu_s, r = _cpu(lambda: fast_integrate(sc, "gauss-2", h=h, n_steps=n, every=every))
        out = {"t": r.t.tolist(), "dE": np.abs(r.energy - E0).tolist(), "cpu": cpu_s,
               "label": f"gauss-2 SPARK fast, h = {h}"}
    else:
        proj = which == "dop853_projected"
        t_eval = np.arange(0.0, t_long + 1e-9, 5.0)
        cpu, ts, q, E, K, nfev = run_scipy(sc, "DOP853", rtol, t_long, project=proj, segment=5.0, t_eval=t_eval)
        out = {"t": list(map(float, ts)), "dE": np.abs(E - E0).tolist(), "cpu": cpu,
               "constraint": float(np.max(np.abs(K))),
               "label": f"DOP853 rtol={rtol:g}" + (" + projection every 5" if proj else "")}
    t = np.array(out["t"])
    d = np.array(out["dE"])
    half = t >= t_long / 2
    out["max_first_half"] = float(np.max(d[~half]))
    out["max_second_half"] = float(np.max(d[half]))
    return out


def long_energy(t_long=2500.0, h=0.1, rtol=1e-6, every=10):
    """|E - E0| over [0, t_long] for the particle: gauss-2 SPARK vs DOP853 with/without projection."""
    return {"t_long": t_long, **{w: long_part(w, t_long, h, rtol, every) for w in LONG_RUNS}}


# --- plots and report -------------------------------------------------------------------------
STYLE = {"spark-fast": "-o", "spark-generic": "-s", "scipy": "--^", "scipy-projected": ":v", "peer": "-.d"}


def plot_study(study, path):
    fig, axes = figure(1, 2, figsize=(12, 5))
    seen = {}
    for r in study["rows"]:
        seen.setdefault((r["kind"], r["method"]), []).append(r)
    # one colour per method (shared by both panels); the kind (fast, generic, scipy, + projection)
    # is the line style and marker, so gauss-2 fast and generic share a colour but not a marker
    methods = list(dict.fromkeys(m for _, m in seen))
    mcol = dict(zip(methods, colours(len(methods))))
    col = {km: mcol[km[1]] for km in seen}
    for ax, key, lab in ((axes[0][0], "error", f"final error max|q - q_ref| at t = {study['t_end']:g}"),
                         (axes[0][1], "energy_error", "max |E - E0| over the run")):
        for (kind, m), rs in seen.items():
            rs = sorted(rs, key=lambda r: r["cpu"])
            ax.loglog([r["cpu"] for r in rs], [max(r[key], 1e-17) for r in rs], STYLE[kind], ms=4,
                      color=col[(kind, m)], label=f"{m} ({kind})")
        ax.set_xlabel("CPU time [s]")
        ax.set_ylabel(lab)
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(f"Work-precision, {study['scene']} on [0, {study['t_end']:g}]")
    atomic_save_figure(fig, path, dpi=110)


def plot_long(le, path):
    fig, axes = figure(1, 1, figsize=(8, 4.5))
    ax = axes[0][0]
    keys = ("spark", "dop853", "dop853_projected")
    for key, c in zip(keys, colours(len(keys))):
        d = le[key]
        ax.semilogy(d["t"], np.maximum(d["dE"], 1e-17), color=c, label=f"{d['label']} ({d['cpu']:.2f} s)")
    _finish(fig, ax, path, "t", "|E - E0|", "Particle: energy error at long times")


def plot_dps(rows, path):
    mp = [r for r in rows if "dps" in r]
    fig, axes = figure(1, 1, figsize=(6, 4))
    ax = axes[0][0]
    ax.semilogy([r["dps"] for r in mp], [r["seconds_per_step"] for r in mp], "-o", color="C0",
                label="mpmath path (newton auto)")
    mx = [r for r in rows if "dps_mixed" in r]
    if mx:
        ax.semilogy([r["dps_mixed"] for r in mx], [r["seconds_per_step"] for r in mx], "-s", color="C1",
                    label="mpmath path, mixed Newton")
    for r in rows:
        if "dps" not in r and "dps_mixed" not in r:
            ax.axhline(r["seconds_per_step"], ls="--", color="gray" if "generic" in r["precision"] else "k",
                       label=r["precision"])
    _finish(fig, ax, path, "dps (decimal digits)", "CPU seconds per step", "Cost of precision: particle, gauss-2")


def _finish(fig, ax, path, xlabel, ylabel, title):
    """Labels, legend and grid of a one-panel figure, written atomically."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    atomic_save_figure(fig, path, dpi=110)


def _fmt(x, f="{:.3g}"):
    return "-" if x is None else f.format(x)


def _ratio_rows(st, key):
    return [[f"{r['target']:.0e}", _fmt(r["spark-fast"]), _fmt(r["spark-generic"]), _fmt(r["scipy (best of 3)"]),
             _fmt(r["scipy + projection (best of 3)"]), _fmt(r["scipy/spark-fast"], "{:.2g}"),
             _fmt(r["scipy/spark-generic"], "{:.2g}"),
             "-" if r.get("best peer") is None else f"{r['best peer name']} {r['best peer']:.3g}",
             _fmt(r.get("peer/spark-fast"), "{:.2g}")] for r in ratios(st, key=key)]


RATIO_HEADER = ["SPARK fast [s]", "SPARK generic [s]", "scipy best [s]", "scipy + proj. best [s]",
                "scipy / SPARK fast", "scipy / SPARK generic", "best peer [s]", "best peer / SPARK fast"]


def _rhs_sentence(c):
    if not c:
        return ""
    return (f" One call of scipy's right-hand side costs {c['compiled'] * 1e6:.3g} us compiled, against "
            f"{c['python'] * 1e6:.3g} us for the lambdified `system.ode_rhs` ({c['python'] / c['compiled']:.0f}x).")


def _study_markdown(st):
    name = st["scene"]
    L = [f"## {name} on [0, {st['t_end']:g}]", "",
         f"Reference: {st['reference']}"
         + (f" (differs from DOP853 rtol 1e-13 by {sci(st['reference_check'])})" if st["reference_check"] is not None else "")
         + f". E0 = {st['E0']:.6g}." + _rhs_sentence(st.get("rhs_seconds_per_call")), "",
         f"![work-precision {name}](figures/wp_{name}.png)", "",
         "CPU time to reach a final error (log-log interpolation on the cheapest runs; '-' = not reached):", ""]
    L += table(["final error"] + RATIO_HEADER, _ratio_rows(st, "error"))
    L += ["", "CPU time to reach a maximum energy error:", ""]
    L += table(["max energy error"] + RATIO_HEADER, _ratio_rows(st, "energy_error"))
    L += ["", "<details><summary>all runs</summary>", ""]
    L += table(["kind", "method", "h or rtol", "CPU [s]", "final error", "max energy error", "max abs k", "nfev"],
               [[r["kind"], r["method"], f"{r['param']:g}", f"{r['cpu']:.3g}", sci(r["error"], 2),
                 sci(r["energy_error"], 2), sci(r["constraint"]), r["nfev"]] for r in st["rows"]])
    return L + ["", "</details>", ""]


def sps_summary(sps):
    """Median, min and max of the fast / generic steps-per-second ratios."""
    r = sorted(x["ratio"] for x in sps)
    return {"median": float(np.median(r)), "min": r[0], "max": r[-1], "n": len(r)} if r else None


def strongest_peers_section(path):
    """Lines of the "Strongest peers" section from ``path`` (``reports/peers.json``, written by
    ``benchmarks/peers.py``: five scenes, T = 100 and T = 1e4, every peer; too long for the main
    job, so the file is committed and rendered here); [] when the file is absent."""
    from .files import load_json
    if not os.path.exists(path):
        return []
    from .peers import section
    return section(load_json(path))


def scaling_section(path):
    """Lines of the "Scale" section from ``path`` (``reports/scaling.json``, written by
    ``benchmarks/scaling.py``: the compiled step's cost against n and s; committed, not regenerated
    by the main job) and its figure ``figures/wp_scaling.png`` beside the report; [] when the
    file is absent."""
    from .files import load_json
    import math
    if not os.path.exists(path):
        return []
    d = load_json(path)
    rows = d["rows"]
    ok = [r for r in rows if r.get("status") == "ok"]
    L = ["", "## Scale: the compiled step against n and s (MP particles, nonholonomic constraint)", "",
         f"From `{d['command']}` on {d['date']} ({d['cpu_count']} CPUs, load average {d['load_average_1min_at_end']} "
         "at the end" + (": a loaded machine" if (d["load_average_1min_at_end"] or 0) > (d["cpu_count"] or 1) else "")
         + "). n = 2m + 1, one constraint, h = 0.001; every size in a fresh process with an empty model cache. "
         "Build: sympy (L, k, Hessians); first call: code generation and numba compilation of the model (the "
         "kernels are compiled once per machine); per step: CPU time of a ~0.3 s run, minimum of 3, with the "
         "linear solver `run_compiled(linear_solver=\"auto\")` picks and, beside it, the dense LU of the whole "
         "Newton matrix (size (s + 1) n + s m, ~((s + 1) n)^3 / 3 multiply-adds per factorisation), both with "
         "the default Newton matrix reuse across steps (`reuse_matrix=\"auto\"`: from n >= 32; column "
         "\"reuse\"). The block "
         "solver (`compiled/sparse.py`, `compiled/kernels_sparse.py`) factors the (s + 1) x (s + 1) blocks of "
         "one degree of freedom's unknowns (Z_1..Z_s, dv) in a minimum-degree order of the pattern of M, "
         "Hess U and d(K^T lam)/dq, and the multipliers by their Schur complement. Operation count: the "
         "multiply-adds of its linear algebra per step (assembly, factorisation, solves; "
         "`benchmarks/scaling.py`, `operation_count`); ns per multiply-add is the measured step time over "
         "that count (the model's evaluations are in the time, not in the count: a scalar loop runs at "
         "~1 ns per multiply-add).", ""]
    L += table(["n", "method", "solver", "build CPU [s]", "first call CPU [s]", "CPU per step [us]",
                "dense LU per step [us]", "dense / solver", "reuse", "Newton iterations / step", "Jacobians / step",
                "multiply-adds / step", "ns per multiply-add", "blocks (fill)", "model source [chars]", "status"],
               [[r["n"], r.get("method", "-"), r.get("linear_solver", "dense"), _fmt(r.get("build_cpu")),
                 _fmt(r.get("first_call_cpu")), _fmt(r.get("us_per_step")), _fmt(r.get("us_per_step_dense")),
                 _fmt(r.get("dense_over_sparse"), "{:.1f}"),
                 {True: "yes", False: "no"}.get(r.get("reuse_matrix"), "-"), _fmt(r.get("mean_iterations"), "{:.2f}"),
                 _fmt(r.get("jacobians_per_step"), "{:.2f}"), _fmt(r.get("madds_per_step")),
                 _fmt(r.get("ns_per_madd"), "{:.2f}"),
                 f"{r['blocks']} ({r['fill_ratio']:.2f})" if "blocks" in r else "-",
                 r.get("model_source_chars", "-"), r.get("status", "-")] for r in rows])
    first = [r for r in ok if r["method"] == ok[0]["method"]] if ok else []
    if len(first) >= 2:
        a, b = first[0], first[-1]
        p = math.log(b["us_per_step"] / a["us_per_step"]) / math.log(b["n"] / a["n"])
        line = f"Cost per step ({a['method']}) grows like n^{p:.2f} between n = {a['n']} and n = {b['n']}"
        if a.get("us_per_step_dense") and b.get("us_per_step_dense"):
            pd = math.log(b["us_per_step_dense"] / a["us_per_step_dense"]) / math.log(b["n"] / a["n"])
            line += f" (the dense LU: n^{pd:.2f})"
        L += ["", line + "."]
    if plot_scaling(ok, os.path.join(os.path.dirname(path), "figures", "wp_scaling.png")):
        L += ["", "![scaling](figures/wp_scaling.png)"]
    return L + [""]


def plot_scaling(ok, path):
    """Cost per step against n (both solvers) and, where several methods ran at one n, against s;
    False (no figure) with fewer than two sizes."""
    first = [r for r in ok if r["method"] == ok[0]["method"]] if ok else []
    if len(first) < 2:
        return False
    by_n: dict = {}
    for r in ok:
        by_n.setdefault(r["n"], []).append(r)
    sweep = max(by_n.values(), key=len)
    fig, axes = figure(1, 2 if len(sweep) >= 2 else 1, figsize=(10 if len(sweep) >= 2 else 6, 4.2))
    ax = axes[0, 0]
    ns = [r["n"] for r in first]
    ax.loglog(ns, [r["us_per_step"] for r in first], "o-", label=f"{first[0]['method']}, {first[0].get('linear_solver', 'dense')}")
    dense = [(r["n"], r["us_per_step_dense"]) for r in first if r.get("us_per_step_dense")]
    if dense:
        ax.loglog(*zip(*dense), "s--", label=f"{first[0]['method']}, dense LU")
    ax.set_xlabel("n")
    ax.set_ylabel("CPU per step [us]")
    ax.set_title("cost per step against n")
    ax.legend()
    if len(sweep) >= 2:
        ax = axes[0, 1]
        sweep = sorted(sweep, key=lambda r: (r.get("s", 0), r["method"]))
        x = range(len(sweep))
        ax.bar([i - 0.2 for i in x], [r["us_per_step"] for r in sweep], 0.4, label="auto solver")
        ax.bar([i + 0.2 for i in x], [r.get("us_per_step_dense") or 0 for r in sweep], 0.4, label="dense LU")
        ax.set_xticks(list(x), [r["method"] for r in sweep], rotation=15)
        ax.set_yscale("log")
        ax.set_ylabel("CPU per step [us]")
        ax.set_title(f"cost per step against the method, n = {sweep[0]['n']}")
        ax.legend()
    os.makedirs(os.path.dirname(path), exist_ok=True)
    atomic_save_figure(fig, path, dpi=110)
    return True


def write_report(outdir, studies, sps, dps_rows, le, clock, command="ldaspark report work-precision"):
    from .peers import available_peers
    skipped = available_peers(PEERS_MAIN)[1]
    L = ["# Work-precision: SPARK against the strongest compiled peers and scipy.integrate.solve_ivp", "",
         "Generated by `ldaspark report work-precision` (`python benchmarks/work_precision.py` prints the "
         "same tables; every number is in `work_precision.json`). CPU times are `time.process_time` on a "
         "shared 2-core machine (noisy, other jobs run concurrently); compiled runs are best of 3 and exclude "
         "numba compilation. scipy solves the index-reduced ODE (3a-b) with a right-hand side compiled by numba "
         "from the same sympy expressions as the SPARK model (`ldaspark.compiled.ode.compiled_rhs`, the saddle "
         "system (4) solved in numba), the strongest baseline a user would set up; atol = 1e-3 rtol; "
         "\"+ projection\" restarts every time unit after projecting v onto k = 0. The strongest peers run on the "
         "same compiled right-hand side (kind `peer`, `ldaspark.lab.reports.peers`): CyRK's compiled step loop "
         "`nbsolve2_ivp` (DOP853 and Vern8 with a numba `cfunc` right-hand side), scipy's `ode('dop853')` (Hairer's "
         "Fortran), `ode('lsoda')` and SUNDIALS CVODE Adams (CyRK and scikit-sundae are the `bench` extra)"
         + "".join(f" (**{n}**)" for n in skipped)
         + "; \"best peer\" is the cheapest of them and solve_ivp at each target, and \"best peer / SPARK fast\" "
         "the honest speed-up (> 1: SPARK faster). SPARK fast is the cheapest compiled SPARK run at each target "
         "over gauss-1..4, 6, 8 and Lobatto IIIA-B 2, 3, as a user picking the best method would.", ""]
    for st in studies:
        L += _study_markdown(st)
    L += ["## Energy error at long times (particle)", "", "![long](figures/wp_energy_long.png)", ""]
    L += table(["run", "CPU [s]", "max abs(E - E0), first half", "max abs(E - E0), second half", "max abs k"],
               [[le[k]["label"], f"{le[k]['cpu']:.3g}", sci(le[k]["max_first_half"], 2), sci(le[k]["max_second_half"], 2),
                 sci(le[k].get("constraint"))] for k in ("spark", "dop853", "dop853_projected")])
    sm = sps_summary(sps)
    L += ["", "## Steps per second, generic vs fast path (h = 0.05, measured side by side)", ""]
    if sm:
        L += [f"fast / generic: median {sm['median']:.0f}x ({sm['min']:.0f}x to {sm['max']:.0f}x) over "
              f"{sm['n']} (scene, method) pairs.", ""]
    L += table(["scene", "method", "kernel", "generic [steps/s]", "fast [steps/s]", "fast / generic", "note"],
               [[r["scene"], r["method"], r["kernel"], f"{r['generic']:.3g}", f"{r['fast']:.3g}", f"{r['ratio']:.0f}",
                 r["note"]] for r in sps])
    L += ["", "## Cost of precision (particle, gauss-2, h = 0.1)", "", "![dps](figures/wp_dps.png)", "",
          "The mpmath rows use `integrate`'s default Newton (`auto`); the 'mixed Newton' rows assemble and "
          "factorise the Newton matrix in float64 and keep the residual at dps digits (the same solution; each "
          "iteration gains ~16 digits, so it pays up to ~100 digits and not at 200).", ""]
    base = [r for r in dps_rows if r["precision"] == "float64 generic"][0]["seconds_per_step"]
    L += table(["precision", "CPU seconds per step", "relative to float64 generic", "Newton iterations per step"],
               [[r["precision"], f"{r['seconds_per_step']:.3g}", f"{r['seconds_per_step'] / base:.3g}",
                 _fmt(r.get("mean_iterations"), "{:.2f}")] for r in dps_rows])
    L += peer_section(os.path.join(outdir, "peer_odelab.json"))
    L += strongest_peers_section(os.path.join(outdir, "peers.json"))
    L += scaling_section(os.path.join(outdir, "scaling.json"))
    L += ["", timing_line(command, clock), ""]
    path = os.path.join(outdir, "work_precision.md")
    atomic_write_text(path, "\n".join(L))
    data = {"studies": [dict(st, ratios={"error": ratios(st, key="error"),
                                         "energy_error": ratios(st, key="energy_error")}) for st in studies],
            "steps_per_second": sps, "steps_per_second_summary": sm, "dps": dps_rows,
            # the strongest peers this run could not set up (the bench extra): their ratios are not
            # "against the strongest peers", and ``summary`` does not quote them as such
            "peers_skipped": list(skipped),
            "long": {k: {kk: vv for kk, vv in v.items() if kk not in ("t", "dE")} if isinstance(v, dict) else v
                     for k, v in le.items()}}
    atomic_write_json(os.path.join(outdir, "work_precision.json"), jsonable(data))
    return path


# --- sizes, jobs of the main job, the section's own command -----------------------------------
def sizes(quick=False, t_long=None):
    """(hs_fast, hs_generic, rtols, rtols_radau, ((scene, t_end), ...), t_long, n_generic, n_fast, dps_steps);
    ``t_long`` None: T_LONG, or T_LONG_QUICK with ``quick`` (a given one is used either way: --quick
    replaced it by 250 in silence)."""
    if t_long is None:
        t_long = T_LONG_QUICK if quick else T_LONG
    if quick:
        return ((0.2, 0.05, 0.0125), (0.2,), (1e-4, 1e-8), (1e-4,), (("particle", 50.0), ("skate", 20.0)),
                t_long, 20, 5000, 3)
    return ((0.4, 0.2, 0.1, 0.05, 0.025, 0.0125, 0.00625), (0.2, 0.1, 0.05), (1e-3, 1e-5, 1e-7, 1e-9, 1e-11),
            (1e-3, 1e-5, 1e-7), (("particle", 250.0), ("skate", 100.0)), t_long, 40, 20000, 8)


# rough CPU seconds on an idle core, to start the longest jobs first
COST = {"Radau": 8.0, "LSODA": 2.0, "DOP853": 1.5, "spark-generic": 12.0, "spark-fast": 2.0, "peer": 0.5}   # rough CPU s, for scheduling


def _run_groups(kind, method, params):
    """[(key tag, params, cost weight)]: one job per run for the expensive kinds (Radau, the generic
    path: the longest pieces of the main job), one job for all runs of a cheap kind (the compiled
    path, DOP853, LSODA: a job's set-up would cost more than its runs)."""
    if method == "Radau" or kind == "spark-generic":
        return [((p,), (p,), (1 + i) / len(params)) for i, p in enumerate(params)]
    return [(("all",), tuple(params), 1.0)]


# jobs on the compiled path (started after the main job has compiled the kernels once)
COMPILED_JOBS = ("scene_runs", "scene_reference", "long_part", "sps_job", "dps_job")


def jobs(full=False, quick=False, t_long=None):
    hs_fast, hs_gen, rtols, rtols_r, cfg, t_long, n_gen, n_fast, dps_steps = sizes(quick, t_long)
    J = []
    for name, t_end in cfg:
        J.append((("ref", name), "scene_reference", (name, t_end), 4.0))
        for kind, m, params in study_plan(name, t_end, hs_fast, hs_gen, rtols, rtols_r):
            J += [(("runs", name, kind, m) + tag, "scene_runs", (name, t_end, kind, m, ps),
                   COST.get(m, COST.get(kind, 2.0)) * t_end / 250.0 * w)
                  for tag, ps, w in _run_groups(kind, m, params)]
    J += [(("long", w), "long_part", (w, t_long), 6.0) for w in LONG_RUNS] + [(("dps",), "dps_job", (dps_steps,), 15.0)]
    J += [(("sps", sc), "sps_job", (sc, n_gen, n_fast), 5.0) for sc in SPS_SCENES]
    return J


SPS_SCENES = ("particle", "skate", "robot", "mp-particles")


def sps_job(scene, n_generic, n_fast):
    return steps_per_second(scenes=(scene,), n_generic=n_generic, n_fast=n_fast)


def dps_job(n_steps):
    return dps_cost(n_steps=n_steps)


def write(results, outdir="reports", full=False, clock=None, command="ldaspark report work-precision",
          quick=False, t_long=None):
    hs_fast, hs_gen, rtols, rtols_r, cfg, t_long, *_ = sizes(quick, t_long)
    figdir = os.path.join(outdir, "figures")
    studies = []
    for name, t_end in cfg:
        rows = [r for kind, m, params in study_plan(name, t_end, hs_fast, hs_gen, rtols, rtols_r)
                for tag, _, _ in _run_groups(kind, m, params) for r in results[("runs", name, kind, m) + tag]]
        st = finish_study(name, t_end, results[("ref", name)], rows)
        plot_study(st, os.path.join(figdir, f"wp_{name}.png"))
        studies.append(st)
    le = {"t_long": t_long, **{w: results[("long", w)] for w in LONG_RUNS}}
    plot_long(le, os.path.join(figdir, "wp_energy_long.png"))
    plot_dps(results[("dps",)], os.path.join(figdir, "wp_dps.png"))
    sps = [r for sc in SPS_SCENES for r in results[("sps", sc)]]
    path = write_report(outdir, studies, sps, results[("dps",)], le, clock or Clock(), command)
    return {"studies": studies, "steps_per_second": sps, "dps": results[("dps",)], "long": le, "path": path}


def run_study(outdir="reports", quick=False, t_long=None, progress=print):
    """The whole section in this process: every job in turn, then the report."""
    clock = Clock()
    os.makedirs(os.path.join(outdir, "figures"), exist_ok=True)
    results = {}
    for key, fn, args, _ in jobs(quick=quick, t_long=t_long):
        progress(f"[work-precision] {' '.join(map(str, key))} ...")
        results[key] = globals()[fn](*args)
    out = write(results, outdir, clock=clock, quick=quick, t_long=t_long)
    progress(f"wrote {out['path']} ({clock.summary()})")
    return out


def add_arguments(p):
    p.add_argument("--outdir", default="reports", help="report directory (figures in OUTDIR/figures)")
    p.add_argument("--quick", action="store_true", help="few points, short intervals (smoke run)")
    p.add_argument("--t-long", type=float, default=None,
                   help=f"horizon of the long-time energy run (default {T_LONG:g}, {T_LONG_QUICK:g} with --quick; "
                        f"at least {LONG_SAMPLE:g}, a multiple of {LONG_H:g})")


def check_t_long(t_long) -> None:
    """Refuse before the study a --t-long its long run cannot take: the report compares the
    largest energy error of the two halves and the DOP853 runs sample every LONG_SAMPLE, so the
    second half needs t_long >= LONG_SAMPLE (``--t-long 3`` ran the whole study, then failed with
    numpy's "zero-size array to reduction operation maximum"); the SPARK run takes whole steps of
    LONG_H (a tenth of a step off was rounded, and the run ended elsewhere than it said)."""
    from ...core.errors import InputError
    from ...core.validate import MAX_STEPS
    if t_long is None:
        return
    n = round(t_long / LONG_H)
    if t_long < LONG_SAMPLE or abs(n * LONG_H - t_long) > 1e-9 * max(1.0, t_long):
        raise InputError(f"--t-long must be at least {LONG_SAMPLE:g} (the long runs sample every {LONG_SAMPLE:g}; "
                         f"each half needs a sample) and a multiple of the SPARK step h = {LONG_H:g}, got {t_long:g}")
    if n > MAX_STEPS:       # refused by the SPARK run itself, but only after the whole study
        raise InputError(f"--t-long {t_long:g} is {n:.3g} steps of h = {LONG_H:g}, more than the limit {MAX_STEPS:.0e}")


#: the files of the report in OUTDIR (``driver.check_report_files``)
REPORT_FILES = ("work_precision.md", "work_precision.json")


def run(args) -> int:
    check_t_long(args.t_long)
    from .driver import check_report_files
    check_report_files(args.outdir, REPORT_FILES)
    run_study(args.outdir, quick=args.quick, t_long=args.t_long)
    return 0


def run_default(outdir="reports") -> None:
    run_study(outdir)
