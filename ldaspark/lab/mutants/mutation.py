"""Mutation testing of the verification suite: ``ldaspark mutants [--quick] [--outdir DIR] [--jobs N]``.

Each mutant of ``ldaspark.lab.mutants.mutation_catalogue.CATALOGUE`` (a semantic fault a developer
of the method could plausibly make) is applied in isolation to a scratch copy of the project
(package, tests, verification suite), and pytest runs against that copy, stopping at the first
failure (``-x``), with the mutant's hint files first. A mutant is

* killed: pytest failed a test (its id is recorded);
* SURVIVED: the suite passed, i.e. no check can see the fault: a missing test;
* invalid: the mutated package does not compile or a test module cannot be collected (a
  catalogue error, not a verdict on the suite);
* timeout: pytest did not finish in time (counted as not killed).

Writes ``mutation.md`` (table and the command that reproduces it) and ``mutation.json`` (list of
{mutant, file, description, category, killed, status, first_failing_test, seconds}) to
``--outdir`` (default ``reports``). ``--quick`` runs the fixed subset ``QUICK`` with the hint
files only, and the generated mutants ``mutgen.QUICK_GENERATED`` against their one test each.
``--generated MODULE...``: generated operator mutants instead (``ldaspark.lab.mutants.mutgen``). The catalogue checks its own snippets first (each must occur exactly once).
"""
from __future__ import annotations

import concurrent.futures
import hashlib
import os
import re
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

from ...core.errors import LdasparkError
from ...core.lifecycle import run_linked, subprocess_guard
from .mutation_catalogue import CATALOGUE, QUICK, Mutant, by_id

PACKAGE = pathlib.Path(__file__).resolve().parents[2]          # .../ldaspark
PROJECT = PACKAGE.parent
# what a test run needs from the project tree (tests read examples/, README.md, .ci/run)
# reports/: README's marks and the report tests read the committed reports; without them those
# tests fail in every copy and would "kill" a mutant that the rest of the suite lets survive
#: what a test run reads: the tests collect the docs' tutorials and read the benchmarks' sources
COPY = ("ldaspark", "tests", "verification", "examples", "reports", "docs", "benchmarks", "conftest.py",
        "pyproject.toml", "README.md", "LICENSE", ".ci")
#: a kill found by the rest of the suite (after the hint files) counts only if that test passes
#: on the unmutated copy; a test that fails there too (something the copy lacks, a test that
#: depends on the machine) is deselected and the run goes on, at most this many times
MAX_CONTROL = 3
EXCLUDED_TESTS = ("tests/lab/mutants/test_mutation_quick.py",)          # would recurse into this runner
TIMEOUT = 1500


class CatalogueError(LdasparkError):
    """A catalogue snippet does not occur exactly once in the current source."""


# --- applying mutants ---------------------------------------------------------------------------
def resolve_file(package_dir, mutant: Mutant) -> tuple[pathlib.Path | None, str]:
    """The file the mutant applies to: ``mutant.file`` may list alternatives separated by '|'
    (code that is expected to move, e.g. the compiled kernels); exactly one of them must hold the
    snippet, exactly once. Returns (path, "") or (None, why not)."""
    counts = {}
    for rel in mutant.file.split("|"):
        path = pathlib.Path(package_dir) / rel
        counts[rel] = path.read_text().count(mutant.snippet) if path.is_file() else None
    hits = [rel for rel, n in counts.items() if n]
    if len(hits) == 1 and counts[hits[0]] == 1:
        return pathlib.Path(package_dir) / hits[0], ""
    if all(n is None for n in counts.values()):
        return None, f"file ldaspark/{mutant.file} not found"
    where = ", ".join(f"{n if n is not None else 'no file'} in ldaspark/{rel}" for rel, n in counts.items())
    return None, f"snippet occurs {where} (must be exactly once in exactly one file)"


def snippet_problems(package_dir=PACKAGE, catalogue=CATALOGUE) -> list[str]:
    """Every mutant whose snippet does not occur exactly once in its file (empty list: all good),
    plus duplicate ids and no-op replacements."""
    out = []
    seen = set()
    for m in catalogue:
        if m.id in seen:
            out.append(f"{m.id}: duplicate id")
        seen.add(m.id)
        if m.snippet == m.replacement:
            out.append(f"{m.id}: replacement equals the snippet")
        path, why = resolve_file(package_dir, m)
        if path is None:
            out.append(f"{m.id}: {why}")
    return out


