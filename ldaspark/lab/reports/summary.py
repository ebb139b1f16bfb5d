"""The numbers and verdict words README.md quotes, computed from the committed reports' JSON.

README's findings and speed tables mark every quoted value as ``<!--KEY-->text<!--/-->`` (the
comment is invisible when rendered); ``tests/project/test_readme.py`` checks that ``text`` equals
``readme_values(reports)[KEY]``, so README and reports cannot disagree. ``python -m
ldaspark.lab.reports.summary`` prints every key with its current text; ``--fill README.md`` rewrites
the marked values after the reports were regenerated.

What a mark is checked against depends on its kind (``quote_kind``), so that running the main job
and then the tests passes on any machine:

* exact (verdicts, counts, lists, errors of deterministic runs): equal to the reports' value;
* residual (``claims.*.max``, ``claims.*.negctl_min``: largest identity residuals, some of them
  float64 round-off whose last digits depend on the machine's libm and BLAS): the same order of
  magnitude as the reports' value (within a factor 10; a fault moves them by many decades);
* timing (CPU and wall times and their ratios, and the round-off-driven Fig. 4 exponents,
  ``ROUNDOFF_DRIVEN``): equal to the snapshot in the committed
  ``reports/report_timing.json`` ("readme": the timing values of the run README was filled from,
  and the sha256 of each report file then), and equal to the reports' value too while a report
  file is the one of the snapshot (same sha256). ``--fill`` writes README's marks and the snapshot;
  the main job keeps the snapshot when it rewrites report_timing.json.
"""
from __future__ import annotations

import math
import os
import re
import sys

from ..theory.orders import verdict
from .files import load_json, sha256

IRK = ("gauss-irk-1", "gauss-irk-2")


def _load(d, name):
    path = os.path.join(d, name)
    return load_json(path)


def _e(x):
    return f"{x:.1e}"


def _x(x):
    return f"{x:.0f}x"


def _list(xs):
    return ", ".join(xs) if xs else "none"


def convergence_values(recs):
    out = {}
    spark = [r for r in recs if r["claimed_order"] is not None and r["claim_scope"] == "variable"]
    n_ok = sum(verdict(r, recs) == "holds" for r in spark)
    out["convergence.spark"] = f"{n_ok} of {len(spark)}"
    out["convergence.spark.verdict"] = "hold" if n_ok == len(spark) else "do not all hold"
    for m in IRK:
        rs = [r for r in recs if r["method"] == m and r["variable"] == "q"]
        groups = {}
        for r in rs:
            groups.setdefault(verdict(r, recs), []).append(r["scene"])
        s = m.rsplit("-", 1)[1]
        parts = [f"holds on {_list(groups.get('holds', []))}"]
        for v, label in (("HIGHER than claimed", "higher than claimed on"), ("FAILS", "fails on"),
                         ("NO WINDOW", "no asymptotic window on")):
            if groups.get(v):
                parts.append(f"{label} {_list(groups[v])}")
        out[f"convergence.{m}"] = f"s = {s}: " + "; ".join(parts)
    return out


def claims_values(recs):
    out = {}
    ex = [r for r in recs if r["claim"] in ("22a", "22b", "23")]
    out["claims.conditions"] = f"{sum(r['status'] == r['expected'] for r in ex)} of {len(ex)}"
    t1 = [r for r in recs if r["claim"].startswith("theorem1") and r["residual"] is not None]
    ok = [r["residual"] for r in t1 if r["expected"] == "pass" and r["status"] == "pass"]
    neg = [r["residual"] for r in t1 if r["method"].startswith("negctl") and r["expected"] == "fail"]
    if ok:
        out["claims.theorem1.max"] = _e(max(ok))
    if neg:
        out["claims.theorem1.negctl_min"] = _e(min(neg))
    un = [r for r in t1 if r["expected"] == "pass" and r["status"] != "pass"]
    out["claims.theorem1.unexpected"] = str(len(un))
    sym = [r["residual"] for r in recs if r["claim"].startswith("symmetry") and r["expected"] == "pass"
           and r["status"] == "pass" and r["residual"] is not None]
    if sym:
        out["claims.symmetry.max"] = _e(max(sym))
    sing = list(dict.fromkeys(f"{r['method']} on {r['scene']}" for r in recs if r["claim"] == "implicit-function"
                              and r["wellposed"] == "singular" and not r["method"].startswith("negctl")))
    out["claims.singular"] = _list(sing)
    out["claims.singular.count"] = str(len(sing))
    for key, names in CLAIM_GROUP_KEYS.items():
        rs = [r for r in recs if names(r["claim"])]
        if not rs:
            continue
        decided = [r for r in rs if r["status"] != "not-applicable"]
        out[key] = f"{sum(r['status'] == r['expected'] for r in decided)} of {len(decided)}"
        res = [r["residual"] for r in decided if r["expected"] == "pass" and r["status"] == "pass"
               and r["residual"] is not None and r["claim"] not in ORDER_CLAIMS]
        if res:
            out[key + ".max"] = _e(max(res))
    return out


