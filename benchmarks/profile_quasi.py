"""Where the quasi-Newton step's CPU goes: run one scene and method with the compiled quasi kernel
(specialised to the run's (s, n, m), or the generic one) and write a perf map of the JIT code, so
that ``perf report`` names numba's functions instead of printing addresses.

    perf record -o /tmp/quasi.data python benchmarks/profile_quasi.py skate gauss-6 1.5625 --runs 400
    perf report -i /tmp/quasi.data --sort sym

numba keeps no perf map of its own and gives the IR (and so the function names) only of code it
compiled in this process, so the script compiles into fresh cache directories (LDASPARK_CACHE_DIR,
NUMBA_CACHE_DIR; ~30-60 s) before the runs. The map is /tmp/perf-<pid>.map (perf's convention for
JIT code); each function's extent is taken to the next function's address, so code LLVM inlined is
counted in its caller. The model's functions (``native``) stay unnamed addresses, libm's sin / cos
are named by perf. What this found: docs/changelog.md, "The quasi step without its call overhead".
"""
from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("method")
    ap.add_argument("h", type=float)
    ap.add_argument("--runs", type=int, default=200, help="runs of --steps steps after the compile")
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--generic", action="store_true", help="the generic kernel instead of the specialised one")
    args = ap.parse_args(argv)
    # before numba is imported: the cache directories it and ldaspark read
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="profile_quasi_numba_")
    os.environ["LDASPARK_CACHE_DIR"] = tempfile.mkdtemp(prefix="profile_quasi_ldaspark_")
    os.environ["LDASPARK_SPECIALISE"] = "0" if args.generic else "1"
    import numpy as np
    from ldaspark.compiled import kernels_quasi as KQ, specialised as SP
    from ldaspark.compiled.fast import compile_system
    from ldaspark.compiled.quasi import entry, run_quasi
    from ldaspark.core.families import get_method
    from ldaspark.models.scenes import get_scene
    SP.BUILD_AFTER = float("inf")
    sc = get_scene(args.scene)
    cs = compile_system(sc.system)
    if cs.form != "mechanical":
        raise SystemExit(f"{args.scene}: general form; this script profiles the mechanical quasi kernel")
    s = get_method(args.method).s
    if args.generic:
        entry()
        disp = KQ.quasi_run
    else:
        SP.build(s, cs.n, cs.m)
        disp = SP._module(s, cs.n, cs.m).quasi_run
    t0, q0, v0 = sc.initial()[:3]
    t0, q0, v0 = float(t0), np.array(q0, float), np.array(v0, float)
    r = run_quasi(cs, args.method, t0, q0, v0, args.h, 10)
    if bool(r.stats["kernel_specialised"]) == args.generic:
        raise SystemExit("the kernel that ran is not the one asked for")
    lib = disp.overloads[tuple(KQ.QUASI_SIG.args)].library
    names = set(re.findall(r"^define [^@]*@\"?([^\"(]+)\"?\(", lib.get_llvm_str(), re.M))
    addrs = sorted((a, nm) for nm in names for a in [lib.get_pointer_to_function(nm)] if a)
    path = f"/tmp/perf-{os.getpid()}.map"
    with open(path, "w") as f:
        for i, (a, nm) in enumerate(addrs):
            nxt = addrs[i + 1][0] - a if i + 1 < len(addrs) else 0
            size = nxt if 0 < nxt < 1 << 20 else 0x4000
            # numba's mangled name without its type signature: module and function
            short = re.sub(r"B\d+v\d+B\d+c8tJTI.*", "", nm)
            f.write(f"{a:x} {size:x} {short[-80:]}\n")
    c = time.process_time()
    for _ in range(args.runs):
        r = run_quasi(cs, args.method, t0, q0, v0, args.h, args.steps, every=args.steps)
    us = (time.process_time() - c) / (args.runs * args.steps) * 1e6
    st = r.stats
    print(f"{args.scene} {args.method} h = {args.h:g}: {us:.3f} us per step, "
          f"{st['newton_iterations'] / max(st['steps'], 1):.3f} iterations per step, "
          f"kernel_specialised {st['kernel_specialised']}; perf map {path} ({len(addrs)} functions)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
