"""``ldaspark mutants``: the command that runs the mutation catalogue (``mutation``) or the
generated operator mutants (``mutgen``); see ``ldaspark.lab.mutants.mutation`` for what a run does and
writes. Here so that the runner and the generator import neither each other nor the CLI."""
from __future__ import annotations

import pathlib
import sys
import time

from ...core.errors import LdasparkError
from ...executors import UnitsFailed, add_scheduler_argument
from ..checkpoint import Checkpoint
from .mutation import (PROJECT, QUICK, CATALOGUE, EXCLUDED_TESTS, TIMEOUT, CatalogueError, all_test_files, by_id,
                       ordered_targets,
                       require_tests, run_catalogue, run_mutant, snippet_problems, verdict_fingerprint, write_reports)
from .mutgen import quick_generated, run_generated


# --- CLI ----------------------------------------------------------------------------------------
def add_arguments(parser):
    parser.add_argument("--quick", action="store_true",
                        help=f"only the fixed subset {', '.join(QUICK)}, with their hint files")
    parser.add_argument("--outdir", default="reports", help="directory for mutation.md and mutation.json")
    # default None, resolved to 2 in run(): a --jobs given with --scheduler is refused, not ignored
    parser.add_argument("--jobs", type=int, default=None, help="mutants run in parallel (default 2)")
    parser.add_argument("--only", default=None, help="comma-separated mutant ids (default: the whole catalogue); "
                        "with --generated also @FILE (one id per line), and with --keep-killed an update of that "
                        "report: these mutants run again, every other one keeps its earlier record")
    parser.add_argument("--exclude", default="",
                        help="comma-separated test files to leave out (which mutants would the rest miss?)")
    add_scheduler_argument(parser)
    parser.add_argument("--fresh", action="store_true",
                        help="do not resume from the checkpoint of an interrupted run (OUTDIR/mutation.partial.jsonl)")
    parser.add_argument("--generated", nargs="+", default=None, metavar="MODULE",
                        help="generated operator mutants of these modules (ldaspark/core/validate.py or "
                             "ldaspark.core.validate) instead of the catalogue; writes mutation-generated.md/json")
    parser.add_argument("--tests", default=None,
                        help="with --generated: comma-separated test files to map by coverage, or 'suite' for the "
                             "whole default suite (default: those importing the modules, plus the verdict-rule "
                             "tests)")
    parser.add_argument("--coverage-only", action="store_true",
                        help="with --generated: measure the branch coverage of the modules by the mapped tests and "
                             "write coverage-checking.md/json, without running mutants")
    parser.add_argument("--limit", type=int, default=None, help="with --generated: run only the first N mutants")
    parser.add_argument("--keep-killed", default=None, metavar="JSON",
                        help="with --generated: take the mutants killed in this earlier mutation-generated.json "
                             "(or these, comma-separated; the first is the report an update continues) as killed "
                             "(their killing test still exists) and run the others; a kill is kept only from a "
                             "report signed with this user's key or an authenticated checkpoint record, the kills "
                             "of any other file are run again, their named test first")
    parser.add_argument("--sample", type=int, default=None,
                        help="with --generated: a fixed, evenly spaced sample of N mutants per module, drawn "
                             "from all its mutants (the same whatever the tests)")
    parser.add_argument("--kinds", default=None,
                        help="with --generated: comma-separated operator kinds to run (call-swap, compare, boolean, "
                             "not-removal, arithmetic, constant, return, slice, unary; default: all)")
    parser.add_argument("--mutant-timeout", type=int, default=None,
                        help="with --generated: whole seconds per mutant, 1..86400 (default 300)")


def run_control(mutants, targets, exclude=()) -> dict:
    """The unmutated package against every test a quick mutant is judged by (its hint files, or
    its one target): they must all pass, else a "killed" verdict says nothing about the mutant
    (a committed report or a fixture that fails without any fault would kill them all)."""
    tests = sorted({h for m in mutants if m.id not in targets for h in ordered_targets(m, PROJECT, True, exclude)}
                   | {x for ts in targets.values() for x in ts})
    rec = run_mutant(None, targets=tests, timeout=TIMEOUT)
    print(f"{'control (unmutated)':32s} {'passes' if rec['status'] == 'survived' else rec['status']:9s} "
          f"{rec['seconds']:7.1f}s  {len(tests)} test files and node ids", flush=True)
    if rec["status"] != "survived":
        raise CatalogueError(f"the unmutated package fails the quick set's own tests ({rec['status']}: "
                             f"{rec['first_failing_test'] or 'no test named'}), so no mutant verdict would mean anything")
    return rec


