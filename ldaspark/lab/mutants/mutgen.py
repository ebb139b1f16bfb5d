"""Generated mutants: ``ldaspark mutants --generated MODULE... [--outdir DIR] [--jobs N]``.

Where ``mutation_catalogue`` lists faults chosen by hand, this module generates the standard
operator mutants of the given modules from their syntax tree, one per site:

* comparisons: ``<`` <-> ``<=``, ``>`` <-> ``>=``, ``==`` <-> ``!=``, ``is`` <-> ``is not``,
  ``in`` <-> ``not in``;
* boolean ``and`` <-> ``or``; ``not x`` -> ``x``; unary ``-x`` -> ``x``;
* arithmetic ``+`` <-> ``-``, ``*`` <-> ``/``, ``//`` -> ``/``, ``**`` -> ``*``, ``%`` -> ``*``;
* integer constants ``c`` -> ``c + 1`` and ``0`` (``c = 0``: ``-1``); float constants -> ``0.0``
  (``0.0`` -> ``1.0``); ``True`` <-> ``False``;
* ``return X`` -> ``return None``;
* ``all`` <-> ``any``, ``min`` <-> ``max`` (calls by name);
* slice bounds ``a[i:j]`` -> ``a[i + 1:j]``, ``a[i:j + 1]``.

A mutant is a splice of one token (or one sub-expression) in the file's text, so everything
else in the file, comments and the catalogue's snippets included, stays byte for byte. Its id
names the file, the enclosing function, the operator and the text replaced, and a running
number among identical ones in the function: it survives edits elsewhere in the file.

Per-mutant test selection: the mapped test files (``--tests``; default: every test file that
imports the module, plus the verdict-rule tests) run once under ``coverage`` with the test's
node id as dynamic context; each mutant then runs only the tests that execute its line (none:
not covered, reported as such without a run). Docstrings and ``if __name__ ...`` blocks are
not mutated. The runner, the checkpoint (``OUTDIR/mutation-generated.partial.jsonl``: resumable)
and the ``--jobs`` / ``--scheduler`` distribution are those of ``ldaspark.lab.mutants.mutation``.

Equivalent mutants are listed in ``verification/mutants_equivalent.json`` ({id: one-line
argument}); a run reads it and does not run them. Writes ``mutation-generated.md`` and
``mutation-generated.json`` to ``--outdir``.
"""
from __future__ import annotations

import ast
import json
import pathlib
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field

from ...core.errors import LdasparkError
from ...core.io import atomic_write_json, atomic_write_text
from ...executors import UnitsFailed
from ..checkpoint import Checkpoint
from .mutation import TIMEOUT, all_test_files, refresh_helper_digests, require_tests, run_catalogue, verdict_fingerprint
from .records import (MAX_SOURCE_BYTES, RecordError, read_bytes, names_existing_test, read_equivalent, read_id_list, read_json,
                      read_previous, read_text, sign_report)

PACKAGE = pathlib.Path(__file__).resolve().parents[2]   # ./ldaspark
PROJECT = PACKAGE.parent
EQUIVALENT = PROJECT / "verification" / "mutants_equivalent.json"
HELPERS_DIR = "verification"     # its non-test modules (strategies, fixtures) are checking code too
#: ``--tests suite``: every test file the default ``pytest`` runs (the coverage the report gives is then
#: the default suite's)
SUITE = "suite"
#: the rule tests (``test_<module>_rules.py``, inputs built so that a rule and its neighbour differ,
#: their inner computations often replaced by stand-ins the coverage map cannot tie to the module)
#: run for every mutant of the module they are named after, and the bookkeeping file for all
ALWAYS_MAPPED = ("tests/lab/mutants/test_generated_mutants_kills.py",) + tuple(
    sorted(str(p.relative_to(PROJECT)) for p in (PROJECT / "tests").rglob("test_*_rules.py")))
BOOKKEEPING = ("tests/lab/mutants/test_generated_mutants_kills.py::test_the_equivalents_list_names_existing_mutants_with_an_argument",
               "tests/lab/mutants/test_generated_mutants_kills.py::test_the_quick_generated_mutants_still_exist_and_name_a_test")
TOOL = "ldaspark.lab.mutants.mutgen (AST operator mutants)"
VERSION = "1"


class MutgenError(LdasparkError):
    """A module to mutate does not exist or cannot be parsed; coverage is not installed."""


@dataclass(frozen=True)
class GenMutant:
    id: str
    file: str                    # relative to ldaspark/, or verification/NAME.py (a helper)
    line: int
    start: int                   # character offsets into the file's text
    end: int
    original: str
    replacement: str
    description: str
    category: str = "generated"
    hint: tuple = field(default=())

    def apply(self, root) -> pathlib.Path:
        path = pathlib.Path(root) / label(self.file)
        text = path.read_text()
        if text[self.start:self.end] != self.original:
            raise MutgenError(f"mutant {self.id}: source moved (expected {self.original!r} at line {self.line})")
        path.write_text(text[:self.start] + self.replacement + text[self.end:])
        refresh_helper_digests(root)
        return path

    def mutated_source(self, text: str) -> str:
        return text[:self.start] + self.replacement + text[self.end:]


# --- generation --------------------------------------------------------------------------------
CMP_SWAP = {ast.Lt: [("<", "<=")], ast.LtE: [("<=", "<")], ast.Gt: [(">", ">=")], ast.GtE: [(">=", ">")],
            ast.Eq: [("==", "!=")], ast.NotEq: [("!=", "==")]}
BIN_SWAP = {ast.Add: ("+", "-"), ast.Sub: ("-", "+"), ast.Mult: ("*", "/"), ast.Div: ("/", "*"),
            ast.FloorDiv: ("//", "/"), ast.Pow: ("**", "*"), ast.Mod: ("%", "*")}
NAME_SWAP = {"all": "any", "any": "all", "min": "max", "max": "min"}


class _Offsets:
    def __init__(self, text):
        self.text = text
        self.starts = [0]
        for line in text.splitlines(keepends=True):
            self.starts.append(self.starts[-1] + len(line))

    def at(self, line, col_bytes):
        # ast columns are UTF-8 byte offsets
        lt = self.text[self.starts[line - 1]:self.starts[line] if line < len(self.starts) else None]
        return self.starts[line - 1] + len(lt.encode()[:col_bytes].decode(errors="ignore"))

    def span(self, node):
        return self.at(node.lineno, node.col_offset), self.at(node.end_lineno, node.end_col_offset)


def _docstring_nodes(tree):
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
                out.add(id(first.value))
    return out


