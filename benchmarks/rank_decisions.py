"""Rank decisions of the claims ledger: the full-precision SVD of all of J against the Schur
complement of its small block (``Backend.small_singular_values``), side by side on the same
matrices.

Runs every ``step``-th (tableau, scene) unit of the main job's claims section, records each
matrix ``_rank_info`` sees, then decides each one both ways and prints the deficiencies that
differ (none expected), the largest relative difference of the nonzero singular values and the
CPU time of each way.

    python benchmarks/rank_decisions.py [--step 7] [--units 10]
"""
from __future__ import annotations

import argparse
import contextlib
import io
import time

import mpmath

from ldaspark.lab.reports import claims
from ldaspark.analysis import discrete as D
from ldaspark.analysis import wellposedness as W


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=int, default=7, help="every step-th ledger unit")
    ap.add_argument("--units", type=int, default=10, help="at most this many units")
    a = ap.parse_args(argv)
    seen = []
    rank_info = D._rank_info

    def spy(bk, J, dps):
        seen.append((bk, J.copy(), dps, mpmath.mp.prec))
        return rank_info(bk, J, dps)
    D._rank_info = W._rank_info = spy
    try:
        units = [j for j in claims.jobs() if j[0][0] == "unit"][::a.step][:a.units]
        with contextlib.redirect_stdout(io.StringIO()):
            for _, fn, args, _ in units:
                getattr(claims, fn)(*args)
    finally:
        D._rank_info = W._rank_info = rank_info
    cpu = {False: 0.0, True: 0.0}
    differ, worst, candidates = 0, 0.0, 0
    for bk, J, dps, prec in seen:
        if not bk.is_mp:
            continue
        out = {}
        with mpmath.workprec(prec):
            for schur in (False, True):
                D.RANK_BY_SCHUR = schur
                t = time.process_time()
                out[schur] = rank_info(bk, J, dps)
                cpu[schur] += time.process_time() - t
        D.RANK_BY_SCHUR = True
        (sa, ra, _, _), (sb, rb, _, _) = out[False], out[True]
        differ += ra != rb
        s0 = float(sa[0])
        candidates += float(sa[-1]) <= 1e-9 * s0
        for x, y in zip(sa, sb):
            x, y = float(x), float(y)
            if x > 10.0 ** (-dps / 2) * s0:
                worst = max(worst, abs(x - y) / x)
    print(f"{len(seen)} rank decisions ({candidates} with a candidate deficiency) from {len(units)} units")
    print(f"deficiencies that differ: {differ}; largest relative difference of a nonzero sigma: {worst:.2e}")
    print(f"CPU: full SVD {cpu[False]:.2f} s, Schur complement {cpu[True]:.2f} s")
    return 1 if differ else 0


if __name__ == "__main__":
    raise SystemExit(main())