# claim groups of ldaspark.lab.claims.claims_general / claims_paper quoted in README: records whose
# outcome is what the paper predicts, and the largest residual of the passing identities
ORDER_CLAIMS = ("order-general-scenes", "variational-order", "nonideal-3.3", "energy-balance-2.2")
CLAIM_GROUP_KEYS = {
    "claims.general": lambda c: c.endswith("-general") or "-general-" in c or c == "order-general-scenes",
    "claims.paper": lambda c: c in ("15a", "15b", "16", "18", "17-integral", "19-integral", "20-integral",
                                    "antisymmetry-exact", "5.1-exact", "euler-i-reduction",
                                    "euler-ii-reduction", "midpoint-7.3", "linearly-implicit-7"),
    "claims.energy-balance": lambda c: c == "energy-balance-2.2",
    "claims.nonideal": lambda c: c == "nonideal-3.3",
}


def energy_values(d):
    out = {}
    recs = [r for f in d["figures"] for r in f["methods"].values()]
    ratios = [r["last_over_first_quarter"] for r in recs]
    out["energy.figs13.ratio"] = f"{min(ratios):.2f}-{max(ratios):.2f}"
    nb = sum(r["bounded"] for r in recs)
    out["energy.figs13.bounded"] = f"{nb} of {len(recs)}"
    for key, label in (("figure4", "printed"), ("figure4_nonholonomic", "nh")):
        f4 = d.get(key)
        if not f4:
            continue
        ex = [f4["fit"][m]["exponent"] for m in f4["methods"]]
        out[f"energy.fig4.{label}.exponents"] = ", ".join(f"{x:.3f}" for x in ex)     # as energy.md prints them
        n1 = sum(abs(x - 1) <= 0.3 for x in ex)
        out[f"energy.fig4.{label}.near1"] = f"{n1} of {len(ex)}"
        out[f"energy.fig4.{label}.verdict"] = ("reproduced" if n1 == len(ex) else
                                              "not reproduced" if n1 == 0 else "partly reproduced")
        out[f"energy.fig4.{label}.seconds"] = f"{f4['seconds']:.1f} s"
    return out


def work_precision_values(d):
    out = {}
    sm = d.get("steps_per_second_summary")
    if sm:
        out["wp.sps.median"] = _x(sm["median"])
        out["wp.sps.range"] = f"{_x(sm['min'])} to {_x(sm['max'])}"
    for st in d["studies"]:
        rs = st["ratios"]["error"]
        out[f"wp.{st['scene']}.ratios"] = " / ".join("-" if r["scipy/spark-fast"] is None else _x(r["scipy/spark-fast"])
                                                      for r in rs)
        out[f"wp.{st['scene']}.targets"] = " / ".join(f"{r['target']:.0e}" for r in rs)
        if any("peer/spark-fast" in r for r in rs):
            # a run without the strongest peers (CyRK, SUNDIALS: the bench extra) compared SPARK with
            # weaker ones (particle 5.5x where CyRK gives 0.057x): README names CyRK there, so
            # those ratios are not quoted
            out[f"wp.{st['scene']}.peer_ratios"] = (
                " / ".join(_r(r.get("peer/spark-fast")) for r in rs) if not d.get("peers_skipped") else
                "not measured (the run that wrote the report had no " + "; ".join(
                    n.split(" skipped")[0] for n in d["peers_skipped"]) + ": pip install -e \".[bench]\")")
    le = d.get("long", {})
    if "spark" in le:
        out["wp.long.spark"] = _e(le["spark"]["max_second_half"])
        dp = le["dop853"]
        out["wp.long.dop853"] = f"{_e(dp['max_first_half'])} -> {_e(dp['max_second_half'])}"
    base = [r for r in d["dps"] if r["precision"] == "float64 generic"]
    mp = [r for r in d["dps"] if "dps" in r]
    if base and mp:
        out["wp.dps.ratios"] = " / ".join(f"{r['seconds_per_step'] / base[0]['seconds_per_step']:.1f}x" for r in mp)
        out["wp.dps.digits"] = " / ".join(str(r["dps"]) for r in mp)
    for st in d.get("studies", []):
        c = st.get("rhs_seconds_per_call")
        if c:
            out[f"wp.{st['scene']}.rhs"] = f"{c['compiled'] * 1e6:.1f} us vs {c['python'] * 1e6:.0f} us"
    return out