def apply_mutant(root, mutant: Mutant) -> pathlib.Path:
    """Apply ``mutant`` to the package copy under ``root`` (root/ldaspark/...); returns the file.
    Raises CatalogueError unless the snippet occurs exactly once."""
    path, why = resolve_file(pathlib.Path(root) / "ldaspark", mutant)
    if path is None:
        raise CatalogueError(f"mutant {mutant.id}: {why}")
    path.write_text(path.read_text().replace(mutant.snippet, mutant.replacement))
    refresh_helper_digests(root)
    return path


#: a kernel module's record of the files numba compiles into it, and their sha256 (numba keys a
#: cached kernel on its own file only: ``compiled/kernels*.py``)
_HELPERS = re.compile(r"^HELPERS = \((.*?)\)\n", re.S | re.M)
_HELPERS_SHA256 = re.compile(r'^HELPERS_SHA256 = "[0-9a-f]{64}"', re.M)


def refresh_helper_digests(root) -> list:
    """Recompute the kernel modules' HELPERS_SHA256 in the copy under ``root`` after a mutant was
    applied; returns the files rewritten. A mutant of a helper (newton.py, kernels_mech.py, ...)
    changes the digest its kernel records, and the test that checks the record
    (``test_kernel_file_records_its_helpers``) then killed every such mutant for its bookkeeping,
    not for what it does (probe t24, stop 65). Repeated until nothing changes: a digest line is
    itself part of another kernel's helpers (kernels.py in kernels_quasi.py's)."""
    d = pathlib.Path(root) / "ldaspark" / "compiled"
    changed: list = []
    for _ in range(8):
        again = False
        for p in sorted(d.glob("kernels*.py")):
            text = p.read_text()
            m = _HELPERS.search(text)
            if m is None or _HELPERS_SHA256.search(text) is None:
                continue
            h = hashlib.sha256()
            for name in re.findall(r'"([^"]+)"', m.group(1)):
                h.update((d / name).read_bytes())
            new = _HELPERS_SHA256.sub(f'HELPERS_SHA256 = "{h.hexdigest()}"', text, count=1)
            if new != text:
                p.write_text(new)
                changed.append(p.name)
                again = True
        if not again:
            return changed
    raise CatalogueError("refresh_helper_digests: the kernels' helper digests do not settle (a cycle in HELPERS)")


_COPY_IGNORE = ("__pycache__", ".hypothesis", ".pytest_cache")


def _copy_tree(src: pathlib.Path, dst: pathlib.Path, root: pathlib.Path, skipped: list) -> None:
    """Copy the directory ``src`` to ``dst`` without ever following a link: regular files are
    copied, directories walked, a link kept as a link when it points inside the project tree
    (``root``) at a file or directory that is copied too, and skipped otherwise; FIFOs, sockets
    and devices are skipped (a link to /dev/zero would be copied until the disk is full)."""
    import stat
    dst.mkdir(parents=True, exist_ok=True)
    with os.scandir(src) as it:
        entries = sorted(it, key=lambda e: e.name)
    for e in entries:
        if e.name in _COPY_IGNORE or e.name.endswith(".pyc"):
            continue
        s, d = pathlib.Path(e.path), dst / e.name
        st = os.lstat(s)
        if stat.S_ISDIR(st.st_mode):
            _copy_tree(s, d, root, skipped)
        elif stat.S_ISREG(st.st_mode):
            _copy_regular(s, d)
        elif stat.S_ISLNK(st.st_mode) and _link_inside(s, root):
            os.symlink(os.readlink(s), d)
        else:
            skipped.append(str(s.relative_to(root)))


def _copy_regular(src: pathlib.Path, dst: pathlib.Path) -> None:
    """A regular file, opened without following a link and without blocking (a file swapped for
    a FIFO after the walk looked at it is skipped, never read)."""
    import stat
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(src, flags)
    except OSError:
        return
    if not stat.S_ISREG(os.fstat(fd).st_mode):          # before fdopen, which refuses a directory
        os.close(fd)
        return
    with os.fdopen(fd, "rb") as fh:
        with open(dst, "wb") as out:
            shutil.copyfileobj(fh, out)
    shutil.copystat(src, dst, follow_symlinks=False)


