"""``ldaspark report``: the main job.

``ldaspark report`` with no section writes every section's default report into reports/ (or
``--outdir``); ``ldaspark report SECTION [options]`` runs one section with its own options. Each
section lives in its own module (listed in SECTION_MODULES) exposing

* ``add_arguments(parser)``: options of ``ldaspark report SECTION``;
* ``run(args) -> int``: run with parsed options;
* ``run_default(outdir) -> None``: what the no-argument main job does for this section;
* optionally ``jobs(full)`` and ``write(results, outdir, ...)`` (see ``ldaspark.lab.reports.jobs``):
  the main job then spreads the section's independent pieces over the worker processes
  together with the other sections' pieces.

The main job prints each section's CPU time and the wall time at which it was written; every
report file ends with the numbers of the run that wrote it. Sections whose module is not
installed are skipped (and not offered on the command line).
"""
from __future__ import annotations

import argparse
import importlib
import importlib.util
import os

from .timing import Clock


REPORT_DIR = "reports"

# order = order of the main job
SECTION_MODULES = {
    "convergence": "ldaspark.lab.reports.convergence",
    "energy": "ldaspark.lab.reports.energy",
    "claims": "ldaspark.lab.reports.claims",
    "work-precision": "ldaspark.lab.reports.work_precision",
    "stability": "ldaspark.lab.reports.stability",
    "systems": "ldaspark.lab.reports.systems",
}


def available_sections():
    out = {}
    for name, mod in SECTION_MODULES.items():
        if importlib.util.find_spec(mod) is not None:
            out[name] = mod
    return out


# --- dispatcher -----------------------------------------------------------------------------
class _MainJobOption(argparse.Action):
    """An option of the main job (``ldaspark report --outdir X``). Given before a section's name
    (``ldaspark report --outdir X systems``) argparse let the section's option of the same name,
    or its default, overwrite it in silence (the section wrote to reports/); the value is also
    kept aside in ``main_options``, and ``run`` hands it to the section or refuses it."""

    def __call__(self, parser, namespace, values, option_string=None):
        val = self.const if self.nargs == 0 else values
        setattr(namespace, self.dest, val)
        given = dict(getattr(namespace, "main_options", None) or {})
        given[self.dest] = (option_string, val)
        namespace.main_options = given


def add_arguments(p):
    p.add_argument("--outdir", default=REPORT_DIR, action=_MainJobOption,
                   help="directory of the reports (main job; before a section: that section's --outdir)")
    p.add_argument("--full", nargs=0, const=True, default=False, action=_MainJobOption,
                   help="main job: the exhaustive sweeps of the sections that have them (stability)")
    # --jobs as well: the name ``ldaspark mutants`` uses; without it "report --jobs 2" failed
    # with argparse's "invalid choice: '2'" (the 2 read as a section's name)
    p.add_argument("--workers", "--jobs", type=int, default=None, action=_MainJobOption,
                   help="main job: worker processes (default: the number of cores)")
    from ...executors import add_scheduler_argument
    add_scheduler_argument(p, action=_MainJobOption)
    sub = p.add_subparsers(dest="section", parser_class=type(p))
    for name, mod in available_sections().items():
        sp = sub.add_parser(name, help=f"{name} report")
        module = importlib.import_module(mod)
        module.add_arguments(sp)
        sp.set_defaults(section_run=module.run,
                        section_options={a.dest: a.default for a in sp._actions if a.option_strings})


def _main_options_to_section(args) -> None:
    """The main job's options given before the section's name: the section's own option of that
    name takes the value (unless it was given after the name too, with another value); an option
    the section does not have is refused (it would be ignored)."""
    from ...core.errors import InputError
    own = getattr(args, "section_options", None) or {}
    for dest, (opt, val) in (getattr(args, "main_options", None) or {}).items():
        if dest not in own:
            raise InputError(f"{opt} is an option of the main job (ldaspark report without a section); "
                             f"the {args.section} section does not take it")
        now = getattr(args, dest, None)
        if now != own[dest] and now != val:
            raise InputError(f"{opt} given before and after {args.section} with different values: "
                             f"{val!r} and {now!r}")
        if dest == "outdir" and isinstance(val, str) and not val.strip():
            raise InputError("--outdir is an empty path")
        if dest == "outdir" and val == "-":         # the command line's check saw the section's default
            from ...cli import dash_message
            raise InputError(dash_message(opt))
        setattr(args, dest, val)