def _gap_token(text, a, b, token):
    """Offset of ``token`` in text[a:b] outside comments (the operator between two operands)."""
    gap = text[a:b]
    i = 0
    while i < len(gap):
        if gap[i] == "#":
            j = gap.find("\n", i)
            i = len(gap) if j < 0 else j
            continue
        if gap.startswith(token, i):
            # whole-token match: "<" must not be the start of "<=", "*" of "**", "/" of "//"
            nxt = gap[i + len(token):i + len(token) + 1]
            prv = gap[i - 1:i] if i else ""
            if token in ("<", ">") and nxt == "=":
                i += 1
                continue
            if token in ("*", "/") and (nxt == token or prv == token):
                i += 1
                continue
            if token in ("and", "or", "is", "in", "not") and ((nxt.isalnum() or nxt == "_") or (prv.isalnum() or prv == "_")):
                i += 1
                continue
            return a + i
        i += 1
    return None


def generate(relfile: str, text: str | None = None, check: bool = True) -> list[GenMutant]:
    """The operator mutants of ``ldaspark/relfile`` (or a verification helper
    ``verification/NAME.py``; module docstring), in source order.
    ``check=False``: without compiling each (~20 ms a mutant); ids do not depend on it (the
    running number counts every splice, compiling or not)."""
    path = source_path(relfile)
    if text is None:
        if not path.is_file():
            raise MutgenError(f"no module {label(relfile)}")
        text = path.read_text()
    try:
        tree = ast.parse(text)
    except SyntaxError as exc:
        raise MutgenError(f"{label(relfile)} does not parse: {exc}") from None
    off = _Offsets(text)
    docs = _docstring_nodes(tree)
    out: list[GenMutant] = []
    counts: dict = {}

    def add(scope, line, start, end, repl, what):
        orig = text[start:end]
        key = (scope, what, orig, repl)
        counts[key] = counts.get(key, 0) + 1
        mid = f"{relfile}::{scope}::{what}::{orig.strip()}->{repl.strip()}#{counts[key]}"
        out.append(GenMutant(mid, relfile, line, start, end, orig, repl, f"line {line}: {what} {orig.strip()!r} -> {repl.strip()!r}"))

    def skip_main(node):
        t = node.test
        return (isinstance(t, ast.Compare) and isinstance(t.left, ast.Name) and t.left.id == "__name__")

    def visit(node, scope):
        if isinstance(node, ast.If) and skip_main(node):
            return
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            scope = node.name if scope == "<module>" else f"{scope}.{node.name}"
            # decorators and defaults belong to the enclosing scope, but keep it simple: the body
        handle(node, scope)
        for child in ast.iter_child_nodes(node):
            visit(child, scope)

    def handle(node, scope):
        if isinstance(node, ast.Compare):
            prev = node.left
            for op, right in zip(node.ops, node.comparators):
                a, b = off.span(prev)[1], off.span(right)[0]
                if type(op) in CMP_SWAP:
                    for tok, rep in CMP_SWAP[type(op)]:
                        i = _gap_token(text, a, b, tok)
                        if i is not None:
                            add(scope, node.lineno, i, i + len(tok), rep, "compare")
                elif isinstance(op, (ast.Is, ast.IsNot)):
                    i = _gap_token(text, a, b, "is")
                    if i is not None:
                        if isinstance(op, ast.Is):
                            add(scope, node.lineno, i, i + 2, "is not", "compare")
                        else:
                            j = _gap_token(text, i + 2, b, "not")
                            if j is not None:
                                add(scope, node.lineno, i, j + 3, "is", "compare")
                elif isinstance(op, (ast.In, ast.NotIn)):
                    if isinstance(op, ast.In):
                        i = _gap_token(text, a, b, "in")
                        if i is not None:
                            add(scope, node.lineno, i, i + 2, "not in", "compare")
                    else:
                        i = _gap_token(text, a, b, "not")
                        j = _gap_token(text, i + 3, b, "in") if i is not None else None
                        if j is not None:
                            add(scope, node.lineno, i, j + 2, "in", "compare")
                prev = right
        elif isinstance(node, ast.BoolOp):
            tok, rep = ("and", "or") if isinstance(node.op, ast.And) else ("or", "and")
            for x, y in zip(node.values, node.values[1:]):
                i = _gap_token(text, off.span(x)[1], off.span(y)[0], tok)
                if i is not None:
                    add(scope, node.lineno, i, i + len(tok), rep, "boolean")
        elif isinstance(node, ast.BinOp) and type(node.op) in BIN_SWAP:
            tok, rep = BIN_SWAP[type(node.op)]
            i = _gap_token(text, off.span(node.left)[1], off.span(node.right)[0], tok)
            if i is not None:
                add(scope, node.lineno, i, i + len(tok), rep, "arithmetic")
        elif isinstance(node, ast.AugAssign) and type(node.op) in BIN_SWAP:
            tok, rep = BIN_SWAP[type(node.op)]
            i = _gap_token(text, off.span(node.target)[1], off.span(node.value)[0], tok + "=")
            if i is not None:
                add(scope, node.lineno, i, i + len(tok) + 1, rep + "=", "arithmetic")
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.Not, ast.USub)):
            s, _ = off.span(node)
            e = off.span(node.operand)[0]
            add(scope, node.lineno, s, e, "", "not-removal" if isinstance(node.op, ast.Not) else "negation-removal")
        elif isinstance(node, ast.Constant) and id(node) not in docs:
            v = node.value
            s, e = off.span(node)
            if isinstance(v, bool):
                add(scope, node.lineno, s, e, str(not v), "constant")
            elif isinstance(v, int):
                src = text[s:e]
                add(scope, node.lineno, s, e, f"({src} + 1)", "constant")
                add(scope, node.lineno, s, e, "0" if v != 0 else f"({src} - 1)", "constant")
            elif isinstance(v, float):
                # one per float: tolerances and factors are rarely off by one, but 0 disables them
                add(scope, node.lineno, s, e, "0.0" if v != 0 else "1.0", "constant")
        elif isinstance(node, ast.Return) and node.value is not None:
            if not (isinstance(node.value, ast.Constant) and node.value.value is None):
                s, e = off.span(node.value)
                add(scope, node.lineno, s, e, "None", "return")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in NAME_SWAP:
            s, e = off.span(node.func)
            add(scope, node.lineno, s, e, NAME_SWAP[node.func.id], "call-swap")
        elif isinstance(node, ast.Slice):
            for bound in (node.lower, node.upper):
                if bound is not None:
                    s, e = off.span(bound)
                    add(scope, node.lineno if hasattr(node, "lineno") else bound.lineno, s, e,
                        f"({text[s:e]}) + 1", "slice")

    visit(tree, "<module>")
    if not check:
        return out
    # a splice that does not compile (e.g. "not" removed from "not in" by accident) is dropped
    good = []
    for m in out:
        try:
            compile(m.mutated_source(text), m.file, "exec")
        except SyntaxError:
            continue
        good.append(m)
    return good