def peer_values(d):
    """odelab vs this library on odelab's robot (``reports/peer_odelab.json``, from
    ``benchmarks/peer_odelab.py``): the first matched Spark2 run."""
    r = next(x for x in d["runs"] if x["matched"] and x["odelab"] == "Spark2")
    ok = [x for x in d["runs"] if x["matched"]]
    return {"peer.spark2": f"{r['odelab_cpu']:.1f} s / {r['generic_cpu']:.1f} s / {r['compiled_cpu'] * 1e3:.1f} ms",
            "peer.ratios": f"{r['odelab_cpu'] / r['generic_cpu']:.1f}x / {r['odelab_cpu'] / r['compiled_cpu']:.0f}x",
            "peer.agree": _e(max(x["tight_max_dq"] for x in ok if x.get("tight_max_dq") is not None)),
            "peer.control": _e(min(x["max_dq"] for x in d["runs"] if not x["matched"]))}


def run_values(d):
    """The main job's own time (``report_timing.json``, written by ``ldaspark report``); with the
    probe (``timing.probe_cpu``) its CPU time in probe units, a figure that does not depend on the
    machine's speed."""
    out = {"run.wall": f"{d['wall']:.0f} s", "run.cpu": f"{d['cpu']:.0f} s",
           "run.cores": str(d["cpu_count"])}
    if d.get("probe"):
        out["run.probe_ratio"] = f"{d['cpu'] / d['probe']['cpu']:.0f}"
    return out


def test_run_values(d):
    """The latest CI run and newcomer run (``reports/test_runs.json``, from
    ``benchmarks/test_runs.py``): counts, seconds, commit and date, as README quotes them."""
    out = {}
    for kind in ("ci", "newcomer"):
        runs = [r for r in d["runs"] if r["kind"] == kind]
        if not runs:
            continue
        r = runs[-1]
        k = f"tests.{kind}"
        out.update({f"{k}.passed": str(r["passed"]), f"{k}.skipped": str(r["skipped"]),
                    f"{k}.test_seconds": f"{r['test_seconds']:.0f} s", f"{k}.commit": r["commit"][:8],
                    f"{k}.date": r["date"][:10], f"{k}.load": f"{r['load_start']:.1f}"})
        if kind == "ci":
            out[f"{k}.wall"] = f"{r['wall_seconds'] / 60:.1f} min"
            out[f"{k}.rc"] = str(r["rc"])
            # .ci/run stops at failing tests, before the quick mutation set: none run then
            out[f"{k}.mutants"] = (f"{r['mutants_killed']} of {r['mutants']}" if "mutants" in r
                                   else "none run (the tests failed first), so no")
        else:
            out[f"{k}.rc"] = f"{r['rc_first']} and {r['rc_second']}"
            out[f"{k}.first"] = f"{r['first_seconds']:.0f} s"
            out[f"{k}.second"] = f"{r['second_seconds']:.0f} s"
            if "main_job_wall" in r:
                out[f"{k}.main_job"] = f"{r['main_job_wall']:.0f} s wall, {r['main_job_cpu']:.0f} s CPU"
    return out


def _r(x, at_least=None, at_most=None):
    """A speed-up as README quotes it: two significant digits ('0.45x', '1.1x', '14x'); '>= 4.9x'
    for a lower bound, '<= 4.9x' for an upper one (``peers.speedups``)."""
    if x is None and at_least is not None:
        return ">= " + _r(at_least)
    if x is None and at_most is not None:
        return "<= " + _r(at_most)
    return "-" if x is None else f"{float(f'{x:.2g}'):g}x"


