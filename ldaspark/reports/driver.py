"""``ldaspark report``: the main job.

``ldaspark report`` with no section writes every section's default report into reports/;
``ldaspark report SECTION [options]`` runs one section with its own options. Each section
lives in its own module (``ldaspark.report_<name>`` or as listed in SECTION_MODULES) exposing

* ``add_arguments(parser)``: options of ``ldaspark report SECTION``;
* ``run(args) -> int``: run with parsed options;
* ``run_default(outdir) -> None``: what the no-argument main job does for this section.

Sections whose module is not installed are skipped (and not offered on the command line).
"""
from __future__ import annotations

import importlib
import importlib.util
import time



REPORT_DIR = "reports"

# order = order of the main job
SECTION_MODULES = {
    "convergence": "ldaspark.reports.convergence",
    "energy": "ldaspark.reports.energy",
    "claims": "ldaspark.reports.claims",
    "work-precision": "ldaspark.reports.work_precision",
    "stability": "ldaspark.reports.stability",
}


def available_sections():
    out = {}
    for name, mod in SECTION_MODULES.items():
        if importlib.util.find_spec(mod) is not None:
            out[name] = mod
    return out


# --- dispatcher -----------------------------------------------------------------------------
def add_arguments(p):
    p.add_argument("--outdir", default=REPORT_DIR, help="directory of the reports (main job)")
    sub = p.add_subparsers(dest="section", parser_class=type(p))
    for name, mod in available_sections().items():
        sp = sub.add_parser(name, help=f"{name} report")
        module = importlib.import_module(mod)
        module.add_arguments(sp)
        sp.set_defaults(section_run=module.run)


def run(args) -> int:
    if getattr(args, "section", None):
        return int(args.section_run(args) or 0)
    for name, mod in available_sections().items():
        t = time.time()
        print(f"[report] {name} ...", flush=True)
        module = importlib.import_module(mod)
        module.run_default(args.outdir)
        print(f"[report] {name} done in {time.time() - t:.1f} s", flush=True)
    return 0
