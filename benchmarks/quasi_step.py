"""The quasi-Newton root finder of the SPARK step (``integrate(..., newton="quasi")``,
``ldaspark.compiled.kernels_quasi``) measured side by side with the compiled Newton step and with
the strongest compiled peers (CyRK's nbsolve2_ivp DOP853 and Vern8 with a numba cfunc right-hand
side, ``ldaspark.lab.reports.peers``), all in one run: CPU time (process time), the minimum over
interleaved rounds, SPARK always through the public ``ldaspark.integrate``.

Part 1 (``per_step``): CPU per step of newton="quasi" (what the default runs on these scenes)
with the kernel specialised to the run's (s, n, m) (``ldaspark.compiled.specialised``, built
before the clock starts, as a long-lived process has it once BUILD_AFTER seconds were spent in the
generic one), the same with the generic kernel (what every run gets first; the same bits) and the
compiled kernels' Newton (the default before it chose the quasi iteration) on the same run
(scene, method, h, 20000 steps), with iterations per step and fallbacks.
Part 2 (``targets``): the targets of issue 48 at equal error, cpu(best peer) / cpu(best SPARK):
skate T = 100 final error 1e-9 and 1e-12; skate T = 1e4 max energy error 1e-8; particle T = 1e4
max energy error 1e-10; SPARK gauss-2, 3, 4, 6, 8 with each of the three, gauss-6 and gauss-8 on
step grids fine enough that the best step for a target is among them (``STUDIES``). Every task
runs for at least MIN_CPU seconds a round (short runs repeated), its CPU the minimum of all runs.

    python benchmarks/quasi_step.py [--rounds 3] [--quick] [--tol-kappa K] [--out reports/quasi_step.json]

--tol-kappa K: the quasi rows (specialised kernel) also run with ``ldaspark.Newton(tol=K * target)``
for each target of a study, the speed-up at a target taken from its own rows ("quasi_tol"): the
rule a user trading accuracy for speed would apply (one K for every scene; K = 1 keeps the
estimated error a step leaves at RATE_KAPPA * target * max|x, v0|, docs/performance.md).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import ldaspark                                                          # noqa: E402
from ldaspark.models.scenes import get_scene                             # noqa: E402
from ldaspark.lab.reports import peers as P                                  # noqa: E402
from ldaspark.compiled import specialised as SP                               # noqa: E402

SP.BUILD_AFTER = float("inf")       # no build in the background: the kernels needed are built first

PER_STEP = (("skate", "gauss-2", 0.1), ("skate", "gauss-4", 0.4), ("skate", "gauss-8", 1.25),
            ("particle", "gauss-2", 0.05), ("particle", "gauss-4", 0.2), ("particle", "gauss-6", 0.4),
            ("robot", "gauss-2", 0.05), ("mp-particles-nh", "gauss-3", 0.01), ("rolling-disk", "gauss-4", 0.2))
PEERS = ("cyrk-nbsolve2-DOP853", "cyrk-nbsolve2-Vern8")
#: the SPARK rows: the quasi-Newton root finder with the kernel specialised to (s, n, m) (built
#: before the clock starts; general-form systems have none and run the generic one), the same
#: with the generic kernel, and the kernels' Newton
VARIANTS = ("quasi", "quasi-generic", "newton")
#: (scene, T, key, targets, SPARK step sizes per method, peer rtols, samples). A user picks the
#: step that just meets the target, as a peer's user picks its tolerance: the steps of gauss-6 and
#: gauss-8 near the targets are T / N for N about 1.1-1.25x apart (an error of order 2s = 16 changes
#: 10-30x between them, as the peers' errors do between tolerances 10x apart), the rest halve
STUDIES = (
    ("skate", 100.0, "error", (1e-9, 1e-12),
     {"gauss-2": (0.05, 0.025, 0.0125, 0.00625), "gauss-3": (0.2, 0.1, 0.05, 0.025),
      "gauss-4": (0.8, 0.4, 0.25, 0.2, 0.125, 0.1),
      "gauss-6": tuple(100.0 / N for N in (80, 100, 120, 140, 160, 200, 250, 320)),
      "gauss-8": tuple(100.0 / N for N in (40, 48, 56, 64, 72, 80, 100, 120, 160))},
     (1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14), 1),
    ("skate", 1e4, "energy_error", (1e-8,),
     {"gauss-3": (0.4, 0.2, 0.1), "gauss-4": (1.0, 0.8, 0.4),
      "gauss-6": tuple(1e4 / N for N in (5000, 6000, 6400, 7000, 8000, 16000)),
      "gauss-8": tuple(1e4 / N for N in (4000, 4400, 5000, 8000))},
     (1e-8, 1e-9, 1e-10, 1e-11, 1e-12), 200),
    ("particle", 1e4, "energy_error", (1e-10,),
     {"gauss-3": (0.1, 0.05), "gauss-4": (0.25, 0.2, 0.1),
      "gauss-6": tuple(1e4 / N for N in (20000, 22500, 25000, 50000)),
      "gauss-8": tuple(1e4 / N for N in (10000, 12500, 14000, 16000, 32000))},
     (1e-9, 1e-10, 1e-11, 1e-12, 1e-13), 200),
)
#: CPU seconds each task runs for in every round of a study (``peers.run_interleaved``'s
#: min_cpu): a 0.1-0.5 ms run (the skate to T = 100, SPARK and peers alike) is timed ~100-500
#: times a round, its minimum taken, instead of once
MIN_CPU = 0.05


def spark_task(scene, method, h, t_end, n_out, newton, tol=None):
    """(label, go, finish) of one run through ldaspark.integrate (compiled once outside the clock);
    tol: the Newton increment tolerance (``ldaspark.Newton(tol=...)``, None: round-off), the
    "quasi" variant only (``--tol-kappa``)."""
    sc = get_scene(scene)
    t0 = float(sc.initial()[0])
    n = int(round((t_end - t0) / h))
    every = max(n // n_out, 1)
    # "newton": the kernels' Newton, which newton="auto" ran before it chose the quasi iteration
    # (runner.auto_runs_quasi); an explicit reuse asks for the Newton matrix, and for n < 32 reuse is
    # off either way. "auto" (the default) runs the quasi iteration on these scenes: the "quasi" rows.
    # "quasi-generic": the same root finder with the generic kernel (what a run gets before the
    # kernel specialised to its (s, n, m) is built: compiled.specialised)
    kw = {"newton": ldaspark.Newton(reuse=False)} if newton == "newton" else {"newton": ldaspark.Newton("quasi", tol=tol)}
    special = "1" if newton == "quasi" else "0"
    if newton == "quasi":
        sc_ = get_scene(scene)
        from ldaspark.compiled.fast import compile_system
        from ldaspark.core.families import get_method
        cs = compile_system(sc_.system)
        if cs.form == "mechanical":
            SP.build(get_method(method).s, cs.n, cs.m)      # compiled or loaded now, outside the clock
    os.environ["LDASPARK_SPECIALISE"] = special
    ldaspark.integrate(scene, method, h=h, n_steps=2, engine="compiled", **kw)

    def go():
        os.environ["LDASPARK_SPECIALISE"] = special
        return ldaspark.integrate(scene, method, h=h, n_steps=n, engine="compiled", save_every=every, **kw)

    def finish(cpu, r):
        st = r.stats
        if newton != "newton" and bool(st.get("kernel_specialised")) != (newton == "quasi"):
            if st.get("form") == "mechanical" or newton == "quasi-generic":
                raise RuntimeError(f"{scene} {method}: kernel_specialised={st.get('kernel_specialised')} "
                                   f"in a {newton} row")
        kind = {"quasi": "spark-quasi", "quasi-generic": "spark-quasi-generic", "newton": "spark"}[newton]
        if tol is not None:
            kind += f"-tol{tol:g}"
        return {"kind": kind, "method": method, "param": h, "tol": tol, "specialised": bool(st.get("kernel_specialised")),
                "cpu": cpu, "steps": n, "q_final": [float(x) for x in r.q[-1]],
                "energy_error": float(np.max(np.abs(r.energy - r.energy[0]))),
                "constraint": float(np.max(np.abs(r.constraint))),
                "iterations_per_step": st["newton_iterations"] / max(st["steps"], 1),
                "fallbacks": st.get("quasi_fallbacks"), "curvature_steps": st.get("curvature_steps"),
                "rate_first_steps": st.get("rate_first_steps")}
    return f"{scene} {method} h={h:g} T={t_end:g} {newton}" + (f" tol={tol:g}" if tol is not None else ""), go, finish


#: the yardstick rate of docs/performance.md's "The step at its operation count" (flops per
#: second of the kernels' own lu_factor on a 64 x 64 matrix on this CPU)
RATE = 4.37e9


def quasi_flops(s, n, m, nnz_M, nnz_Minv, iterations, curvature=False):
    """Counted flops (one per multiplication or addition) of one quasi-Newton step with
    ``iterations`` increments (as many residuals: the predictor's and one after every increment
    but the last), the model's own operations not counted (s + 1 points of grad U, K, b per
    residual, k_q at s + 1 points and Hess U at one per step). curvature: the velocity block with
    Hess U (``kernels_quasi.curvature_matrix``, ``curvature_increment``), its decomposition (once
    per run for a constant Hessian) not counted. Returns (total, multiplier matrix + its LU)."""
    k = iterations
    residual = (2 * s * s * n + 2 * s * n + 2 * nnz_M * (s + 1) + 4 * s * (s + 1) * n + 4 * s * m * n
                + 2 * (s - 1) * s * m + 2 * m * n)
    if curvature:
        N1 = (s + 1) * n
        apply_c = 2 * s * s * n + 4 * s * m * n + 2 * (s - 1) * s * m + 2 * s * n + 4 * m * n
        matrix = s * m * (2 * N1 * n + apply_c) + 2 * (s * m) ** 3 / 3
        increment = 2 * N1 * N1 + apply_c + 2 * (s * m) ** 2 + 2 * N1 * s * m + s * m
        return k * (residual + increment) + matrix, matrix
    matrix = (2 * s * m * nnz_Minv + 4 * s * s * m * m * n + 4 * (s - 1) * s * s * m * m + 4 * s * m * m * n
              + 2 * (s * m) ** 3 / 3)
    increment = (2 * (s + 1) * nnz_Minv + 2 * s * s * n + 4 * s * m * n + 2 * (s - 1) * s * m + 2 * s * m * n
                 + 4 * m * n + 2 * (s * m) ** 2 + 2 * s * n * m + 2 * (s + 1) * s * n)
    return k * (residual + increment) + matrix, matrix


def per_step(rounds, quick):
    tasks = []
    for scene, method, h in PER_STEP:
        n = 2000 if quick else 20000
        for newton in VARIANTS:
            tasks.append(spark_task(scene, method, h, n * h, 1, newton))
    rows = P.run_interleaved(tasks, rounds=rounds, short=10.0)
    out = []
    for i in range(0, len(rows), 3):
        q, qg, nw = rows[i], rows[i + 1], rows[i + 2]
        dg = float(np.max(np.abs(np.asarray(q["q_final"]) - np.asarray(qg["q_final"]))))
        d = float(np.max(np.abs(np.asarray(q["q_final"]) - np.asarray(nw["q_final"]))))
        from ldaspark.compiled.fast import compile_system
        from ldaspark.core.families import get_method
        sc = get_scene(PER_STEP[i // 3][0])
        cs = compile_system(sc.system)
        fl, flm = quasi_flops(get_method(q["method"]).s, cs.n, cs.m, int(np.count_nonzero(cs.M)),
                              int(np.count_nonzero(cs.Minv)), q["iterations_per_step"],
                              curvature=2 * (q["curvature_steps"] or 0) > q["steps"])
        out.append({"scene": PER_STEP[i // 3][0], "method": q["method"], "h": q["param"],
                    "us_per_step_quasi": 1e6 * q["cpu"] / q["steps"], "specialised": q["specialised"],
                    "us_per_step_quasi_generic": 1e6 * qg["cpu"] / qg["steps"],
                    "specialised_speedup": qg["cpu"] / q["cpu"], "generic_speedup": nw["cpu"] / qg["cpu"],
                    "specialised_q_difference": dg,
                    "us_per_step_newton": 1e6 * nw["cpu"] / nw["steps"],
                    "speedup": nw["cpu"] / q["cpu"], "iterations_quasi": q["iterations_per_step"],
                    "iterations_newton": nw["iterations_per_step"], "fallbacks": q["fallbacks"],
                    "final_q_difference": d, "counted_flops": fl, "counted_flops_matrix": flm,
                    "curvature_steps": q["curvature_steps"],
                    "counted_us": 1e6 * fl / RATE})
    return out


def study(scene, t_end, key, targets, hs, rtols, n_out, rounds, quick, tol_kappa=None):
    """One study of STUDIES. tol_kappa: the quasi rows also run with the Newton tolerance a user
    trading accuracy for speed would set from the target, tol = tol_kappa * target (the same
    rule for every scene and target; ``--tol-kappa``), compared with the peers at that target only."""
    sc = get_scene(scene)
    if quick:
        t_end = min(t_end, 100.0)
    sp = [spark_task(scene, m, h, t_end, n_out, nw) for m, hl in hs.items() for h in hl for nw in VARIANTS]
    if tol_kappa is not None:
        sp += [spark_task(scene, m, h, t_end, n_out, "quasi", tol_kappa * tgt)
               for tgt in targets for m, hl in hs.items() for h in hl]
    pt = []
    failed = []
    for p in PEERS:
        for tol in rtols:
            try:
                pt.append((f"{p} rtol {tol:g}", *P.prepare_peer(sc, p, tol, t_end, n_out)))
            except P.PeerFailure as exc:
                failed.append(f"{p} rtol {tol:g}: {exc}")
    tasks = []
    for i in range(max(len(sp), len(pt))):
        tasks += sp[i:i + 1] + pt[i:i + 1]
    rows = P.run_interleaved(tasks, rounds=rounds, short=1.0, failed=failed, min_cpu=MIN_CPU)
    if key == "error":
        q_ref = P.reference_final(sc, t_end)[0]
        for r in rows:
            r["error"] = float(np.max(np.abs(np.asarray(r["q_final"]) - q_ref)))
    for r in rows:
        r.pop("q_final", None)
    res = {"scene": scene, "t_end": t_end, "key": key, "failed": failed, "rows": rows,
           "quasi": P.speedups(rows, targets, key=key, spark="spark-quasi"),
           "quasi_generic": P.speedups(rows, targets, key=key, spark="spark-quasi-generic"),
           "newton": P.speedups(rows, targets, key=key, spark="spark")}
    if tol_kappa is not None:
        res["tol_kappa"] = tol_kappa
        res["quasi_tol"] = [P.speedups(rows, (tgt,), key=key, spark=f"spark-quasi-tol{tol_kappa * tgt:g}")[0]
                            for tgt in targets]
    return res


def _ratio(s):
    for k, pre in (("speedup", ""), ("speedup_at_least", ">= "), ("speedup_at_most", "<= ")):
        if s.get(k) is not None:
            return (f"{pre}{s[k]:.2f} ({s['spark']} {s['spark_cpu'] * 1e3:.1f} ms vs {s['peer']} "
                    f"{s['peer_cpu'] * 1e3:.1f} ms)")
    return f"none (SPARK {s['spark']}, peer {s['peer']})"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--skip-steps", action="store_true")
    ap.add_argument("--studies", default="0,1,2")
    ap.add_argument("--out", default=os.path.join("reports", "quasi_step.json"))
    ap.add_argument("--tol-kappa", type=float, default=None,
                    help="also run the quasi rows with Newton(tol = KAPPA * target) per target (a user's "
                         "accuracy-for-speed rule; the first increment is then accepted on the carried rate)")
    a = ap.parse_args(argv)
    if a.tol_kappa is not None and not (a.tol_kappa > 0 and np.isfinite(a.tol_kappa)):
        print("quasi_step.py: --tol-kappa must be a finite positive number", file=sys.stderr)
        return 2
    load0 = os.getloadavg()[0]
    c0 = time.process_time()
    out = {"load_average_1min_at_start": load0, "cpu_count": os.cpu_count(), "rounds": a.rounds}
    if not a.skip_steps:
        out["per_step"] = per_step(a.rounds, a.quick)
        print("CPU per step, quasi vs Newton (same run, min of interleaved rounds, through ldaspark.integrate):")
        for r in out["per_step"]:
            print(f"  {r['scene']:16s} {r['method']:8s} h={r['h']:<6g} quasi {r['us_per_step_quasi']:6.2f} us "
                  f"({r['iterations_quasi']:.2f} it, {r['fallbacks']} fallbacks; generic kernel "
                  f"{r['us_per_step_quasi_generic']:.2f} us, x{r['specialised_speedup']:.2f}, "
                  f"|dq| {r['specialised_q_difference']:.0e})  "
                  f"newton {r['us_per_step_newton']:6.2f} us ({r['iterations_newton']:.2f} it)  "
                  f"speed-up {r['speedup']:.2f}  |dq_final| {r['final_q_difference']:.1e}  "
                  f"counted {r['counted_flops']:.0f} flops = {r['counted_us']:.2f} us")
    out["studies"] = []
    for i in (int(x) for x in a.studies.split(",") if x):
        st = study(*STUDIES[i], rounds=a.rounds, quick=a.quick, tol_kappa=a.tol_kappa)
        out["studies"].append(st)
        print(f"{st['scene']} T = {st['t_end']:g}, {st['key']}: cpu(best of {', '.join(PEERS)}) / cpu(best SPARK)")
        for q, qg, nw in zip(st["quasi"], st["quasi_generic"], st["newton"]):
            print(f"  target {q['target']:.0e}: quasi {_ratio(q)}; generic kernel {_ratio(qg)}; newton {_ratio(nw)}")
        for qt in st.get("quasi_tol", ()):
            print(f"  target {qt['target']:.0e}: quasi with tol = {a.tol_kappa:g} * target {_ratio(qt)}")
        for f in st["failed"]:
            print(f"  failed: {f}")
    out["load_average_1min_at_end"] = os.getloadavg()[0]
    out["cpu_seconds"] = time.process_time() - c0
    with open(a.out, "w") as fh:
        json.dump(out, fh, indent=1, default=float)
    print(f"wrote {a.out}; load average {load0:.1f} at the start, {out['load_average_1min_at_end']:.1f} at the end "
          f"({out['cpu_count']} CPUs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