def definition_time_lines(rel: str) -> set:
    """Lines evaluated when the module is imported rather than when a function runs: module-level
    statements outside functions, class bodies, decorators, default values and annotations of
    ``def``. A test that imports the module inside its body records them in its context, but a
    test that calls the function does not run them again: their mutants are decided by the files
    that import the module, run whole."""
    tree = ast.parse(source_path(rel).read_text())
    out = set()

    def span(node):
        out.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))

    def walk(body):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for d in node.decorator_list:
                    span(d)
                a = node.args
                for d in [*a.defaults, *(x for x in a.kw_defaults if x is not None)]:
                    span(d)
                for x in [*a.posonlyargs, *a.args, *a.kwonlyargs, a.vararg, a.kwarg]:
                    if x is not None and x.annotation is not None:
                        span(x.annotation)
                if node.returns is not None:
                    span(node.returns)
            elif isinstance(node, ast.ClassDef):
                for d in node.decorator_list:
                    span(d)
                walk(node.body)
            else:
                span(node)
    walk(tree.body)
    return out


#: decorators under which numba compiles a function from its bytecode (the library's own
#: ``cache.model_jit`` as ``_jit`` too): coverage.py never sees the body's lines run
_JIT_NAME = re.compile(r"^(numba\.)?(njit|jit|cfunc|vectorize|guvectorize)$|^(_jit|model_jit)$")


