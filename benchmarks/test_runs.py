"""Record the test runs README quotes: the CI run (``bash .ci/run`` on a fresh clone with empty
kernel caches) and the newcomer's two commands (README's main job, then its test command, in a
fresh clone and venv), with their counts and times, in ``reports/test_runs.json`` and
``reports/test_runs.md``. README's numbers about test runs are read from that file
(``ldaspark.lab.reports.summary.test_run_values``), so that each is the record of a run.

    python benchmarks/test_runs.py --ci [--repo .] [--out reports]
    python benchmarks/test_runs.py --newcomer [--repo .] [--out reports]

Each run is of the repository's HEAD commit (recorded with the run). The machine's load
average at the start and the end is recorded: the shared host's speed varies 1.5-2.5x with it.
A run appends one record; the latest record of each kind is what README quotes (the file keeps
the last ``KEEP`` records).
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

KEEP = 20
#: pytest -q's last line: "4553 passed, 733 skipped, 5 warnings in 249.12s (0:04:09)", or with
#: failures first: "2 failed, 4551 passed, 733 skipped, 1 error in 250.31s"
PYTEST_LINE = re.compile(r"^(?:=+ )?(?P<body>\d+ (?:failed|passed|skipped|errors?)\b.*?) in (?P<sec>[0-9.]+)s")
#: the quick mutation set's verdict line in mutation.md / its output: "**17 of 17 mutants killed**"
MUTANTS_LINE = re.compile(r"(\d+) of (\d+) mutants killed")
README_TESTS = 'python -m pytest -q -n 2 --dist loadfile'
README_MAIN = 'pip install -e ".[test]" && ldaspark report'


def pytest_summary(text: str) -> dict:
    """Counts and seconds of the last pytest summary line in ``text`` (passed, skipped, failed,
    errors; 0 when absent); {} when there is none."""
    found = None
    for line in text.splitlines():
        m = PYTEST_LINE.match(line.strip())
        if m:
            found = m
    if found is None:
        return {}
    counts = {k: 0 for k in ("passed", "skipped", "failed", "errors")}
    for n, word in re.findall(r"(\d+) (passed|skipped|failed|errors?)", found.group("body")):
        counts["errors" if word.startswith("error") else word] = int(n)
    counts["test_seconds"] = float(found.group("sec"))
    return counts


def _clone(repo: str, dest: str) -> str:
    subprocess.run(["git", "clone", "-q", repo, dest], check=True)
    return subprocess.run(["git", "-C", dest, "rev-parse", "HEAD"], check=True, capture_output=True,
                          text=True).stdout.strip()


def _fresh_env(tmp: str) -> dict:
    env = dict(os.environ)
    for k in ("VIRTUAL_ENV", "PYTHONPATH"):
        env.pop(k, None)
    env["LDASPARK_CACHE_DIR"] = os.path.join(tmp, "ldaspark-cache")
    env["NUMBA_CACHE_DIR"] = os.path.join(tmp, "numba-cache")
    return env


def _run(cmd: str, cwd: str, env: dict, log: str) -> tuple:
    t0 = time.monotonic()
    with open(log, "w") as fh:
        rc = subprocess.run(["bash", "-c", cmd], cwd=cwd, env=env, stdout=fh, stderr=subprocess.STDOUT).returncode
    wall = time.monotonic() - t0
    with open(log, errors="replace") as fh:
        return rc, wall, fh.read()


def run_ci(repo: str, keep_logs: str | None) -> dict:
    tmp = tempfile.mkdtemp(prefix="ldaspark-ci-")
    try:
        commit = _clone(repo, os.path.join(tmp, "clone"))
        rc, wall, out = _run("bash .ci/run", os.path.join(tmp, "clone"), _fresh_env(tmp), os.path.join(tmp, "ci.log"))
        rec = {"kind": "ci", "command": "bash .ci/run (fresh clone, empty kernel caches)", "commit": commit,
               "rc": rc, "wall_seconds": round(wall, 1), **pytest_summary(out)}
        m = MUTANTS_LINE.findall(out)
        if m:
            rec["mutants_killed"], rec["mutants"] = int(m[-1][0]), int(m[-1][1])
        if keep_logs:
            shutil.copy(os.path.join(tmp, "ci.log"), keep_logs)
        return rec
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def run_newcomer(repo: str, keep_logs: str | None) -> dict:
    tmp = tempfile.mkdtemp(prefix="ldaspark-newcomer-")
    try:
        clone = os.path.join(tmp, "clone")
        commit = _clone(repo, clone)
        env = _fresh_env(tmp)
        venv = "python3 -m venv .venv && . .venv/bin/activate && "
        rc1, wall1, out1 = _run(venv + README_MAIN, clone, env, os.path.join(tmp, "first.log"))
        rc2, wall2, out2 = _run(". .venv/bin/activate && " + README_TESTS, clone, env, os.path.join(tmp, "second.log"))
        rec = {"kind": "newcomer", "command": "README's two commands in order (fresh clone and venv, empty caches)",
               "commit": commit, "rc_first": rc1, "first_seconds": round(wall1, 1), "rc_second": rc2,
               "second_seconds": round(wall2, 1), **pytest_summary(out2)}
        try:
            with open(os.path.join(clone, "reports", "report_timing.json")) as fh:
                t = json.load(fh)
            rec["main_job_wall"], rec["main_job_cpu"] = round(t["wall"], 1), round(t["cpu"], 1)
        except (OSError, ValueError, KeyError):
            pass
        if keep_logs:
            for name in ("first.log", "second.log"):
                shutil.copy(os.path.join(tmp, name), f"{keep_logs}.{name}")
        return rec
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def render(runs: list) -> str:
    lines = ["# Test runs", "",
             "Written by `python benchmarks/test_runs.py --ci` / `--newcomer`: the CI run (`bash .ci/run` on a "
             "fresh clone with empty kernel caches) and README's two commands in order in a fresh clone and venv, "
             "on the commit named. README's numbers about test runs are the latest record of each kind. Load: "
             "the 1-minute load average at the start and the end (2 cores; the shared host runs 1.5-2.5x slower "
             "when loaded).", "",
             "| date (UTC) | kind | commit | rc | passed | skipped | failed | tests (s) | wall (s) | other | load start/end |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in runs:
        if r["kind"] == "ci":
            rc, wall = str(r["rc"]), f"{r['wall_seconds']:.0f}"
            other = f"mutants {r['mutants_killed']} of {r['mutants']} killed" if "mutants" in r else ""
        else:
            rc, wall = f"{r['rc_first']} / {r['rc_second']}", f"{r['first_seconds']:.0f} + {r['second_seconds']:.0f}"
            other = (f"main job {r['main_job_wall']:.0f} s wall, {r['main_job_cpu']:.0f} s CPU"
                     if "main_job_wall" in r else "")
        lines.append(f"| {r['date']} | {r['kind']} | {r['commit'][:8]} | {rc} | {r.get('passed', '-')} | "
                     f"{r.get('skipped', '-')} | {r.get('failed', 0) + r.get('errors', 0)} | "
                     f"{r.get('test_seconds', 0):.0f} | {wall} | {other} | "
                     f"{r['load_start']:.2f} / {r['load_end']:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    kind = ap.add_mutually_exclusive_group(required=True)
    kind.add_argument("--ci", action="store_true")
    kind.add_argument("--newcomer", action="store_true")
    ap.add_argument("--repo", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    ap.add_argument("--out", default=None, help="reports directory (default: the repo's reports/)")
    ap.add_argument("--keep-log", default=None, help="copy the run's output to this path")
    a = ap.parse_args(argv)
    out = a.out or os.path.join(a.repo, "reports")
    load0 = os.getloadavg()[0]
    rec = run_ci(a.repo, a.keep_log) if a.ci else run_newcomer(a.repo, a.keep_log)
    rec["date"] = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")
    rec["load_start"], rec["load_end"], rec["cpu_count"] = load0, os.getloadavg()[0], os.cpu_count()
    path = os.path.join(out, "test_runs.json")
    try:
        with open(path) as fh:
            runs = json.load(fh)["runs"]
    except (OSError, ValueError, KeyError):
        runs = []
    runs = (runs + [rec])[-KEEP:]
    sys.path.insert(0, a.repo)
    from ldaspark.core.io import atomic_write_json, atomic_write_text
    atomic_write_json(path, {"runs": runs})
    atomic_write_text(os.path.join(out, "test_runs.md"), render(runs))
    print(json.dumps(rec, indent=1))
    ok = rec.get("rc", 0) == 0 and rec.get("rc_first", 0) == 0 and rec.get("rc_second", 0) == 0
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