def _check_outdir_writable(outdir) -> None:
    """OUTDIR made now and a file created (and removed) in it, as the sections will at the end of
    their runs: ``--outdir /proc/x`` or a read-only directory ran the whole job, then failed."""
    from ...core.errors import InputError
    from ...core.io import check_destination
    try:
        os.makedirs(outdir, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--outdir {outdir}: cannot be created ({exc.strerror or exc})") from None
    check_destination(os.path.join(outdir, "report_timing.json"))


def check_report_files(outdir, names) -> None:
    """OUTDIR/<name> of each of a section's own files (``REPORT_FILES``: its markdown and JSON)
    can be written: a directory or socket of that name was refused at the end of the section's
    runs (``report energy`` with OUTDIR/energy.md a directory computed every figure, wrote them,
    then failed on energy.md)."""
    from ...core.io import check_destination
    for name in names:
        check_destination(os.path.join(outdir, name))


def check_figures_dir(outdir) -> None:
    """OUTDIR/figures can hold a new figure (made now if missing): a regular file of that name
    let every section compute to the end and then fail on its first plot ("cannot write
    OUTDIR/figures/convergence_gauss.png: Not a directory"; the systems section's bicycle part
    also reported a FileExistsError)."""
    from ...core.errors import InputError
    from ...core.io import check_destination
    figdir = os.path.join(outdir, "figures")
    if os.path.lexists(figdir) and not os.path.isdir(figdir):
        raise InputError(f"{figdir} is not a directory: the report's figures go there")
    check_destination(os.path.join(figdir, "figure.png"))     # writable (made if missing)


def run(args) -> int:
    # the reports time the kernel every run gets from its first call (the generic one), not the one
    # specialised per (s, n, m) that a long-lived process builds in the background: a row must not
    # depend on when a build finished (benchmarks/quasi_step.py measures both; the results are the
    # same bits either way). The workers inherit this.
    os.environ["LDASPARK_SPECIALISE"] = "0"
    if getattr(args, "section", None):
        _main_options_to_section(args)
    outdir = getattr(args, "outdir", None)
    if outdir is not None and os.path.lexists(outdir) and not os.path.isdir(outdir):
        # refused now: every section writes OUTDIR/<name> and OUTDIR/figures at the end of its runs
        from ...core.errors import InputError
        raise InputError(f"--outdir {outdir} is not a directory")
    if outdir is not None:
        _check_outdir_writable(outdir)
        if getattr(args, "section", None) != "claims":     # every other section plots into OUTDIR/figures
            check_figures_dir(outdir)
    if getattr(args, "section", None):
        return int(args.section_run(args) or 0)
    from ...core.errors import InputError
    from ...executors import check_where
    from .jobs import run_sections
    check_where(getattr(args, "scheduler", None))    # before the CPU probe and the section imports
    if args.workers is not None and getattr(args, "scheduler", None) is not None:
        # the cluster's workers run the jobs: --workers was accepted and ignored there
        raise InputError("--workers sets the local worker processes; with --scheduler the cluster's workers run "
                         "the jobs: give one of them")
    workers = args.workers or os.cpu_count() or 1
    if workers < 1:
        raise InputError(f"--workers must be positive, got {workers}")
    for mod in available_sections().values():      # each section's files, before any of them runs
        check_report_files(args.outdir, importlib.import_module(mod).REPORT_FILES)
    from .timing import probe_cpu
    probe = probe_cpu()                  # before the workers start: the machine's speed, not the job's
    clock = Clock()
    modules = {name: importlib.import_module(mod) for name, mod in available_sections().items()}
    stats = run_sections(modules, args.outdir, full=getattr(args, "full", False), workers=workers,
                         where=getattr(args, "scheduler", None))
    print("[report] section      CPU [s]  written at [s wall]", flush=True)
    for name, st in stats.items():
        print(f"[report] {name:14s} {st['cpu']:7.1f}  {st['wall']:7.1f}", flush=True)
    print(f"[report] all sections: {clock.summary()} -> {args.outdir}", flush=True)
    write_run_timing(args.outdir, stats, clock, workers, full=getattr(args, "full", False), probe=probe)
    return 0


def write_run_timing(outdir, stats, clock, workers, full=False, probe=None):
    """``OUTDIR/report_timing.json``: the wall and CPU time of this run of the main job, per
    section and in all (README quotes it), with the machine's core count and load, and the CPU
    time of the fixed probe (``timing.probe_cpu``) so that ``cpu_over_probe`` compares machines.
    The "readme" block of the file it replaces (the snapshot of the timings README quotes,
    ``summary.write_snapshot``) is kept: README's timing marks are checked against it."""
    import datetime
    from .files import load_json
    import platform
    from ...core.io import atomic_write_json
    path = os.path.join(outdir, "report_timing.json")
    keep = {}
    try:
        old = load_json(path)
        if isinstance(old, dict) and isinstance(old.get("readme"), dict):
            keep["readme"] = old["readme"]
    except (OSError, ValueError):
        pass
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    extra = {} if probe is None else {
        "probe": {"cpu": round(probe, 4), "what": "ldaspark.lab.reports.timing.probe_cpu (min of 3)"},
        "cpu_over_probe": round(clock.cpu / probe)}
    atomic_write_json(path, {
        "command": f"ldaspark report{' --full' if full else ''}", "wall": round(clock.wall, 1),
        "cpu": round(clock.cpu, 1), "workers": workers, "cpu_count": os.cpu_count(),
        "load_average_1min_at_end": None if load is None else round(load, 2),
        "date": datetime.date.today().isoformat(), "python": platform.python_version(),
        "sections": {k: {"cpu": round(v["cpu"], 1), "written_at_wall": round(v["wall"], 1), "jobs": v["jobs"]}
                     for k, v in stats.items()}, **extra, **keep})
