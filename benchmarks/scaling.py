"""Cost of the compiled SPARK step against the system size n, on the McLachlan-Perlmutter particles
with the nonholonomic constraint (``mp_particles(m, constraint="nonholonomic")``, n = 2m + 1,
one constraint), gauss-2 (and gauss-3 where it fits), h = 0.001.

Per n, in a child process of its own (a fresh process, so that nothing is cached in memory;
numba's and the model cache on disk are emptied by a fresh LDASPARK_CACHE_DIR):

* build: CPU seconds to build the scene (sympy: L, k, the Hessians);
* first call: CPU seconds of the first ``fast_integrate`` of 2 steps (code generation of the
  model, numba compilation of its functions; the kernels themselves are compiled once per machine
  and loaded from numba's cache, so their compilation is not included);
* per step: CPU microseconds per step of a run long enough to take ~0.3 s (minimum of 3),
  with the mean Newton iterations per step.

Writes reports/scaling.json (rendered by ``ldaspark report work-precision`` as its "Scale"
section); a size that does not finish within --timeout seconds is recorded as such.

    python benchmarks/scaling.py [--n 21,61,121,1001] [--timeout 900] [--out reports/scaling.json]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))


def child(n, method, h):
    """One size in this process; prints one JSON line."""
    from ldaspark.compiled import fast
    from ldaspark.core.scenes import mp_particles
    fast._kernels().entry_point("spark_run")           # the kernel from numba's cache, off the clock
    m = (n - 1) // 2
    c = time.process_time()
    sc = mp_particles(m=m, constraint="nonholonomic")
    build = time.process_time() - c
    print(f"built the scene: {build:.1f} s CPU", file=sys.stderr, flush=True)
    c = time.process_time()
    cs = fast.compile_system(sc.system)
    print(f"generated the model source ({len(cs.source)} chars): {time.process_time() - c:.1f} s CPU",
          file=sys.stderr, flush=True)
    fast.fast_integrate(sc, method, h=h, n_steps=2)
    first = time.process_time() - c
    print(f"first call (2 steps): {first:.1f} s CPU", file=sys.stderr, flush=True)
    c = time.process_time()
    fast.fast_integrate(sc, method, h=h, n_steps=5)
    probe = max((time.process_time() - c) / 5, 1e-7)
    steps = int(min(max(0.3 / probe, 10), 200000))
    best, r = float("inf"), None
    for _ in range(3):
        c = time.process_time()
        r = fast.fast_integrate(sc, method, h=h, n_steps=steps, every=steps)
        best = min(best, time.process_time() - c)
    src = fast.compile_system(sc.system).source
    print(json.dumps({"n": n, "m_constraints": 1, "method": method, "h": h, "build_cpu": build,
                      "first_call_cpu": first, "us_per_step": best / steps * 1e6, "steps": steps,
                      "mean_iterations": r.stats["mean_iterations"], "model_source_chars": len(src),
                      "status": "ok"}))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", default="21,61,121,1001")
    ap.add_argument("--methods", default="gauss-2")
    ap.add_argument("--h", type=float, default=0.001)
    ap.add_argument("--timeout", type=float, default=900.0)
    ap.add_argument("--out", default=os.path.join("reports", "scaling.json"))
    ap.add_argument("--child", nargs=3, metavar=("N", "METHOD", "H"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        child(int(a.child[0]), a.child[1], float(a.child[2]))
        return
    rows = []
    for method in a.methods.split(","):
        for n in (int(x) for x in a.n.split(",")):
            env = dict(os.environ, LDASPARK_CACHE_DIR=tempfile.mkdtemp(prefix="ldscale-"))
            t = time.perf_counter()
            try:
                p = subprocess.run([sys.executable, os.path.abspath(__file__), "--child", str(n), method, str(a.h)],
                                   capture_output=True, text=True, timeout=a.timeout, env=env)
                lines = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
                row = json.loads(lines[-1]) if p.returncode == 0 and lines else {
                    "n": n, "method": method, "status": f"failed: {(p.stderr.strip().splitlines() or ['?'])[-1][:200]}"}
            except subprocess.TimeoutExpired as exc:
                err = exc.stderr.decode() if isinstance(exc.stderr, bytes) else (exc.stderr or "")
                done = [ln for ln in err.splitlines() if ln and not ln.startswith(" ")]
                row = {"n": n, "method": method, "status": f"did not finish in {a.timeout:g} s wall"
                       + (f" (done: {'; '.join(done[-3:])})" if done else " (the scene was not built)")}
            row["wall"] = time.perf_counter() - t
            rows.append(row)
            print(json.dumps(row), flush=True)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    out = {"command": "python benchmarks/scaling.py " + " ".join(argv or sys.argv[1:]),
           "date": time.strftime("%Y-%m-%d"), "cpu_count": os.cpu_count(),
           "load_average_1min_at_end": None if load is None else round(load, 2), "rows": rows}
    from ldaspark.core.io import atomic_write_json
    atomic_write_json(a.out, out)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
