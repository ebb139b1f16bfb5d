"""The best compiled SPARK method against the strongest peers, measured side by side in one run:
scipy's ode('dop853') (Hairer's Fortran) and ode('lsoda'), solve_ivp DOP853, SUNDIALS CVODE
(Adams, BDF) and IDA on the index-1 form (scikit-sundae: pip install -e ".[bench]"; skipped
with a note without it), every one with a right-hand side compiled by numba from the same sympy
expressions as the SPARK model (``ldaspark.reports.peers``).

Scenes: particle, skate, robot, mp-particles-nh (n = 7), relativistic (a general scene).
T = 100: CPU time at equal final error in q; T = 1e4: energy error and constraint drift vs CPU.
Writes reports/peers.json (rendered by ``ldaspark report work-precision`` as its "Strongest
peers" section; README quotes the speed-ups) and prints the speed-ups.

    python benchmarks/peers.py [--quick] [--scenes particle,skate] [--out reports/peers.json]
"""
from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from ldaspark.core.io import atomic_write_json                 # noqa: E402
from ldaspark.reports.markdown import jsonable                 # noqa: E402
from ldaspark.reports.peers import SCENES, run_study, speedup_text   # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short intervals, few points (smoke run)")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--out", default=os.path.join("reports", "peers.json"))
    a = ap.parse_args(argv)
    d = run_study(tuple(a.scenes.split(",")), quick=a.quick,
                  on_scene=lambda part: atomic_write_json(a.out, jsonable(part)))
    atomic_write_json(a.out, jsonable(d))
    print(f"speed-up of the best compiled SPARK method over the best peer (cpu(peer) / cpu(SPARK)); "
          f"final error {' / '.join(f'{t:.0e}' for t in d['targets'])} at T = {d['studies'][0]['t_end']:g}; "
          f"energy error {' / '.join(f'{t:.0e}' for t in d['energy_targets'])} at T = {d['studies'][0]['t_long']:g}")
    for st in d["studies"]:
        best = ", ".join(f"{r['peer']}" for r in st["speedups"])
        print(f"  {st['scene']:16s} {speedup_text(st['speedups']):24s} (best peers: {best}); "
              f"long: {speedup_text(st['long_speedups'])}")
        for x in st["notes"] + st["failed"]:
            print(f"    {x}")
    print(f"wrote {a.out} ({d['cpu_seconds']} s CPU)")


if __name__ == "__main__":
    main()