def _link_inside(link: pathlib.Path, root: pathlib.Path) -> bool:
    """The link's target, relative and resolved, is a regular file or directory inside ``root``
    under one of the copied entries (``COPY``), so the copy holds it too."""
    import stat
    target = os.readlink(link)
    if os.path.isabs(target):
        return False
    try:
        real = (link.parent / target).resolve(strict=True)
        rel = real.relative_to(root.resolve())
        mode = os.stat(real).st_mode
    except (ValueError, OSError, RuntimeError):
        return False
    return bool(rel.parts) and rel.parts[0] in COPY and (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def copy_project(dest, project=PROJECT) -> pathlib.Path:
    """The parts of the project a test run needs (``COPY``), without caches. Never follows a
    link out of the tree nor into a special file (``_copy_tree``)."""
    import stat
    dest = pathlib.Path(dest)
    root = pathlib.Path(project)
    skipped: list = []
    dest.mkdir(parents=True, exist_ok=True)
    for name in COPY:
        src = root / name
        try:
            st = os.lstat(src)
        except OSError:
            continue
        if stat.S_ISDIR(st.st_mode):
            _copy_tree(src, dest / name, root, skipped)
        elif stat.S_ISREG(st.st_mode):
            _copy_regular(src, dest / name)
        elif stat.S_ISLNK(st.st_mode) and _link_inside(src, root):
            os.symlink(os.readlink(src), dest / name)
        else:
            skipped.append(name)
    return dest


def verdict_paths(project=None) -> list[pathlib.Path]:
    """Every path a mutant's verdict depends on: what ``copy_project`` copies (the package with
    its data, tests/, verification/ with the equivalents list and its helpers, conftest.py,
    pyproject.toml, the reports the tests read, ...)."""
    return [pathlib.Path(PROJECT if project is None else project) / name for name in COPY]


def verdict_fingerprint(*config, project=None) -> str:
    """The checkpoint fingerprint of a mutation run: ``config`` and every file under
    ``verdict_paths`` (a change in any of them invalidates the records of an interrupted run)."""
    from ..checkpoint import source_fingerprint
    return source_fingerprint(*config, paths=verdict_paths(project))


def all_test_files(project=PROJECT) -> list[str]:
    import stat
    files = sorted(str(p.relative_to(project)) for d in ("verification", "tests")
                   for p in (pathlib.Path(project) / d).rglob("test_*.py")
                   if stat.S_ISREG(os.lstat(p).st_mode))      # a FIFO or a link is never a test file
    return [f for f in files if f not in EXCLUDED_TESTS]


def ordered_targets(mutant: Mutant, project=PROJECT, hints_only=False, exclude=()) -> list[str]:
    """The mutant's hint files (or node ids) first, then every other test file; files in
    ``exclude`` are left out (to ask whether the rest of the suite alone would kill)."""
    hint = [h for h in mutant.hint if (pathlib.Path(project) / h.split("::")[0]).exists()
            and h.split("::")[0] not in exclude]
    if hints_only:
        return hint
    hinted = {h.split("::")[0] for h in hint if "::" not in h}
    return hint + [f for f in all_test_files(project) if f not in hinted and f not in exclude]


# --- running --------------------------------------------------------------------------------------
#: pytest's exit code for "tests were collected and run, and some failed": the only one a kill comes from
#: (2 interrupted, a collection error; 3 internal error; 4 usage error; 5 no tests collected;
#: negative: killed by a signal, a segfault)
PYTEST_TESTS_FAILED = 1
_SUMMARY = "short test summary info"


def _first_failure(output: str) -> str | None:
    """The first test pytest's short summary (``-rfE``) names as FAILED or ERROR: only lines
    after the summary's header count (a test's own output saying "FAILED x" is not a verdict),
    and a collection error of a whole file ('ERROR tests/x.py') names no test."""
    lines = output.splitlines()
    start = next((i for i in range(len(lines) - 1, -1, -1) if _SUMMARY in lines[i] and lines[i].startswith("=")), None)
    if start is None:
        return None
    for line in lines[start + 1:]:
        if line.startswith("="):
            break
        for tag in ("FAILED ", "ERROR "):
            if line.startswith(tag):
                node = line[len(tag):].split(" - ")[0].strip()
                return node if "::" in node else None
    return None


def run_pytest(root, targets, timeout=TIMEOUT, cache_dir=None, python=sys.executable):
    """pytest -x on ``targets`` inside the copy ``root`` with only that copy on the path.
    Returns (returncode or None on timeout, output, seconds)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = str(root)
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    if cache_dir is not None:
        env["LDASPARK_CACHE_DIR"] = str(cache_dir)
    cmd = [python, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-rfE", *targets]
    t = time.time()
    try:
        # a child that dies with this process (and is killed when the run is stopped)
        p = run_linked(cmd, cwd=root, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        out = (exc.stdout or b"").decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        return None, out, time.time() - t
    return p.returncode, p.stdout + p.stderr, time.time() - t


def classify(rc, output) -> tuple[str, str | None]:
    """(status, first failing test) from a pytest run on a mutant. A kill is pytest's exit code
    1 (tests ran and failed) with a failing test named in its summary, nothing else:

    * ``rc`` None (the time bound passed): "timeout", counted with the survivors, never a kill;
    * 0: "survived";
    * 1 with a test named: "killed";
    * 1 without one (a process that exited 1 by itself), 2 (a collection error, an
      interruption), 3, 4, 5 (no test ran), a negative code (a signal: a segfault, a kill) or
      any other: "invalid", not a verdict on the suite."""
    if rc is None:
        return "timeout", None
    if rc == 0:
        return "survived", None
    first = _first_failure(output)
    if rc == PYTEST_TESTS_FAILED and first is not None:
        return "killed", first
    return "invalid", first


def project_snapshot(project=PROJECT) -> bytes:
    """The parts of the project a test run needs (``copy_project``) as a gzipped tar: what a
    mutant's work unit carries to a worker on another machine (~0.4 MB)."""
    import io
    import tarfile
    buf = io.BytesIO()
    with tempfile.TemporaryDirectory(prefix="ldaspark-snap-") as tmp:
        root = copy_project(pathlib.Path(tmp) / "proj", project)
        with tarfile.open(fileobj=buf, mode="w:gz") as tar:
            for p in sorted(root.iterdir()):
                tar.add(p, arcname=p.name)
    return buf.getvalue()


def _unpack_snapshot(snapshot: bytes, dest) -> pathlib.Path:
    import io
    import tarfile
    dest = pathlib.Path(dest)
    dest.mkdir(parents=True)
    with tarfile.open(fileobj=io.BytesIO(snapshot), mode="r:gz") as tar:
        # the "data" filter refuses absolute paths, links out of dest and device files
        tar.extractall(dest, filter="data")
    return dest


def run_mutant(mutant: Mutant | None, hints_only=False, project=PROJECT, timeout=TIMEOUT,
               targets=None, exclude=(), snapshot: bytes | None = None) -> dict:
    """Apply one mutant (None: the unmutated package, a control) to a fresh scratch copy (of
    ``project``, or unpacked from ``snapshot``, see ``project_snapshot``), run the suite (or
    ``targets``), return its record. A kill found by the rest of the suite (not by the hint files
    or the given targets) counts only if that test passes on an unmutated copy; a test failing
    there too is deselected and the run goes on (at most MAX_CONTROL times, then "invalid")."""
    t = time.time()
    label = mutant.id if mutant is not None else "none"
    import re
    safe = re.sub(r"[^A-Za-z0-9_.-]", "_", label)[:60]      # generated ids hold '/', ':', '>'
    with tempfile.TemporaryDirectory(prefix=f"ldaspark-mut-{safe}-") as tmp:
        if snapshot is not None:
            root = _unpack_snapshot(snapshot, pathlib.Path(tmp) / "proj")
        else:
            root = copy_project(pathlib.Path(tmp) / "proj", project)
        if mutant is not None:
            # a generated mutant (``mutgen.GenMutant``) splices itself in at a fixed offset
            path = mutant.apply(root) if hasattr(mutant, "apply") else apply_mutant(root, mutant)
            try:
                compile(path.read_text(), str(path), "exec")
            except SyntaxError as exc:
                return _record(mutant, "invalid", f"SyntaxError: {exc}", time.time() - t)
        cache = pathlib.Path(tmp) / "cache" if mutant is not None and mutant.category == "compiled" else None
        phases = [targets]
        suite_phase = None           # the index of the phase that runs the rest of the suite
        if targets is None:
            full = ordered_targets(mutant, root, hints_only, exclude)
            hint = ordered_targets(mutant, root, True, exclude) if mutant is not None else []
            # the hint files alone first (pytest collects only them: seconds), then the rest of
            # the suite only if they pass: the same verdict and first failing test as one run
            # of hint + rest with -x, without collecting the whole suite for every killed mutant
            phases = [hint, full[len(hint):]] if hint and not hints_only else [full]
            suite_phase = None if hints_only else len(phases) - 1
        if not phases[0]:     # pytest without targets would run its default testpaths
            raise CatalogueError(f"mutant {label}: none of its hint files exists")
        control = None
        deselected: list = []
        for i, phase in enumerate(phases):
            if not phase:
                continue
            while True:
                left = max(1.0, timeout - (time.time() - t))
                rc, out, _ = run_pytest(root, list(phase) + [f"--deselect={d}" for d in deselected], left, cache)
                status, first = classify(rc, out)
                if status != "killed" or mutant is None or i != suite_phase:
                    break
                # the rest of the suite named a test: it must pass without the mutant to be a kill
                if control is None:
                    control = (_unpack_snapshot(snapshot, pathlib.Path(tmp) / "control") if snapshot is not None
                               else copy_project(pathlib.Path(tmp) / "control", project))
                crc, cout, _ = run_pytest(control, [first], max(1.0, timeout - (time.time() - t)), None)
                if crc == 0:
                    break
                deselected.append(first)
                if len(deselected) > MAX_CONTROL:
                    status, out = "invalid", (f"{len(deselected)} tests fail on the unmutated copy too: "
                                              + ", ".join(deselected) + "\n" + cout)
                    break
            if status != "survived":
                break
        if deselected and status != "invalid":
            out = "deselected (they fail on the unmutated copy too): " + ", ".join(deselected) + "\n" + out
        rec = _record(mutant, status, first, time.time() - t)
        if mutant is not None:       # the file actually mutated (of the alternatives)
            rec["file"] = str(path.relative_to(root))
        if status != "killed":
            rec["output_tail"] = out[-2000:]
        return rec


STATUSES = ("killed", "survived", "invalid", "timeout")
_TEXT_FIELDS = ("file", "description", "category")


def check_record(name, rec):
    """The schema of a mutant's record (``_record``, ``run_mutant``), for the checkpoint reader:
    the mutant is the unit, status from STATUSES, killed a bool that says status == killed,
    strings where ``_record`` puts strings, finite seconds >= 0. Raises LdasparkError."""
    import math
    keys = {"mutant", "file", "description", "category", "killed", "status", "first_failing_test", "seconds"}
    if not isinstance(rec, dict) or not keys <= set(rec) or not set(rec) <= keys | {"output_tail"}:
        raise LdasparkError(f"the record of {name} does not have a mutant record's keys")
    if rec["mutant"] != name:
        raise LdasparkError(f"the record of {name} names the mutant {str(rec['mutant'])[:40]}")
    if rec["status"] not in STATUSES or not isinstance(rec["killed"], bool) or rec["killed"] != (rec["status"] == "killed"):
        raise LdasparkError(f"the record of {name} has status {str(rec['status'])[:20]}, killed {rec['killed']!r}")
    if not all(isinstance(rec[k], str) for k in _TEXT_FIELDS) or not isinstance(rec.get("output_tail", ""), str) \
            or not (rec["first_failing_test"] is None or isinstance(rec["first_failing_test"], str)):
        raise LdasparkError(f"the record of {name} has a text field that is not a string")
    sec = rec["seconds"]
    if isinstance(sec, bool) or not isinstance(sec, (int, float)) or not math.isfinite(sec) or sec < 0:
        raise LdasparkError(f"the record of {name} has seconds {str(sec)[:30]}")
    return True


def _record(m: Mutant | None, status, first, seconds) -> dict:
    if m is None:
        m = Mutant("none", "", "", "", "unmutated package (control)", "control")
    return {"mutant": m.id, "file": "|".join(f"ldaspark/{f}" for f in m.file.split("|")), "description": m.description,
            "category": m.category, "killed": status == "killed", "status": status,
            "first_failing_test": first, "seconds": round(seconds, 1)}


def run_catalogue(mutants, jobs=2, hints_only=False, progress=None, exclude=(), where=None,
                  checkpoint=None, targets=None, timeout=TIMEOUT) -> list[dict]:
    """Run mutants, ``jobs`` at a time on this machine (threads, each driving a pytest process), or
    as work units on a Dask cluster (``where``: a scheduler address or client; each unit carries
    a snapshot of the project); records in catalogue order. ``checkpoint``
    (``ldaspark.lab.checkpoint.Checkpoint``): mutants finished by an interrupted run are resumed
    from it. ``targets``: {mutant id: test node ids} to run instead of the suite."""
    from ...executors import Unit, check_where, is_address
    from ..checkpoint import run_resumable
    check_where(where, jobs)
    targets = targets or {}
    remote = where is not None and where != "local"
    snapshot = project_snapshot() if remote else None
    units = [Unit(m.id, run_mutant, (m, hints_only, PROJECT, timeout, targets.get(m.id), tuple(exclude), snapshot))
             for m in mutants]

    def done(name, rec):
        if progress is not None:
            progress(rec)
    if checkpoint is not None:      # a verdict depends on these, whatever the caller's fingerprint
        checkpoint = checkpoint.bound_to("run_catalogue", hints_only, sorted(exclude), sorted(targets.items()),
                                         timeout)
    if remote:
        recs = run_resumable(units, checkpoint, where=where, on_done=done, validate=check_record)
    else:
        assert not is_address(where)
        with subprocess_guard() as guard, concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs)) as ex:
            try:
                recs = run_resumable(units, checkpoint, where=ex, on_done=done, validate=check_record)
            except BaseException:
                # stopped (a signal, an error): the threads' pytest processes are killed and no
                # new one starts, so that leaving the pool does not wait for them to finish
                guard.stop()
                raise
    return [recs[m.id] for m in mutants]