def peers_values(d):
    """The best compiled SPARK method against the best peer (``reports/peers.json``, from
    ``benchmarks/peers.py``): speed-ups at the final-error targets (T = 100) and at the energy
    targets of the long runs (T = 1e4), per scene."""
    out = {"peers.targets": " / ".join(f"{t:.0e}" for t in d["targets"]),
           "peers.energy_targets": " / ".join(f"{t:.0e}" for t in d["energy_targets"])}
    for st in d["studies"]:
        out[f"peers.{st['scene']}.speedups"] = " / ".join(_r(r["speedup"], r.get("speedup_at_least"), r.get("speedup_at_most"))
                                                         for r in st["speedups"])
        out[f"peers.{st['scene']}.long"] = " / ".join(_r(r["speedup"], r.get("speedup_at_least"), r.get("speedup_at_most"))
                                                     for r in st["long_speedups"])
        # the same against SPARK's internal fast path, the strongest peer's name, and T = 1e5
        for key, part in (("speedups_fast", "speedups_fast"), ("long_fast", "long_speedups_fast"),
                          ("vlong", "vlong_speedups"), ("vlong_fast", "vlong_speedups_fast")):
            if st.get(part):
                out[f"peers.{st['scene']}.{key}"] = " / ".join(
                    _r(r["speedup"], r.get("speedup_at_least"), r.get("speedup_at_most")) for r in st[part])
        for key, part in (("best_peer", "speedups"), ("long_best_peer", "long_speedups")):
            names = list(dict.fromkeys(r["peer"] for r in st[part] if r["peer"]))
            out[f"peers.{st['scene']}.{key}"] = ", ".join(names) or "-"
        if st.get("t_vlong"):
            out[f"peers.{st['scene']}.t_vlong"] = f"{st['t_vlong']:.0e}"
        # the floors of the long runs: the smallest energy error each side reaches, and the largest
        # constraint error |k| of the runs at that floor ("SPARK / best of the peers")
        for key, part in (("long_floor", "long_rows"), ("vlong_floor", "vlong_rows")):
            rows = st.get(part) or []
            sides = [[r for r in rows if r["kind"] == "spark"], [r for r in rows if r["kind"] == "peer"]]
            if all(sides):
                best = [min(x, key=lambda r: r["energy_error"]) for x in sides]
                out[f"peers.{st['scene']}.{key}"] = " / ".join(f"{r['energy_error']:.1e}" for r in best)
                out[f"peers.{st['scene']}.{key}_k"] = " / ".join(f"{r['constraint']:.0e}" for r in best)
    for k in ("load_average_1min_at_start", "load_average_1min_at_end"):
        if d.get(k) is not None:
            out[f"peers.{k.replace('load_average_1min_', 'load_')}"] = f"{d[k]:g}"
    return out


def scaling_values(d):
    """The compiled step's cost against n (``reports/scaling.json``, from ``benchmarks/scaling.py``):
    per size of the first method, CPU per step with the solver auto picks and with the dense LU,
    and the first call's CPU."""
    out = {}
    ok = [r for r in d["rows"] if r.get("status") == "ok"]
    for r in ok:
        if r["method"] != ok[0]["method"]:
            continue
        dense = f" (dense LU {_us(r['us_per_step_dense'])})" if r.get("us_per_step_dense") else ""
        out[f"scaling.step.{r['n']}"] = f"{_us(r['us_per_step'])}{dense}"
        out[f"scaling.first_call.{r['n']}"] = f"{r['first_call_cpu']:.2g} s"
    return out


