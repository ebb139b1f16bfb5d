"""The best compiled SPARK method against the strongest peers, measured side by side in one run:
CyRK's compiled step loops (nbsolve2_ivp DOP853 and Vern8 with a numba cfunc right-hand side,
nbsolve_ivp DOP853, pysolve_ivp), scipy's ode('dop853') (Hairer's Fortran) and ode('lsoda'),
solve_ivp DOP853, SUNDIALS CVODE (Adams, BDF) and IDA on the index-1 form (CyRK and
scikit-sundae: pip install -e ".[bench]"; skipped with a note without them), every one with the
faster of a closed-form and a buffered numeric right-hand side compiled by numba from the same
sympy expressions as the SPARK model (``ldaspark.lab.reports.peers``).

Scenes: particle, skate, robot, mp-particles-nh (n = 7), relativistic (a general scene).
T = 100: CPU time at equal final error in q; T = 1e4: energy error and constraint drift vs CPU;
``--very-long skate``: T = 1e5 too, the strongest peers only. SPARK through the public
``ldaspark.integrate(..., engine="compiled")`` (the speed-ups) and the internal fast path (beside
them). Runs interleaved in rounds, CPU time the minimum over the rounds. Writes reports/peers.json
(rendered by ``ldaspark report work-precision`` as its "Strongest peers" section; README quotes
the speed-ups) and prints the speed-ups.

    python benchmarks/peers.py [--quick] [--scenes particle,skate] [--very-long skate] [--rounds 3]
                               [--newton quasi] [--out reports/peers.json]

--newton quasi: the SPARK runs through ldaspark.integrate use the quasi-Newton root finder
(``newton="quasi"``, ``ldaspark.compiled.kernels_quasi``; the internal fast path stays Newton's);
the JSON then records "newton": "quasi" and the command. The targets of issue 48 (skate final
error 1e-9 / 1e-12 at T = 100, energy 1e-8 at T = 1e4; particle energy 1e-10 at T = 1e4, with
gauss-6 and gauss-8) are measured side by side by benchmarks/quasi_step.py.
"""
from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from ldaspark.core.io import atomic_write_json                 # noqa: E402
from ldaspark.lab.reports.markdown import jsonable                 # noqa: E402
from ldaspark.lab.reports.peers import SCENES, run_study, speedup_text   # noqa: E402

# the generic kernel is timed, as in the reports: no specialised kernel built in the background
# mid-run (ldaspark.compiled.specialised; benchmarks/quasi_step.py times both)
os.environ.setdefault("LDASPARK_SPECIALISE", "0")


def _use_newton(kind):
    """The study's public SPARK runs (``peers.prepare_spark`` imports ``ldaspark.solve.integrate``
    when it prepares a run) made with newton=kind: ldaspark.solve.integrate wrapped for this process."""
    import functools
    from ldaspark import solve
    base = solve.integrate
    solve.integrate = functools.wraps(base)(functools.partial(base, newton=kind))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short intervals, few points (smoke run)")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--very-long", default="", help="scenes also run to T = 1e5 (comma-separated)")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds (CPU time: the minimum)")
    ap.add_argument("--out", default=os.path.join("reports", "peers.json"))
    ap.add_argument("--newton", default="auto", choices=("auto", "quasi"),
                    help="root finder of the SPARK runs through ldaspark.integrate (default: auto, the quasi "
                         "iteration where runner.auto_runs_quasi holds, the kernels' Newton elsewhere)")
    a = ap.parse_args(argv)
    if a.rounds < 1:
        print("peers.py: --rounds must be at least 1", file=sys.stderr)
        return 2
    if a.newton != "auto":
        _use_newton(a.newton)

    def mark(part):
        if a.newton != "auto":
            part["newton"] = a.newton
            part["command"] += f" --newton {a.newton}"
        return part
    d = run_study(tuple(a.scenes.split(",")), quick=a.quick, rounds=a.rounds,
                  very_long=tuple(x for x in a.very_long.split(",") if x),
                  on_scene=lambda part: atomic_write_json(a.out, jsonable(mark(part))))
    d = mark(d)
    atomic_write_json(a.out, jsonable(d))
    print(f"speed-up of the best compiled SPARK method over the best peer (cpu(peer) / cpu(SPARK)); "
          f"final error {' / '.join(f'{t:.0e}' for t in d['targets'])} at T = {d['studies'][0]['t_end']:g}; "
          f"energy error {' / '.join(f'{t:.0e}' for t in d['energy_targets'])} at T = {d['studies'][0]['t_long']:g}; "
          f"SPARK through ldaspark.integrate [internal fast path]")
    for st in d["studies"]:
        best = ", ".join(f"{r['peer']}" for r in st["speedups"] + st["long_speedups"])
        print(f"  {st['scene']:16s} {speedup_text(st['speedups'])} [{speedup_text(st['speedups_fast'])}]; "
              f"long: {speedup_text(st['long_speedups'])} [{speedup_text(st['long_speedups_fast'])}]"
              + (f"; T = {st['t_vlong']:g}: {speedup_text(st['vlong_speedups'])} "
                 f"[{speedup_text(st['vlong_speedups_fast'])}]" if "t_vlong" in st else "")
              + f" (best peers: {best}; rhs {st['rhs']['form']})")
        for x in st["notes"] + st["failed"]:
            print(f"    {x}")
    print(f"wrote {a.out} ({d['cpu_seconds']} s CPU; load average {d['load_average_1min_at_start']} at the start, "
          f"{d['load_average_1min_at_end']} at the end, {d['cpu_count']} CPUs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
