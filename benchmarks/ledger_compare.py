"""Compare two claims-ledger JSON files record by record (``ldaspark verify --outdir DIR`` writes
DIR/claims.json): the same records in the same order, the same verdict (status, expected) and
well-posedness class for each, and the ratio of the residuals.

    python benchmarks/ledger_compare.py BEFORE.json AFTER.json [--factor 10]

Exit status 1 if a record or a verdict differs, or if a residual moved by more than ``--factor``
either way (a residual that is 0 on one side and not on the other counts as moved unless both
are below 1e-6 x its threshold: round-off at the floor, listed separately).
"""
from __future__ import annotations

import argparse
import json
import sys

KEY = ("claim", "method", "scene", "point")
VERDICT = ("status", "expected", "wellposed")


def compare(before, after, factor=10.0):
    """dict: n, key_diffs, verdict_diffs, max_ratio (over residuals nonzero on both sides),
    moved (> factor), floor (0 <-> tiny), and the worst records."""
    out = {"n": len(before), "key_diffs": [], "verdict_diffs": [], "moved": [], "floor": [], "ratios": [],
           "note_diffs": 0}
    if len(before) != len(after):
        out["key_diffs"].append(f"{len(before)} records before, {len(after)} after")
    for i, (a, b) in enumerate(zip(before, after)):
        ka, kb = tuple(a[k] for k in KEY), tuple(b[k] for k in KEY)
        if ka != kb:
            out["key_diffs"].append(f"#{i}: {ka} -> {kb}")
            continue
        out["note_diffs"] += a["note"] != b["note"]
        if any(a[k] != b[k] for k in VERDICT):
            out["verdict_diffs"].append(f"#{i} {ka}: {[a[k] for k in VERDICT]} -> {[b[k] for k in VERDICT]}")
        ra, rb = a["residual"], b["residual"]
        if ra is None or rb is None:
            if (ra is None) != (rb is None):
                out["verdict_diffs"].append(f"#{i} {ka}: residual {ra} -> {rb}")
            continue
        ra, rb = abs(ra), abs(rb)
        if ra == rb:
            out["ratios"].append((1.0, i, ka, ra, rb))
        elif ra > 0 and rb > 0:
            r = max(ra / rb, rb / ra)
            out["ratios"].append((r, i, ka, ra, rb))
            if r > factor:
                out["moved"].append((r, i, ka, ra, rb))
        else:
            tol = a.get("threshold") or 0.0
            item = (float("inf"), i, ka, ra, rb)
            (out["floor"] if max(ra, rb) <= 1e-6 * tol else out["moved"]).append(item)
    out["max_ratio"] = max((r[0] for r in out["ratios"]), default=1.0)
    out["ratios"].sort(reverse=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--factor", type=float, default=10.0)
    ap.add_argument("--show", type=int, default=8, help="list this many of the largest ratios")
    a = ap.parse_args(argv)
    with open(a.before) as f:
        before = json.load(f)
    with open(a.after) as f:
        after = json.load(f)
    c = compare(before, after, a.factor)
    print(f"{c['n']} records; record/order differences: {len(c['key_diffs'])}; verdict differences: "
          f"{len(c['verdict_diffs'])}; max residual ratio (nonzero both sides) {c['max_ratio']:.3g}; "
          f"moved > {a.factor:g}x: {len(c['moved'])}; 0 <-> round-off below 1e-6 x threshold: {len(c['floor'])}; "
          f"notes that differ: {c['note_diffs']}")
    for line in c["key_diffs"][:20] + c["verdict_diffs"][:20]:
        print("  ", line)
    for title, rows in (("moved", c["moved"]), ("floor", c["floor"]), ("largest ratios", c["ratios"][:a.show])):
        if rows:
            print(f"{title}:")
            for r, i, k, ra, rb in rows:
                print(f"   #{i} {'/'.join(map(str, k))}: {ra:.2e} -> {rb:.2e} (x{r:.3g})")
    return 1 if c["key_diffs"] or c["verdict_diffs"] or c["moved"] else 0


if __name__ == "__main__":
    sys.exit(main())