def quasi_step_values(d):
    """The quasi-Newton step against the kernels' Newton and against the best compiled peer
    (``reports/quasi_step.json``, from ``benchmarks/quasi_step.py``): the range of the per-step
    speed-ups, and per study and target cpu(best peer) / cpu(best SPARK) with the quasi root
    finder (``qs.<scene>.<key>.<target>``), the same with the generic kernel (``...generic``; the
    plain keys run the kernel specialised per (s, n, m)), with the kernels' Newton (``...newton``)
    and, when the study ran with ``--tol-kappa K``, with ``Newton(tol = K * target)`` (``...tol``)."""
    sp = [r["speedup"] for r in d.get("per_step", [])]
    out = {"qs.per_step.range": f"{min(sp):.3g}-{max(sp):.2g}x"} if sp else {}
    # the kernel specialised per (s, n, m) against the generic one (rows with a specialised kernel)
    ss = [r["specialised_speedup"] for r in d.get("per_step", []) if r.get("specialised")]
    if ss:
        out["qs.specialised.range"] = f"{min(ss):.3g}-{max(ss):.2g}x"
    gs = [r["generic_speedup"] for r in d.get("per_step", []) if "generic_speedup" in r]
    if gs:
        out["qs.per_step.generic.range"] = f"{min(gs):.3g}-{max(gs):.2g}x"
    for st in d.get("studies", []):
        for side, suffix in (("quasi", ""), ("quasi_generic", ".generic"), ("newton", ".newton"),
                             ("quasi_tol", ".tol")):
            for r in st.get(side, []):
                key = f"qs.{st['scene']}.{st['key']}.{r['target']:.0e}{suffix}"
                if r.get("speedup") is not None:
                    out[key] = f"{r['speedup']:.2f}x"
                elif r.get("speedup_at_least") is not None:
                    out[key] = f">= {r['speedup_at_least']:.2f}x"
                elif r.get("speedup_at_most") is not None:
                    out[key] = f"<= {r['speedup_at_most']:.2f}x"
                else:
                    out[key] = "-"
    if "load_average_1min_at_start" in d:
        out["qs.load"] = f"{d['load_average_1min_at_start']:.1f}-{d['load_average_1min_at_end']:.1f}"
    return out


def mutgen_values(d):
    """The generated mutants' report (``mutation-generated.json``): counts over every listed
    module, and the lowest per-module score among the modules with mutants run."""
    mods = d.get("modules", {})
    tot = lambda k: sum(c.get(k, 0) for c in mods.values())  # noqa: E731
    scores = [(c["score"], f) for f, c in mods.items() if c.get("score") is not None]
    run = tot("killed") + tot("survived") + tot("timeout")
    out = {"mutgen.modules": str(len(mods)), "mutgen.generated": str(tot("generated")), "mutgen.run": str(run),
           "mutgen.killed": str(tot("killed")), "mutgen.equivalent": str(tot("equivalent")),
           "mutgen.surviving": str(tot("survived") + tot("timeout")), "mutgen.not_covered": str(tot("not-covered"))}
    if scores:
        low = min(scores)
        where = "every module" if all(sc == low[0] for sc, _ in scores) else low[1]
        out["mutgen.min_score"] = f"{100 * low[0]:.1f}% ({where})"
    return out


def coverage_values(d):
    """The default suite's coverage of the checking code (``coverage-checking.json``): the
    lowest branch coverage among the modules and how many are at 90% or more."""
    rows = [(c["branches"][0] / c["branches"][1], f) for f, c in d.get("modules", {}).items()
            if c.get("branches") and c["branches"][1]]
    if not rows:
        return {}
    low = min(rows)
    return {"coverage.modules": str(len(d["modules"])),
            "coverage.at90": f"{sum(r >= 0.9 for r, _ in rows)} of {len(rows)}",
            "coverage.min_branches": f"{100 * low[0]:.0f}% ({low[1]})"}


def _us(x):
    """Microseconds as README quotes them: '51 us', '1.2 ms', '0.13 s' (two significant digits)."""
    return f"{float(f'{x:.2g}'):g} us" if x < 1e3 else (f"{float(f'{x / 1e3:.2g}'):g} ms" if x < 1e6
                                                      else f"{float(f'{x / 1e6:.2g}'):g} s")


def readme_values(reports_dir="reports") -> dict:
    """{key: text} for every value README quotes (keys of absent reports are missing)."""
    from ...core.errors import InputError
    out = {}
    for name, fn in (("convergence.json", convergence_values), ("claims.json", claims_values),
                     ("energy.json", energy_values), ("work_precision.json", work_precision_values),
                     ("report_timing.json", run_values), ("peer_odelab.json", peer_values),
                     ("peers.json", peers_values), ("scaling.json", scaling_values),
                     ("quasi_step.json", quasi_step_values),
                     ("mutation-generated.json", mutgen_values), ("coverage-checking.json", coverage_values),
                     ("test_runs.json", test_run_values)):
        path = os.path.join(reports_dir, name)
        try:
            d = _load(reports_dir, name)
            if d is not None:
                out.update(fn(d))
        except (ValueError, KeyError, TypeError, AttributeError, IndexError) as exc:
            # a malformed file or one of another layout (not the main job's): one line naming it,
            # not a traceback from deep inside the value functions
            raise InputError(f"report file {path} is not a report of the layout summary reads "
                             f"({type(exc).__name__}: {str(exc)[:120]})") from None
    return out