def run(args) -> int:
    require_tests()
    only_generated = [f"--{k.replace('_', '-')}" for k in ("tests", "limit", "keep_killed", "sample", "mutant_timeout",
                                                                 "kinds")
                      if getattr(args, k, None) is not None]
    if getattr(args, "coverage_only", False):
        only_generated.append("--coverage-only")
    if only_generated and not getattr(args, "generated", None):
        raise CatalogueError(f"{', '.join(only_generated)}: only with --generated MODULE...")
    # options of the catalogue run that the generated run has no use for: refused, not ignored
    # (``--generated M --quick`` ran every generated mutant of M, hours instead of a quick set)
    not_generated = [o for o, given in (("--quick", getattr(args, "quick", False)),
                                        ("--exclude", bool((getattr(args, "exclude", "") or "").strip())))
                     if given]
    if not_generated and getattr(args, "generated", None):
        raise CatalogueError(f"{', '.join(not_generated)}: not with --generated (the catalogue's options; "
                             "--generated selects its mutants with --only, --sample, --kinds, --limit)")
    # the user's own input is judged before the catalogue (a malformed --scheduler is one line
    # about it, in a mutated copy too, where the catalogue itself is "out of date": that test would
    # otherwise kill every mutant that reached it)
    from ...executors import check_where
    check_where(getattr(args, "scheduler", None))
    if getattr(args, "jobs", None) is None:
        args.jobs = 2
    elif getattr(args, "scheduler", None) is not None and not getattr(args, "generated", None):
        # the cluster's workers run the catalogue's units: --jobs was accepted and ignored there
        # (with --generated it still sets the local processes of the coverage map)
        raise CatalogueError("--jobs sets the mutants run in parallel on this machine; with --scheduler the "
                             "cluster's workers run them: give one of them")
    if getattr(args, "generated", None):
        if args.jobs < 1:
            raise CatalogueError("--jobs must be >= 1")
        return run_generated(args)
    exclude = tuple(x.strip() for x in args.exclude.split(",") if x.strip())
    known = set(all_test_files(PROJECT)) | set(EXCLUDED_TESTS)
    unknown = [x for x in exclude if x not in known]
    if unknown:     # a misspelt file excluded nothing, and the run answered another question
        raise CatalogueError(f"--exclude {unknown[0][:80]!r} is not a test file of the suite (a path such as "
                             "tests/core/test_spark.py or verification/test_theorem1.py, relative to the project)")
    problems = snippet_problems()
    if problems:
        raise CatalogueError("mutation catalogue out of date: " + "; ".join(problems))
    if args.only is not None:
        ids = [x.strip() for x in args.only.split(",") if x.strip()]
        if not ids:      # '--only ,' would run nothing and report success
            raise CatalogueError(f"--only {args.only[:80]!r} selects no mutant (comma-separated catalogue ids)")
        try:
            mutants = [by_id(x) for x in ids]
        except KeyError as exc:
            raise CatalogueError(f"unknown mutant id {str(exc.args[0])[:80]!r}") from None
    else:
        mutants = [by_id(x) for x in QUICK] if args.quick else list(CATALOGUE)
    targets = {}
    if args.quick and args.only is None:
        # a fixed sample of generated mutants, each run against the one test that must kill it
        gen, targets = quick_generated()
        mutants += gen
    if args.jobs < 1:
        raise CatalogueError("--jobs must be >= 1")
    t = time.time()

    def progress(r):
        print(f"{r['mutant']:32s} {r['status']:9s} {r['seconds']:7.1f}s  {r['first_failing_test'] or ''}",
              flush=True)
    from .mutgen import make_outdir
    make_outdir(args.outdir)
    ck = Checkpoint(pathlib.Path(args.outdir) / "mutation.partial.jsonl",
                    verdict_fingerprint("mutants", args.quick, exclude))
    if getattr(args, "fresh", False):
        ck.discard()
    if args.quick:
        run_control(mutants, targets, exclude)
    try:
        recs = run_catalogue(mutants, args.jobs, hints_only=args.quick, progress=progress, exclude=exclude,
                             where=getattr(args, "scheduler", None), checkpoint=ck, targets=targets)
    except UnitsFailed as exc:
        raise UnitsFailed(exc.failed, exc.results, kept=ck.path) from None
    cmd = "ldaspark mutants" + (" --quick" if args.quick else "") + (f" --only {args.only}" if args.only else "") \
        + (f" --exclude {args.exclude}" if exclude else "") + f" --jobs {args.jobs}"
    write_reports(recs, args.outdir, cmd, time.time() - t)
    ck.discard()
    n_k = sum(r["killed"] for r in recs)
    print(f"{n_k} of {len(recs)} mutants killed -> {args.outdir}/mutation.md")
    return 0 if n_k == len(recs) else 1


def main(argv=None) -> int:
    import argparse
    p = argparse.ArgumentParser(prog="mutants", description=__doc__.splitlines()[0])
    add_arguments(p)
    try:
        return run(p.parse_args(argv))
    except LdasparkError as exc:
        print(f"mutants: error: {exc}", file=sys.stderr)
        return 2
