"""Time before the first step of a new model: building the ``LagrangianSystem`` (the symbolic
derivation) and the first compiled call (code generation of the model and numba's compilation
of its functions), each model in a fresh child process with an empty model cache (a new
LDASPARK_CACHE_DIR per model; the kernels are compiled once per machine and not counted).

Models: mp-particles-nh at n = 2m + 1 (the expressions of ``scenes.mp_particles``; the build is
timed on ``LagrangianSystem(L, k, q, v)`` alone, not on writing down L and k) and the Whipple
bicycle (``bicycle.build``: the build timed on ``LagrangianSystem.from_mechanics`` of the
prepared Lagrangian).

    python benchmarks/first_call.py [--n 21,121,1001] [--bicycle] [--kane3] [--no-call] [--timeout 900]

A size with a trailing "a" (``--n 121a``) leaves ``system.mechanical`` unset, as a user would: the
compiled engine then detects the mechanical form from the derived expressions.

Prints one JSON object per model: build_cpu, build_wall, first_call_cpu, first_call_wall (s).
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
ROOT = os.path.join(HERE, "..")


def _clock():
    return time.process_time(), time.perf_counter()


def _since(c):
    return time.process_time() - c[0], time.perf_counter() - c[1]


def child(model: str, call: bool) -> dict:
    sys.path.insert(0, ROOT)
    import sympy

    from ldaspark.core.system import LagrangianSystem
    out = {"model": model}
    if model == "kane3ref":            # initial values of sympy's bicycle (in another process: not timed)
        sys.path.insert(0, os.path.join(ROOT, "verification"))
        import test_mechanics_kane3 as k3
        q0, v0 = k3._reference()[:2]
        return {"q0": [float(x) for x in q0], "v0": [float(x) for x in v0]}
    if model == "kane3":
        # sympy's own Whipple bicycle (test_kane3, as verification/test_mechanics_kane3 writes it):
        # the KanesMethod built untimed (kane_cpu), then from_mechanics (the build) and the first call
        sys.path.insert(0, os.path.join(ROOT, "verification"))
        import test_mechanics_kane3 as k3
        c = _clock()
        KM = k3._model()[0]
        out["kane_cpu"], out["kane_wall"] = _since(c)
        c = _clock()
        system = LagrangianSystem.from_mechanics(KM, name="bicycle")
        out["build_cpu"], out["build_wall"] = _since(c)
        ref = json.loads(os.environ["LDAFIRST_KANE3"])
        system = system.with_params(k3._values())
        t0, q0, v0 = 0.0, ref["q0"], ref["v0"]
    elif model == "bicycle":
        from ldaspark.models import bicycle
        orig = LagrangianSystem.from_mechanics.__func__
        spent = []

        def timed(cls, *a, **kw):
            c = _clock()
            try:
                return orig(cls, *a, **kw)
            finally:
                spent.append(_since(c))
        LagrangianSystem.from_mechanics = classmethod(timed)
        c = _clock()
        sc = bicycle.bicycle()
        out["scene_cpu"], out["scene_wall"] = _since(c)
        out["build_cpu"], out["build_wall"] = spent[0]
        system = sc.system
        t0, q0, v0 = sc.initial()
    else:
        auto = model.endswith("a")          # "121a": the mechanical form detected, not given
        n = int(model.rstrip("a"))
        m = (n - 1) // 2
        q = list(sympy.symbols(f"q0:{n}"))
        v = list(sympy.symbols(f"v0:{n}"))
        U = (sum(x ** 2 for x in q) + q[m + 1] ** 2 * q[m + 2] ** 2
             + sum(q[i] ** 2 * q[m + i] ** 2 for i in range(1, m + 1))) / 2
        L = sum(x ** 2 for x in v) / 2 - U
        k = [v[0] + sum(q[i - 1 - m] * v[i - 1] for i in range(m + 2, n + 1))]
        c = _clock()
        system = LagrangianSystem(L, k, q, v, name="mp-particles-nh")
        out["build_cpu"], out["build_wall"] = _since(c)
        if not auto:
            system.mechanical = {"M": sympy.eye(n), "U": U, "K": sympy.Matrix([k]).jacobian(v),
                                 "b": sympy.zeros(1, 1)}
        t0 = 0
        q0 = [1.0] + [2 * (m - i) / 10 for i in range(m)] + [1.0] * m
        v0 = [0.0] * n
    if call:
        from ldaspark.compiled import fast
        c = _clock()
        cs = fast.compile_system(system)
        r = fast.run_compiled(cs, "gauss-2", float(t0), [float(x) for x in q0], [float(x) for x in v0], 0.001, 1)
        out["first_call_cpu"], out["first_call_wall"] = _since(c)
        out["form"] = cs.form
        out["q1_0"] = float(r.q[-1][0])
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", default="21,121,1001")
    ap.add_argument("--bicycle", action="store_true")
    ap.add_argument("--kane3", action="store_true", help="sympy's bicycle from its KanesMethod (test_kane3)")
    ap.add_argument("--no-call", action="store_true")
    ap.add_argument("--timeout", type=float, default=900)
    ap.add_argument("--child", default=None)
    args = ap.parse_args(argv)
    if args.child == "warm":   # every kernel a model below may run, compiled into numba's cache
        sys.path.insert(0, ROOT)
        from ldaspark.compiled import runner
        for name in ("spark_run", "spark_sparse_run", "general_run", "lf2_run"):
            runner._entry(name)
        return 0
    if args.child is not None:
        print(json.dumps(child(args.child, not args.no_call)))
        return 0
    models = [x for x in args.n.split(",") if x] + (["bicycle"] if args.bicycle else []) + \
        (["kane3"] if args.kane3 else [])
    kane3 = {}
    if args.kane3:
        p = subprocess.run([sys.executable, os.path.abspath(__file__), "--child", "kane3ref"], capture_output=True,
                           text=True, env=dict(os.environ, PYTHONPATH=ROOT), timeout=args.timeout)
        kane3 = {"LDAFIRST_KANE3": p.stdout.strip().splitlines()[-1]}
    if not args.no_call:       # the kernels compiled (or loaded) once, outside the timings
        subprocess.run([sys.executable, os.path.abspath(__file__), "--child", "warm"], capture_output=True,
                       env=dict(os.environ, PYTHONPATH=ROOT), timeout=args.timeout)
    for model in models:
        with tempfile.TemporaryDirectory(prefix="ldafirst-") as d:
            env = dict(os.environ, LDASPARK_CACHE_DIR=os.path.join(d, "cache"), PYTHONPATH=ROOT, **kane3)
            cmd = [sys.executable, os.path.abspath(__file__), "--child", model] + (["--no-call"] if args.no_call else [])
            try:
                p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=args.timeout)
                line = p.stdout.strip().splitlines()[-1] if p.stdout.strip() else json.dumps(
                    {"model": model, "error": p.stderr.strip().splitlines()[-1:]})
            except subprocess.TimeoutExpired:
                line = json.dumps({"model": model, "error": f"timeout {args.timeout} s"})
        print(line, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