MARK = re.compile(r"<!--([\w.:+\-]+)-->(.*?)<!--/-->")

# --- what a mark is checked against -----------------------------------------------------------
TIMING = re.compile(r"^(run\.(wall|cpu|probe_ratio)|energy\.fig4\.\w+\.seconds|wp\.sps\.\w+"
                    r"|wp\.[\w-]+\.(ratios|peer_ratios|rhs)|peer\.(spark2|ratios)"
                    r"|peers\.[\w-]+\.(speedups|long|speedups_fast|long_fast|vlong|vlong_fast|best_peer|long_best_peer)"
                    r"|peers\.load_(at_start|at_end)|scaling\.(step|first_call)\.\d+|qs\.[\w.+-]+)$")
#: values that float64 round-off decides, checked as timings are (against the snapshot): the
#: Fig. 4 drift exponents fit mu((E - E0)^2) over 1e6 steps, where the energy error is a random
#: walk of round-off; a fresh main job on the same machine after a change of the generated
#: model code's operation order moved the nonholonomic ones from 1.31 / 1.15 / 0.39 to
#: 0.64 / 1.07 / 0.72 (and the count near 1 from 1 to 2). The printed scene's verdict stays exact:
#: its exponents are ~0.01 whatever the round-off, far from 1.
ROUNDOFF_DRIVEN = re.compile(r"^energy\.fig4\.(printed\.exponents|nh\.(exponents|near1|verdict))$")
RESIDUAL = re.compile(r"^claims\.[\w.-]+\.(max|negctl_min)$")
#: the report file each key's value comes from (its first dotted part)
SOURCE = {"convergence": "convergence.json", "claims": "claims.json", "energy": "energy.json",
          "wp": "work_precision.json", "run": "report_timing.json", "peer": "peer_odelab.json",
          "peers": "peers.json", "scaling": "scaling.json", "mutgen": "mutation-generated.json",
          "coverage": "coverage-checking.json", "qs": "quasi_step.json", "tests": "test_runs.json"}


def quote_kind(key: str) -> str:
    """"timing", "residual" or "exact" (see the module docstring)."""
    return "timing" if TIMING.match(key) or ROUNDOFF_DRIVEN.match(key) else \
        "residual" if RESIDUAL.match(key) else "exact"


def same_magnitude(a: str, b: str) -> bool:
    """Two residuals printed as numbers ('6.3e-17', '9.9e-17') within a factor 10 of each other:
    float64 round-off differs between machines by a few units in the last place times the
    problem's amplification (1.6x here), a wrong formula by many decades."""
    try:
        x, y = float(a), float(b)
    except ValueError:
        return a == b
    if x == 0 or y == 0 or not (math.isfinite(x) and math.isfinite(y)):
        return x == y
    return abs(math.log10(abs(x) / abs(y))) <= 1.0


def _sha(path):
    return sha256(path)


def file_digests(reports_dir) -> dict:
    """{report file: sha256} of the report files present (report_timing.json excluded: its
    snapshot block changes when it is filled)."""
    return {name: _sha(os.path.join(reports_dir, name)) for name in sorted(set(SOURCE.values()))
            if name != "report_timing.json" and os.path.exists(os.path.join(reports_dir, name))}


def _run_id(d):
    return None if d is None else {k: d.get(k) for k in ("date", "wall", "cpu")}


def snapshot(reports_dir, values=None) -> dict:
    """The "readme" block of report_timing.json: the timing values README quotes now, and what
    identifies the reports they come from (report files' sha256, the main job's run)."""
    values = readme_values(reports_dir) if values is None else values
    return {"values": {k: v for k, v in values.items() if quote_kind(k) == "timing"},
            "files": file_digests(reports_dir), "run": _run_id(_load(reports_dir, "report_timing.json"))}