def compiled_body_lines(rel: str) -> set:
    """Lines of the bodies of numba-compiled functions: they run as machine code, so coverage
    records no test's context for them and the map alone would call every mutant there "not
    covered" (every kernel mutant of ``compiled/kernels*.py``: probe t24, stop 65)."""
    out = set()
    for node in ast.walk(ast.parse(source_path(rel).read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and any(
                _JIT_NAME.match(ast.unparse(d.func if isinstance(d, ast.Call) else d)) for d in node.decorator_list):
            for st in node.body:
                out.update(range(st.lineno, (st.end_lineno or st.lineno) + 1))
    return out


def statement_lines(rel: str) -> dict:
    """{line: the first line of the innermost statement containing it}: coverage.py records a
    statement that spans lines at its first line only, so a mutant on a continuation line is
    looked up there."""
    out = {}
    for node in ast.walk(ast.parse(source_path(rel).read_text())):   # parents before children
        if isinstance(node, ast.stmt):
            for ln in range(node.lineno, (node.end_lineno or node.lineno) + 1):
                out[ln] = node.lineno
    return out


def label(rel: str) -> str:
    """The project-relative path of a module to mutate: ``ldaspark/REL`` or ``verification/NAME.py``."""
    return rel if rel.startswith(HELPERS_DIR + "/") else f"ldaspark/{rel}"


def source_path(rel: str) -> pathlib.Path:
    return PROJECT / label(rel)


def module_file(name: str) -> str:
    """'ldaspark/core/validate.py', 'core/validate.py' or 'ldaspark.core.validate' -> 'core/validate.py';
    a verification helper (not a test file) as 'verification/strategies.py' stays so. The path is
    resolved (links and '..' included) and must stay inside the package (or verification/) and be
    a regular file there: 'ldaspark/../../x.py' is refused."""
    if not isinstance(name, str) or not name.strip() or len(name) > 500 or "\0" in name:
        raise MutgenError(f"--generated: {str(name)[:80]!r} is not a module name")
    n = name.strip()
    hp = pathlib.Path(n)
    if n.endswith(".py") and len(hp.parts) == 2 and hp.parts[0] == HELPERS_DIR:
        if hp.name.startswith("test_") or hp.name == "conftest.py" or not _inside(PROJECT / HELPERS_DIR, PROJECT / hp):
            raise MutgenError(f"no verification helper {n} (test files and conftest.py are not mutated)")
        return str(hp)
    if n.endswith(".py"):
        p = pathlib.Path(n)
        if p.is_absolute() or ".." in p.parts:
            raise MutgenError(f"--generated: {n[:120]} is not a module of the ldaspark package (a path inside it, "
                              "without '..', or a dotted name)")
        parts = p.parts[1:] if p.parts and p.parts[0] == "ldaspark" else p.parts
        if not parts:
            raise MutgenError(f"--generated: {n[:120]} is not a module name")
        rel = str(pathlib.Path(*parts))
    else:
        parts = n.split(".")
        if not all(x.isidentifier() for x in parts):
            raise MutgenError(f"--generated: {n[:120]} is not a dotted module name")
        parts = parts[1:] if parts[0] == "ldaspark" else parts
        if not parts:
            raise MutgenError(f"--generated: {n[:120]} is the package, not a module")
        rel = "/".join(parts) + ".py"
    if not _inside(PACKAGE, PACKAGE / rel):
        raise MutgenError(f"no module ldaspark/{rel[:120]} (a regular file inside the package)")
    return rel


def _inside(root: pathlib.Path, path: pathlib.Path) -> bool:
    """``path``, resolved, is a regular file under ``root`` resolved."""
    import os
    import stat
    try:
        real = path.resolve()
        real.relative_to(root.resolve())
        return stat.S_ISREG(os.stat(real).st_mode)
    except (ValueError, OSError, RuntimeError):
        return False


# --- equivalents ---------------------------------------------------------------------------------
def load_equivalent(path=EQUIVALENT) -> dict:
    """{mutant id: why it is equivalent} (``records.read_equivalent``: a regular file, bounded)."""
    try:
        return read_equivalent(path)
    except RecordError as exc:
        raise MutgenError(str(exc)) from None


# --- coverage: which tests execute which lines ----------------------------------------------------
_COV_DRIVER = r'''
import os, sys, json, coverage, pytest


class Ctx:
    def __init__(self, cov):
        self.cov, self.dur, self.bad = cov, {}, {}

    def pytest_runtest_setup(self, item):
        self.cov.switch_context(item.nodeid)

    def pytest_runtest_teardown(self, item):
        self.cov.switch_context("")

    def pytest_runtest_logreport(self, report):
        self.dur[report.nodeid] = self.dur.get(report.nodeid, 0.0) + report.duration
        if report.failed:
            self.bad[report.nodeid] = report.when


# guarded: a test that starts processes by spawn (a Dask LocalCluster) imports this script again
if __name__ == "__main__":
    data, sources, *files = sys.argv[1:]
    cov = coverage.Coverage(data_file=data, source=sources.split(","), branch=True)
    ctx = Ctx(cov)
    cov.start()
    rc = pytest.main(["-q", "-p", "no:cacheprovider", *files], plugins=[ctx])
    cov.stop()
    cov.save()
    # written whole then renamed: the parent reads it, and a killed run must leave none or all of it
    with open(data + ".durations.json.part", "w") as fh:
        json.dump({"durations": ctx.dur, "failed": ctx.bad}, fh)
    os.replace(data + ".durations.json.part", data + ".durations.json")
    sys.exit(int(rc))
'''


def _source_text(path) -> str:
    """A test file's text ('' unless a regular file within the reader's bound: a FIFO named
    test_x.py is never opened)."""
    try:
        return read_bytes(path, "a test file", MAX_SOURCE_BYTES).decode("utf-8", "ignore")
    except RecordError:
        return ""


def mapped_tests(relfile: str, project=PROJECT) -> list[str]:
    """Test files that import the module (by its dotted name or a relative import of it; a
    verification helper by its bare name, as the tests beside it import it)."""
    out = []
    if relfile.startswith(HELPERS_DIR + "/"):
        name = pathlib.Path(relfile).stem
        pats = (f"from {name} import", f"import {name}", f"{HELPERS_DIR}.{name}")
        for f in all_test_files(project):
            src = _source_text(pathlib.Path(project) / f)
            if any(p in src for p in pats):
                out.append(f)
        return out + [f for f in ALWAYS_MAPPED if (pathlib.Path(project) / f).is_file() and f not in out]
    dotted = "ldaspark." + relfile[:-3].replace("/", ".")
    mod = dotted.rsplit(".", 1)
    pats = (dotted, f"from {mod[0]} import {mod[1]}", f"import {mod[1]}")
    for f in all_test_files(project):
        src = _source_text(pathlib.Path(project) / f)
        if any(p in src for p in pats[:2]) or (pats[2] in src and mod[0] in src):
            out.append(f)
    if (pathlib.Path(project) / label(relfile)).is_file() and compiled_body_lines(relfile):
        # numba-compiled code is exercised through the layer's public paths, which the files
        # importing this module need not be: the tests of the layer (tests mirror the modules)
        layer = "tests/" + relfile.split("/", 1)[0] + "/"
        out += [f for f in all_test_files(project) if f.startswith(layer) and f not in out]
    for f in ALWAYS_MAPPED:
        if (pathlib.Path(project) / f).is_file() and f not in out:
            out.append(f)
    return out


def _shards(test_files, n):
    """``test_files`` in ``n`` groups of about equal size in bytes (a proxy for their time)."""
    groups, load = [[] for _ in range(max(1, n))], [0] * max(1, n)
    for f in sorted(test_files, key=lambda f: (-(PROJECT / f).stat().st_size if (PROJECT / f).is_file() else 0, f)):
        i = load.index(min(load))
        groups[i].append(f)
        load[i] += (PROJECT / f).stat().st_size if (PROJECT / f).is_file() else 0
    return [g for g in groups if g]


def _combined_rc(rcs):
    """pytest's exit status of the shards as one: an error beats a test failure beats success;
    'no tests collected' (5) only when every shard says so."""
    bad = [r for r in rcs if r not in (0, 1, 5)]
    if bad:
        return bad[0]
    if 1 in rcs:
        return 1
    return 5 if rcs and all(r == 5 for r in rcs) else 0


def coverage_map(files: list[str], test_files: list[str], datafile, timeout=3600, reuse=False, jobs=1):
    """Run ``test_files`` under coverage with per-test contexts, in ``jobs`` processes (each a
    share of the files; their data combined); returns
    ({relfile: {line: [node ids]}}, {relfile: (lines covered, lines, branches covered, branches)},
    pytest's return code, seconds, the tail of pytest's output)."""
    try:
        import coverage  # noqa: F401
    except ImportError:
        raise MutgenError("per-mutant test selection needs coverage (pip install coverage)") from None
    import os
    t = time.time()
    rc, tail = 0, ""
    sources = [str(PACKAGE)] + ([str(PROJECT / HELPERS_DIR)] if any(f.startswith(HELPERS_DIR + "/") for f in files) else [])
    if not reuse:
        from coverage import CoverageData
        with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as fh:
            fh.write(_COV_DRIVER)
            driver = fh.name
        env = dict(os.environ, PYTHONPATH=str(PROJECT))
        shards = _shards(test_files, jobs)
        parts = [f"{datafile}.shard{i}" for i in range(len(shards))]
        procs, outs = [], []
        try:
            for part, group in zip(parts, shards):
                out = tempfile.TemporaryFile("w+")
                outs.append(out)
                procs.append(subprocess.Popen([sys.executable, driver, part, ",".join(sources), *group], cwd=PROJECT,
                                              env=env, stdout=out, stderr=subprocess.STDOUT, text=True))
            rcs = []
            for pr in procs:
                try:
                    rcs.append(pr.wait(timeout=max(1.0, timeout - (time.time() - t))))
                except subprocess.TimeoutExpired:
                    for q in procs:
                        q.kill()
                    raise MutgenError(f"the coverage run of the mapped tests took over {timeout} s") from None
            rc = _combined_rc(rcs)
            for out in outs:
                out.seek(0)
                tail += out.read()[-3000:]
            # one data file (contexts kept) and one durations file, as one process would write them
            if pathlib.Path(datafile).exists():
                pathlib.Path(datafile).unlink()
            whole = CoverageData(basename=str(datafile))
            runinfo = {"durations": {}, "failed": {}}
            for part in parts:
                if pathlib.Path(part).is_file():
                    d = CoverageData(basename=part)
                    d.read()
                    whole.update(d)
                dpath = pathlib.Path(part + ".durations.json")
                if dpath.is_file():
                    info = json.loads(dpath.read_text())
                    for k in runinfo:
                        runinfo[k].update(info.get(k, {}))
            whole.write()
            atomic_write_json(pathlib.Path(str(datafile) + ".durations.json"), runinfo)
        finally:
            os.remove(driver)
            for pr in procs:
                if pr.poll() is None:
                    pr.kill()
                    pr.wait()
            for out in outs:
                out.close()
            for part in parts:
                for q in (pathlib.Path(part), pathlib.Path(part + ".durations.json")):
                    if q.is_file():
                        q.unlink()
    import coverage
    cov = coverage.Coverage(data_file=str(datafile))
    cov.load()
    data = cov.get_data()
    out, stats = {}, {}
    for rel in files:
        fn = str(source_path(rel))
        by = data.contexts_by_lineno(fn) if fn in data.measured_files() else {}
        out[rel] = {int(k): sorted(c for c in v if c) for k, v in by.items()}
        try:
            an = cov._analyze(fn)            # coverage's own numbers: statements and branches
            nums = an.numbers
            stats[rel] = (nums.n_statements - nums.n_missing, nums.n_statements,
                          nums.n_branches - nums.n_missing_branches, nums.n_branches)
        except Exception:                    # noqa: BLE001 - not measured
            stats[rel] = (0, 0, 0, 0)
    return out, stats, rc, time.time() - t, tail


def coverage_key(files, tests) -> str:
    import hashlib
    h = hashlib.sha256()
    for rel in sorted(files):
        h.update(rel.encode() + b"\0" + source_path(rel).read_bytes())
    for t in sorted(tests):
        h.update(t.encode() + b"\0" + (PROJECT / t).read_bytes())
    return h.hexdigest()


def _file_costs(durations) -> dict:
    """{test file: the sum of its tests' durations in the coverage run}."""
    out = {}
    for k, v in durations.items():
        f = k.split("::")[0]
        out[f] = out.get(f, 0.0) + v
    return out


def _order_tests(ids, durations=None, file_costs=None):
    """The covering tests, fastest first (their durations in the coverage run; a whole test file
    by the sum of its tests'): a killed mutant stops at its first failure, so the cheap tests
    decide most of them."""
    d = durations or {}
    fc = file_costs if file_costs is not None else _file_costs(d)
    return sorted(ids, key=lambda i: (d.get(i, fc.get(i, 1e9) if "::" not in i else 1e9), i))


# --- running ---------------------------------------------------------------------------------------
def run_generated(args) -> int:
    require_tests()
    files = [module_file(m) for m in args.generated]
    if not files:
        raise MutgenError("--generated: no module given")
    t0 = time.time()
    equivalent = load_equivalent()
    mutants = [m for f in files for m in generate(f)]
    # every file argument and selection is read and checked before any work starts
    tests = _selected_tests(args, files)
    only = _only_ids(args, mutants)
    kinds = _kinds(args)
    keep = _keep_files(args)
    earlier = [read_previous(k) for k in keep]
    if only is not None and earlier and not earlier[0].trusted:
        raise MutgenError(f"--only with --keep-killed {keep[0][:200]} updates that report in place, but it is not "
                          "signed with this user's key (written elsewhere, edited or forged): its records cannot be "
                          "kept; run without --only to rerun its kills against their named tests")
    outdir = make_outdir(args.outdir)
    print(f"[mutgen] {len(mutants)} mutants in {len(files)} modules; coverage of {len(tests)} test files ...",
          flush=True)
    # the coverage map is reused while the modules under test and the mapped test files are
    # unchanged (it is the run's most expensive single step; lines elsewhere do not move)
    key = coverage_key(files, tests)
    cfile, kfile = outdir / ".mutgen.coverage", outdir / ".mutgen.coverage.key"
    if cfile.is_file() and _small_text(kfile).strip() == key:
        cmap, cstats, rc, csec, tail = coverage_map(files, tests, cfile, reuse=True)
    else:
        cmap, cstats, rc, csec, tail = coverage_map(files, tests, cfile, jobs=max(1, int(args.jobs or 1)))
    dpath = pathlib.Path(str(cfile) + ".durations.json")
    runinfo = read_json(dpath, "the coverage run's durations") if dpath.is_file() else {}
    durations, failed = (runinfo.get("durations", {}), runinfo.get("failed", {})) if isinstance(runinfo, dict) else ({}, {})
    if not isinstance(durations, dict) or not isinstance(failed, dict):
        raise MutgenError(f"{dpath}: not the durations a coverage run writes")
    if rc not in (0, 1, 5) or (rc == 1 and not failed):
        last = tail.strip().splitlines()[-1] if tail.strip() else ""
        raise MutgenError(f"the mapped tests could not run on the unmutated package (pytest exit {rc}): {last}")
    if failed:
        # a test that fails (or errors) without any mutant cannot tell a mutant: left out
        print(f"[mutgen] {len(failed)} mapped tests fail on the unmutated package and are not used: "
              + ", ".join(sorted(failed)[:5]) + (" ..." if len(failed) > 5 else ""), flush=True)
    if rc in (0, 1):
        kfile.write_text(key + "\n")
    print(f"[mutgen] coverage map in {csec:.0f} s", flush=True)
    if getattr(args, "coverage_only", False) or getattr(args, "tests", None) == SUITE:
        # the default suite's coverage of the checking code, beside the mutants' report
        write_coverage_report(files, cfile, outdir, tests, failed, csec,
                              "ldaspark mutants --coverage-only --generated " + " ".join(args.generated)
                              + _tests_flag(args) + f" --jobs {args.jobs}")
        print(f"[mutgen] coverage of {len(files)} modules -> {outdir}/coverage-checking.md")
    if getattr(args, "coverage_only", False):
        return 0
    todo, recs_fixed, targets, deftime, stmts, jitted, importers = [], {}, {}, {}, {}, {}, {}
    fcost = _file_costs(durations)
    for m in mutants:
        if m.id in equivalent:
            recs_fixed[m.id] = _rec(m, "equivalent", None, 0.0, equivalent[m.id])
            continue
        if m.file not in deftime:
            deftime[m.file] = definition_time_lines(m.file)
            stmts[m.file] = statement_lines(m.file)
            jitted[m.file] = compiled_body_lines(m.file)
        line = m.line if m.line in cmap.get(m.file, {}) else stmts[m.file].get(m.line, m.line)
        ids = [i for i in cmap.get(m.file, {}).get(line, []) if i not in failed]
        module_level = m.id.split("::")[1] == "<module>"
        at_import = line in cmap.get(m.file, {}) and (not ids or m.line in deftime[m.file])
        if m.line in jitted[m.file]:
            # compiled by numba: no context can name a test; the mapped files decide, run whole
            at_import = True
        if at_import:
            # evaluated at import: a module constant, a default value, a decorator. The contexts
            # name only a test that happened to import the module first; the mapped test files
            # that import it decide it, run whole (after the tests of the contexts)
            if m.file not in importers:
                importers[m.file] = mapped_tests(m.file)
            ids = ids + [f for f in importers[m.file] if f in tests and f not in ALWAYS_MAPPED and f not in ids]
        if not ids:
            recs_fixed[m.id] = _rec(m, "not-covered", None, 0.0)
            continue
        targets[m.id] = _order_tests(ids, durations, fcost)
        if module_level or at_import:
            # a module constant runs at import (collection), in no test's context: the tests that
            # read it are not in the map, so the kill files run whole too, after the module's own
            # test files (those importing it: the likeliest to read the constant; with the ~50
            # kill files first, a constant their tests do not read ran into the timeout before
            # its own test was reached). The verdict is that of the whole list either way
            targets[m.id] = targets[m.id] + [f for f in ALWAYS_MAPPED if (PROJECT / f).is_file()
                                             and f not in targets[m.id]]
        if getattr(args, "keep_killed", None):
            # a rerun after kills were written: the kill files run whole (tests newer than the
            # coverage map are not in it; they are written for these survivors), after the
            # mutant's covering tests (pytest -x stops at the first failure: the same verdict,
            # without ~50 files ahead of a test that kills in a second)
            targets[m.id] = targets[m.id] + [f for f in ALWAYS_MAPPED if (PROJECT / f).is_file() and f not in tests
                                             and f not in targets[m.id]]
        # the bookkeeping tests (do the listed ids still exist?) fail on any mutant that touches
        # a listed site: a verdict on the lists, not on the mutant
        targets[m.id] += [f"--deselect={t}" for t in BOOKKEEPING]
        todo.append(m)
    covered = {m.id for m in todo}
    if kinds is not None:
        # one kind of fault across many modules (all <-> any, min <-> max: the one-sided verdicts)
        todo = [m for m in todo if mutant_kind(m.id) in kinds]
    if getattr(args, "sample", None):
        # drawn from every generated mutant (not only the covered ones): the same sample whatever
        # the tests, so runs against other test sets or after new tests extend one another
        picked = {m.id for m in sample([m for m in mutants if m.id not in equivalent], files, args.sample)}
        todo = [m for m in todo if m.id in picked]
    if earlier:
        # adding tests cannot revive a killed mutant while its killing test is still there:
        # reuse those records (of any covered mutant, in the sample or not: an earlier run's
        # kills stay in the report), run the rest (the survivors and the mutants not yet run).
        # Only a record its writer signed is a verdict (records.read_previous); a kill in an
        # unsigned or forged file is a hint: the mutant runs again, its named test first
        seen_tests: dict = {}
        for prev in earlier:
            for r in prev.records:
                test = r.get("first_failing_test")
                if r.get("status") != "killed" or r["mutant"] not in covered or r["mutant"] in recs_fixed \
                        or not names_existing_test(test, PROJECT, seen_tests):
                    continue
                if prev.trusted:
                    recs_fixed[r["mutant"]] = dict(r, previous_run=True)
                elif r["mutant"] in targets and test not in targets[r["mutant"]]:
                    targets[r["mutant"]] = [test] + targets[r["mutant"]]
        if only is not None:
            # an update of the earlier report (signed: checked above): the listed mutants run
            # again, every other mutant keeps its earlier record (whatever its status), so the
            # report stays whole (over this run's verdict of "not covered" too: a narrower
            # --tests must not erase them)
            for r in earlier[0].records:
                mine = recs_fixed.get(r["mutant"])
                if r["mutant"] not in only and r.get("status") != "equivalent" \
                        and (mine is None or mine["status"] != "equivalent"):
                    recs_fixed[r["mutant"]] = dict(r, previous_run=True)
        todo = [m for m in todo if m.id not in recs_fixed]
    if only is not None:
        todo = [m for m in todo if m.id in only]
    if getattr(args, "limit", None):
        todo = todo[:args.limit]
    ck = Checkpoint(outdir / "mutation-generated.partial.jsonl",
                    verdict_fingerprint("mutants-generated", files, tests, getattr(args, "tests", None)))
    if getattr(args, "fresh", False):
        ck.discard()

    def progress(r):
        print(f"{r['status']:9s} {r['seconds']:6.1f}s  {r['mutant']}  {r['first_failing_test'] or ''}", flush=True)
    timeout = getattr(args, "mutant_timeout", None) or min(TIMEOUT, 300)
    try:
        recs = run_catalogue(todo, args.jobs, progress=progress, where=getattr(args, "scheduler", None),
                             checkpoint=ck, targets=targets, timeout=timeout)
    except UnitsFailed as exc:
        raise UnitsFailed(exc.failed, exc.results, kept=ck.path) from None
    ran = {r["mutant"]: r for r in recs}
    keep_order = {m.id for m in mutants}
    ran.update({k: v for k, v in recs_fixed.items() if k in keep_order and k not in ran})
    allrecs = []
    for m in mutants:
        r = ran.get(m.id)
        if r is None:               # left out by --sample / --limit
            r = _rec(m, "not-run", None, 0.0)
        r = dict(r)
        r.update(line=m.line, original=m.original, replacement=m.replacement)
        allrecs.append(r)
    cmd = "ldaspark mutants --generated " + " ".join(args.generated) + _tests_flag(args) + f" --jobs {args.jobs}"
    if getattr(args, "sample", None):
        cmd += f" --sample {args.sample}"
    if getattr(args, "kinds", None):
        cmd += f" --kinds {args.kinds}"
    if only is not None:
        cmd += f" --only <{len(only)} ids>"
    if getattr(args, "keep_killed", None):
        cmd += f" --keep-killed {args.keep_killed}"
    # the history (earlier runs' commands) is that of the first report among them (a checkpoint
    # of an interrupted run has none: it contributes its records only)
    history = _previous_runs(next((e.doc for e in earlier if e.doc is not None), None)) if earlier else {}
    if history.get("modules_not_run"):
        # a module this run mutates is no longer "not yet run"
        names = {pathlib.Path(f).name for f in files}
        history["modules_not_run"] = [x for x in history["modules_not_run"] if not any(n in x for n in names)]
    if only is not None and getattr(args, "tests", None) and args.tests != SUITE:
        # an update with a narrower --tests: its coverage is of those files only; the report keeps
        # the coverage measured by the earlier runs' mapped tests
        cstats = dict(cstats, **{f: c for f, c in history.get("coverage", {}).items() if f in cstats})
    write_reports(allrecs, files, cstats, outdir, cmd, time.time() - t0, tests, history)
    ck.discard()
    surv = [r for r in allrecs if r["status"] in ("survived", "timeout")]
    print(f"[mutgen] {sum(r['status'] == 'killed' for r in allrecs)} killed, {len(surv)} surviving, "
          f"{sum(r['status'] == 'equivalent' for r in allrecs)} equivalent -> {outdir}/mutation-generated.md")
    return 0 if not surv else 1


def _tests_flag(args) -> str:
    t = getattr(args, "tests", None)
    return f" --tests {t}" if t else ""


def _arc_text(arcs) -> str:
    """Missed branch arcs {line: [destinations]} as 'L->D' (D < 0: the exit of the function)."""
    out = []
    for a in sorted(arcs):
        out += [f"{a}->{'exit' if d < 0 else d}" for d in sorted(arcs[a])]
    return ", ".join(out)


def write_coverage_report(files, datafile, outdir, tests, failed, seconds, command):
    """coverage-checking.md / .json: statements and branches per module over ``tests`` (with
    ``--tests suite``: the default suite), and the branch arcs no test takes."""
    import coverage
    cov = coverage.Coverage(data_file=str(datafile))
    cov.load()
    every = all_test_files(PROJECT)
    suite = sorted(tests) == sorted(every)
    within = not suite and set(tests) <= set(every)
    which = "the default suite (`pytest`, every file under tests/ and verification/)" if suite else \
        f"{len(tests)} of the default suite's {len(every)} test files" if within else f"{len(tests)} test files"
    mods = {}
    for rel in files:
        fn = str(source_path(rel))
        try:
            an = cov._analyze(fn)
        except Exception:                    # noqa: BLE001 - not measured: nothing covered
            mods[label(rel)] = {"lines": [0, None], "branches": [0, None], "missed_branches": "not measured"}
            continue
        n = an.numbers
        mods[label(rel)] = {"lines": [n.n_statements - n.n_missing, n.n_statements],
                            "branches": [n.n_branches - n.n_missing_branches, n.n_branches],
                            "missed_branches": _arc_text(an.missing_branch_arcs()),
                            "missed_lines": an.missing_formatted()}
    doc = {"command": command, "seconds": round(seconds, 1), "tests": "default suite" if suite else tests,
           "tests_failing_unmutated": sorted(failed), "modules": mods}
    atomic_write_json(pathlib.Path(outdir) / "coverage-checking.json", doc)
    pct = lambda a, b: f"{100 * a / b:.0f}% ({a}/{b})" if b else "-"  # noqa: E731
    lines = ["# Coverage of the checking code", "",
             f"Statements and branches of each module executed by "
             f"{which}"
             f", measured by coverage.py {coverage.__version__} with branch coverage. Reproduce: `{command}` "
             f"({seconds / 60:.1f} min).", "",
             "| module | lines | branches | branch arcs no test takes |", "|---|---|---|---|"]
    for f, c in mods.items():
        miss = c["missed_branches"].replace("|", "\\|") or "none"
        lines.append(f"| {f} | {pct(*c['lines']) if c['lines'][1] else '-'} | "
                     f"{pct(*c['branches']) if c['branches'][1] else '-'} | {miss} |")
    if failed:
        lines += ["", f"Tests failing on the unmutated code (left out): {', '.join(sorted(failed))}"]
    atomic_write_text(pathlib.Path(outdir) / "coverage-checking.md", "\n".join(lines) + "\n")


def _only_ids(args, mutants):
    """The set of ``--only`` ids (comma-separated, or @FILE with one id per line) for a generated
    run, None without ``--only``; an id that is not generated is an error (a typo would run
    nothing and look like success), and so is an empty selection ('--only ,', an empty file)."""
    spec = getattr(args, "only", None)
    if spec is None:
        return None
    if not isinstance(spec, str):
        raise MutgenError("--only: a comma-separated list of ids or @FILE")
    if spec.startswith("@"):
        ids = read_id_list(spec[1:])
    else:
        ids = [x.strip() for x in spec.split(",") if x.strip()]
    if not ids:
        raise MutgenError(f"--only {spec[:80]!r} selects no mutant (give ids, comma-separated, or @FILE with one a line)")
    known = {m.id for m in mutants}
    unknown = [x for x in ids if x not in known]
    if unknown:
        raise MutgenError(f"--only: {len(unknown)} ids are not generated from these modules, e.g. {unknown[0][:200]}")
    return set(ids)


#: the operator kinds ``generate`` makes (``--kinds``)
KINDS = ("call-swap", "compare", "boolean", "not-removal", "negation-removal", "arithmetic", "constant", "return",
         "slice")


def _kinds(args):
    """The ``--kinds`` set, None without it; empty or unknown kinds refused (they would run nothing)."""
    spec = getattr(args, "kinds", None)
    if spec is None:
        return None
    kinds = {k.strip() for k in str(spec).split(",") if k.strip()}
    if not kinds or not kinds <= set(KINDS):
        bad = sorted(kinds - set(KINDS))
        raise MutgenError(f"--kinds {str(spec)[:80]!r}: " + (f"unknown kind {bad[0][:40]!r}; " if bad else "no kind; ")
                          + f"one or more of {', '.join(KINDS)}")
    return kinds


def _keep_files(args) -> list[str]:
    """The ``--keep-killed`` files; an empty list ('--keep-killed ,') refused."""
    spec = getattr(args, "keep_killed", None)
    if spec is None:
        return []
    keep = [x.strip() for x in str(spec).split(",") if x.strip()]
    if not keep:
        raise MutgenError(f"--keep-killed {str(spec)[:80]!r} names no file")
    return keep


def _selected_tests(args, files) -> list[str]:
    """The test files mapped by coverage: ``--tests`` (each a regular test_*.py under tests/ or
    verification/ of this project; 'suite': every default test file) or those importing the
    modules; an empty selection refused."""
    spec = getattr(args, "tests", None)
    if spec == SUITE:
        return all_test_files(PROJECT)
    if spec is None:
        return sorted({t for f in files for t in mapped_tests(f)})
    tests = [x.strip() for x in str(spec).split(",") if x.strip()]
    if not tests:
        raise MutgenError(f"--tests {str(spec)[:80]!r} names no test file")
    bad = [t for t in tests if "::" in t or not names_existing_test(t, PROJECT)]
    if bad:
        raise MutgenError(f"--tests: {bad[0][:200]} is not a test file of this project (tests/test_*.py or "
                          "verification/test_*.py, a regular file)")
    return tests


def make_outdir(path) -> pathlib.Path:
    """``--outdir``, created if needed; a path that is not a directory refused in one line."""
    out = pathlib.Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise MutgenError(f"--outdir {str(path)[:200]}: cannot be created ({exc.strerror or exc})") from None
    if not out.is_dir():
        raise MutgenError(f"--outdir {str(path)[:200]}: not a directory")
    return out


def _small_text(path) -> str:
    """A small file of this tool's own (the coverage map's key): '' when absent or not a regular file."""
    try:
        return read_text(path, "the coverage key", 4096)
    except RecordError:
        return ""


def _previous_runs(doc) -> dict:
    """The run history (``runs``) and ``modules_not_run`` of an earlier report (its ``doc`` as
    ``records.read_previous`` read it, or a path), carried into an update of it (empty for a
    checkpoint or None)."""
    if doc is None or str(doc).endswith(".jsonl"):
        return {}
    if not isinstance(doc, dict):
        doc = read_previous(doc).doc
    runs = doc.get("runs")
    if not isinstance(runs, list):     # a report of one run: its own command is its history
        runs = [{k: doc[k] for k in ("command", "seconds", "test_files_mapped") if k in doc}] if "command" in doc else []
    nr = doc.get("modules_not_run")
    cov = {}
    for f, c in (doc.get("modules") or {}).items():
        lines, branches = (c.get("coverage") or {}).get("lines"), (c.get("coverage") or {}).get("branches")
        if isinstance(f, str) and isinstance(lines, list) and isinstance(branches, list) \
                and len(lines) == len(branches) == 2:
            cov[f[len("ldaspark/"):] if f.startswith("ldaspark/") else f] = (*lines, *branches)
    return {"runs": runs, "modules_not_run": nr if isinstance(nr, list) else [], "coverage": cov}


def _previous_records(path) -> list:
    """The records of an earlier run: its mutation-generated.json, or the checkpoint
    (``*.partial.jsonl``) of an interrupted one, as the one reader gives them
    (``records.read_previous``: schema-checked; a checkpoint's records with their HMAC)."""
    return read_previous(path).records


def mutant_kind(mid: str) -> str:
    """The operator kind of a generated mutant id ('file::scope::kind::text#k')."""
    parts = mid.split("::")
    return parts[2] if len(parts) > 3 else ""


def sample(mutants, files, n):
    """A fixed sample of at most ``n`` mutants per module, evenly spaced in source order (the same
    for the same source and list of equivalents: a partial run that can be repeated and extended)."""
    out = []
    for f in files:
        ms = [m for m in mutants if m.file == f]
        if len(ms) <= n:
            out += ms
            continue
        out += [ms[(i * len(ms)) // n] for i in range(n)]
    return out


#: generated mutants that join ``ldaspark mutants --quick`` (and so ``.ci/run``), each with the one
#: test that must kill it: a fault of each kind the verdict-rule tests were written for
QUICK_GENERATED = (
    ("lab/reports/stability_stiff.py::stiff_run::arithmetic::/->*#3",
     "tests/lab/reports/test_stability_stiff_rules.py::test_the_growth_ratio_is_second_half_over_first_half"),
    ("lab/theory/audit.py::_theorem1_summary::call-swap::max->min#1", "tests/lab/theory/test_audit_rules.py::test_theorem1_summary_rule_directly"),
    ("lab/claims/claims_paper.py::section5_records::call-swap::max->min#1",
     "tests/lab/claims/test_claims_paper_rules.py::test_the_antisymmetry_record_fails_when_one_identity_fails[f_minus]"),
    ("lab/checkpoint.py::_hash_tree::compare::in->not in#1",
     "tests/ensemble/test_executors_rules.py::test_the_files_under_dirs_change_the_fingerprint"),
    ("lab/reports/systems.py::_row::call-swap::all->any#1",
     "tests/lab/reports/test_systems_rules.py::test_row_verdict_needs_both_symmetric_methods"),
    ("lab/theory/definition1.py::definition1_residuals::call-swap::max->min#5",
     "tests/lab/theory/test_definition1_rules.py::test_definition1_aggregates_the_right_neighbours"),
)


def quick_generated() -> tuple[list, dict]:
    """(mutants, {id: [test]}) of ``QUICK_GENERATED``; an id no longer generated is an error
    (the code moved: update the list)."""
    out, targets = [], {}
    for mid, test in QUICK_GENERATED:
        found = [m for m in generate(mid.split("::")[0], check=False) if m.id == mid]
        if found:
            try:
                compile(found[0].mutated_source(source_path(found[0].file).read_text()), found[0].file, "exec")
            except SyntaxError:
                found = []
        if not found:
            raise MutgenError(f"quick generated mutant {mid} is no longer generated (update QUICK_GENERATED)")
        out.append(found[0])
        targets[mid] = [test]
    return out, targets


def _rec(m, status, first, seconds, why=None):
    r = {"mutant": m.id, "file": label(m.file), "description": m.description, "category": m.category,
         "killed": status == "killed", "status": status, "first_failing_test": first, "seconds": seconds}
    if why:
        r["equivalent_because"] = why
    return r


def summarize(recs, files):
    per = {}
    for f in files:
        rs = [r for r in recs if r["file"] == label(f)]
        c = {k: sum(r["status"] == k for r in rs) for k in
             ("killed", "survived", "timeout", "invalid", "equivalent", "not-covered", "not-run")}
        c["generated"] = len(rs)
        # over the mutants run (the sample); mutants no mapped test executes are counted apart
        judged = c["killed"] + c["survived"] + c["timeout"]
        c["score"] = round(c["killed"] / judged, 4) if judged else None
        per[label(f)] = c
    return per


def write_reports(recs, files, cstats, outdir, command, seconds, tests, history=None):
    """mutation-generated.json / .md. ``history`` (an update of an earlier report): its ``runs``,
    to which this run is appended, and its ``modules_not_run``."""
    per = summarize(recs, files)
    for f, (lc, ln, bc, bn) in cstats.items():
        per[label(f)]["coverage"] = {"lines": [lc, ln], "branches": [bc, bn]}
    history = history or {}
    runs = list(history.get("runs", [])) + [{"command": command, "seconds": round(seconds, 1),
                                             "test_files_mapped": tests}]
    by = lambda *st: [r["mutant"] for r in recs if r["status"] in st]  # noqa: E731
    doc = {"tool": TOOL, "version": VERSION, "command": command, "seconds": round(seconds, 1),
           "runs": runs, "modules_not_run": history.get("modules_not_run", []),
           "equivalent": by("equivalent"), "surviving": by("survived", "timeout"),
           "not_covered": by("not-covered"), "modules": per, "test_files_mapped": tests,
           "mutants": recs}
    # signed with this user's key: a later run takes its kills as verdicts only when it verifies
    atomic_write_json(pathlib.Path(outdir) / "mutation-generated.json", sign_report(doc))
    lines = ["# Generated mutants", "", f"Tool: {TOOL}, version {VERSION}. Reproduce: `{command}`; "
             f"wall time {seconds / 60:.1f} min.", ""]
    if len(runs) > 1:
        lines += ["Runs that made this report (the records of each mutant are from the last run that ran it):", ""]
        lines += [f"- `{r.get('command', '?')}` ({r.get('seconds', 0) / 60:.1f} min)"
                  + (f": {r['what']}" if r.get("what") else "") for r in runs]
        lines += [""]
    if doc["modules_not_run"]:
        lines += [f"Not yet run: {', '.join(doc['modules_not_run'])}.", ""]
    lines += [
             "| module | generated | run | killed | equivalent | surviving | not covered | invalid | not run | score | lines | branches |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for f, c in per.items():
        cv = c.get("coverage", {"lines": [0, 0], "branches": [0, 0]})
        pct = lambda a, b: f"{100 * a / b:.0f}% ({a}/{b})" if b else "-"  # noqa: E731
        sc = "-" if c["score"] is None else f"{100 * c['score']:.1f}%"
        run = c["killed"] + c["survived"] + c["timeout"] + c["invalid"]
        lines.append(f"| {f} | {c['generated']} | {run} | {c['killed']} | {c['equivalent']} | {c['survived'] + c['timeout']} | "
                     f"{c['not-covered']} | {c['invalid']} | {c['not-run']} | {sc} | {pct(*cv['lines'])} | {pct(*cv['branches'])} |")
    lines += ["", "Score: killed / (killed + surviving) over the mutants run; equivalent, invalid and not covered "
              "mutants counted apart.",
              "", "## Surviving and not covered", ""]
    for r in recs:
        if r["status"] in ("survived", "timeout", "not-covered"):
            lines.append(f"- `{r['mutant']}` ({r['status']}): {r['description']}")
    lines += ["", "## Equivalent (verification/mutants_equivalent.json)", ""]
    for r in recs:
        if r["status"] == "equivalent":
            lines.append(f"- `{r['mutant']}`: {r.get('equivalent_because', '')}")
    atomic_write_text(pathlib.Path(outdir) / "mutation-generated.md", "\n".join(lines) + "\n")