def require_tests(project=PROJECT):
    """Refuse at once (one line, exit 2) when the project's tests are not beside the package: an
    installed wheel has ``ldaspark/`` only, and every mutant would fail after minutes."""
    have = [d for d in ("tests", "verification") if any((pathlib.Path(project) / d).rglob("test_*.py"))]
    if len(have) < 2:
        raise CatalogueError(f"ldaspark mutants needs the repository's tests (tests/ and verification/ beside the "
                             f"ldaspark package; none under {project}): run it from a git checkout or an unpacked "
                             "source distribution")


# --- reports ----------------------------------------------------------------------------------
def _cell(x) -> str:
    return "" if x is None else str(x).replace("|", "\\|").replace("\n", " ")


def write_reports(recs, outdir, command, seconds):
    from ...core.io import atomic_write_json, atomic_write_text
    outdir = pathlib.Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    atomic_write_json(outdir / "mutation.json", [{k: r[k] for k in (
        "mutant", "file", "description", "category", "killed", "status", "first_failing_test", "seconds")}
        for r in recs])
    n_k = sum(r["killed"] for r in recs)
    lines = [
        "# Mutation catalogue: does the suite notice plausible faults?",
        "",
        "Each row is one semantic fault a developer of the method could plausibly make, planted alone in a",
        "scratch copy of the package (`ldaspark/lab/mutants/mutation_catalogue.py`); the unit tests and the",
        "verification suite then run against the copy and stop at the first failure. A killed mutant names",
        "the first test that failed; a surviving one would be a fault no check can see.",
        "",
        f"**{n_k} of {len(recs)} mutants killed** ({100 * n_k / max(len(recs), 1):.0f}%), "
        f"wall time {seconds / 60:.1f} min.",
        "",
        f"Reproduce: `{command}`",
        "",
        "| category | mutants | killed |",
        "|---|---|---|",
    ]
    cats = {}
    for r in recs:
        c = cats.setdefault(r["category"], [0, 0])
        c[0] += 1
        c[1] += bool(r["killed"])
    lines += [f"| {c} | {a} | {b} |" for c, (a, b) in cats.items()]
    lines += [
        "",
        "| mutant | file | description | killed | first failing test | seconds |",
        "|---|---|---|---|---|---|",
    ]
    for r in recs:
        k = "yes" if r["killed"] else f"**NO ({r['status']})**"
        lines.append(f"| {_cell(r['mutant'])} | {_cell(r['file'])} | {_cell(r['description'])} | {k} | "
                     f"{_cell(r['first_failing_test'])} | {r['seconds']:.1f} |")
    atomic_write_text(outdir / "mutation.md", "\n".join(lines) + "\n")