def _current(key, reports_dir, snap):
    """Whether the report file of ``key`` is the one the snapshot was taken from."""
    name = SOURCE.get(key.split(".", 1)[0])
    if name == "report_timing.json":
        return _run_id(_load(reports_dir, name)) == snap.get("run")
    path = os.path.join(reports_dir, name) if name else None
    return bool(path) and os.path.exists(path) and snap.get("files", {}).get(name) == _sha(path)


def quote_problem(key, shown, values, reports_dir=None, snap=None):
    """None if README's ``shown`` text for ``key`` agrees with the reports (by the key's kind),
    else what is wrong."""
    kind = quote_kind(key)
    if kind == "timing":
        if snap is None:
            snap = (_load(reports_dir, "report_timing.json") or {}).get("readme") if reports_dir else None
        if not snap or key not in snap.get("values", {}):
            return f"{key}: a timing with no snapshot in report_timing.json (run --fill)"
        if shown != snap["values"][key]:
            return f"{key} shows {shown!r}, the committed snapshot gives {snap['values'][key]!r}"
        if reports_dir is not None and _current(key, reports_dir, snap) and values.get(key) != shown:
            return f"{key} shows {shown!r}, the reports (those of the snapshot) give {values.get(key)!r}"
        return None
    if key not in values:
        return f"unknown key {key}"
    if kind == "residual":
        return None if same_magnitude(shown, values[key]) else \
            f"{key} shows {shown!r}, the reports give {values[key]!r} (another order of magnitude)"
    return None if shown == values[key] else f"{key} shows {shown!r}, the reports give {values[key]!r}"


def write_snapshot(reports_dir, values=None):
    """Store ``snapshot`` as the "readme" block of ``reports_dir``/report_timing.json."""
    path = os.path.join(reports_dir, "report_timing.json")
    d = _load(reports_dir, "report_timing.json")
    if d is None:
        return
    d["readme"] = snapshot(reports_dir, values)
    from ...core.io import atomic_write_json
    atomic_write_json(path, d)


def fill(text, values):
    """``text`` with every marked value replaced by the reports' current one (unknown keys kept)."""
    return MARK.sub(lambda m: f"<!--{m.group(1)}-->{values.get(m.group(1), m.group(2))}<!--/-->", text)


#: the largest file ``--fill`` reads (README.md is ~45 kB; /dev/zero or a runaway file is refused)
FILL_MAX_BYTES = 2 ** 24


def main(argv=None):
    """``python -m ldaspark.lab.reports.summary [--reports DIR] [--fill FILE]``: list every key with its
    current text, or rewrite the marked values of FILE (README.md) from the reports. A bad input
    (no such directory, FILE not a regular UTF-8 text file of at most 16 MiB, a malformed report)
    is one line on stderr and exit 2, as for ``ldaspark``'s commands."""
    import argparse

    from ...core.errors import InputError, LdasparkError
    from ...core.validate import read_regular
    ap = argparse.ArgumentParser(prog="python -m ldaspark.lab.reports.summary", description=main.__doc__)
    ap.add_argument("--reports", default="reports")
    ap.add_argument("--fill", default=None, help="rewrite the <!--KEY-->value<!--/--> marks of this file")
    args = ap.parse_args(argv)
    try:
        if not os.path.isdir(args.reports):     # else every key is silently absent: nothing listed or filled
            raise InputError(f"--reports {args.reports} is not a directory")
        if args.fill is not None:
            from ...core.io import check_destination
            # read bounded, through the checked opener: a FIFO or /dev/zero is refused, never read
            raw = read_regular(args.fill, FILL_MAX_BYTES, "--fill file")
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError:
                raise InputError(f"--fill file {args.fill} is not UTF-8 text") from None
            check_destination(args.fill)
        values = readme_values(args.reports)
        if args.fill is not None:
            new = fill(text, values)
            if new != text:
                from ...core.io import atomic_write_text
                atomic_write_text(args.fill, new)
            write_snapshot(args.reports, values)
            print(f"{args.fill}: {'updated' if new != text else 'already current'}; timing snapshot in "
                  f"{os.path.join(args.reports, 'report_timing.json')}")
            return 0
    except LdasparkError as exc:
        print(f"summary: error: {exc}", file=sys.stderr)
        return 2
    from ...core.errors import one_line
    for k, v in values.items():     # scene and method names come from the files: no raw controls
        print(one_line(f"<!--{k}-->{v}<!--/-->"))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
