"""The one reader of what the mutation tools read back: file arguments (``--only @FILE``,
``--keep-killed`` reports and checkpoints, the list of equivalent mutants, ``--tests``) and the
records in them.

* A file is opened only when it is a regular file (a FIFO would block, ``/dev/zero`` would be
  read until memory runs out), without blocking, and read up to a bound fixed before reading;
  a longer file, a directory, a missing file, bytes that are not UTF-8, JSON that is not finite
  or nested past ``MAX_DEPTH`` each end in one ``RecordError`` naming the file.
* A record is believed only when its writer's signature verifies: a report carries an HMAC
  with this user's checkpoint key (``ldaspark.lab.checkpoint.sign_document``), a checkpoint an HMAC
  per record (``Checkpoint``). An unsigned, edited or forged report is not refused as a file,
  but none of its verdicts is taken: its kills only order the tests that rerun their mutants
  (the named test first), so a forged "killed" costs a run and never turns a survivor into a
  kill.
* A kill names a test that exists in the project: a ``test_*.py`` file under ``tests/`` or
  ``verification/`` of this project (no ``..``, no link out) that defines the test function.
"""
from __future__ import annotations

import ast
import json
import math
import os
import pathlib
import stat

from ...core.errors import LdasparkError

#: bounds fixed before reading: the committed report is ~6 MB, an id list ~1 MB
MAX_REPORT_BYTES = 64 * 2 ** 20
MAX_LIST_BYTES = 8 * 2 ** 20
MAX_SOURCE_BYTES = 8 * 2 ** 20
MAX_DEPTH = 32
#: a mutant id holds the replaced source text (a ``return`` of a 20-line dict literal: 2430
#: characters in the committed report); bounded, far above every id the generator makes
MAX_ID_CHARS = 16384
REPORT_KIND = "mutation-generated-report"
#: every status a generated mutant's record can carry (``mutgen._rec``, ``mutation.STATUSES``)
GEN_STATUSES = ("killed", "survived", "invalid", "timeout", "equivalent", "not-covered", "not-run")
_GEN_KEYS = {"mutant", "file", "description", "category", "killed", "status", "first_failing_test", "seconds"}
_GEN_OPTIONAL = {"output_tail", "equivalent_because", "line", "original", "replacement", "previous_run"}
TEST_DIRS = ("tests", "verification")


class RecordError(LdasparkError):
    """A file argument or a record read back is not what its reader accepts."""


# --- files --------------------------------------------------------------------------------------
def read_bytes(path, what: str, limit: int) -> bytes:
    """The bytes of ``path`` when it is a regular file of at most ``limit`` bytes (a link to one
    is followed: the file opened is checked, not its name); opened without blocking."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    shown = str(path)[:200]
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise RecordError(f"{what} {shown}: cannot be read ({exc.strerror or exc})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
            raise RecordError(f"{what} {shown}: {kind}")
    except BaseException:
        os.close(fd)
        raise
    with os.fdopen(fd, "rb") as fh:         # a regular file: fdopen accepts it
        data = fh.read(limit + 1)
    if len(data) > limit:
        raise RecordError(f"{what} {shown}: larger than the reader's bound of {limit} bytes")
    return data


def read_text(path, what: str, limit: int | None = None) -> str:
    data = read_bytes(path, what, MAX_LIST_BYTES if limit is None else limit)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RecordError(f"{str(path)[:200]}: {what} is not UTF-8 (byte {exc.start})") from None


def _depth(text: str) -> int:
    from ..checkpoint import _json_depth
    return _json_depth(text)


def _finite(text):
    x = float(text)
    if not math.isfinite(x):
        raise ValueError(f"{text[:20]} is not a finite number")
    return x


def _no_constant(name):
    raise ValueError(f"{name} is not a finite number")


def parse_json(text: str, where: str):
    """Finite JSON nested at most ``MAX_DEPTH`` deep (checked before parsing: no recursion)."""
    if _depth(text) > MAX_DEPTH:
        raise RecordError(f"{where}: nested more than {MAX_DEPTH} deep")
    try:
        return json.loads(text, parse_constant=_no_constant, parse_float=_finite)
    except (ValueError, RecursionError) as exc:
        raise RecordError(f"{where}: not finite JSON ({str(exc)[:80]})") from None


def read_json(path, what: str, limit: int | None = None):
    return parse_json(read_text(path, what, MAX_REPORT_BYTES if limit is None else limit), f"{str(path)[:200]}: {what}")


def read_id_list(path) -> list[str]:
    """``--only @FILE``: one mutant id a line (blank lines skipped)."""
    return [x.strip() for x in read_text(path, "the --only list").splitlines() if x.strip()]


def read_equivalent(path) -> dict:
    """verification/mutants_equivalent.json: {mutant id: one-line argument}; {} when absent."""
    if not os.path.lexists(path):
        return {}
    data = read_json(path, "the list of equivalent mutants", MAX_LIST_BYTES)
    if not isinstance(data, dict) or not all(isinstance(k, str) and isinstance(v, str) and v.strip()
                                             for k, v in data.items()):
        raise RecordError(f"{path}: must map each mutant id to a one-line argument")
    return data


# --- records -------------------------------------------------------------------------------------
def check_generated_record(rec) -> dict:
    """The schema of one generated mutant's record (``mutgen._rec``, plus the fields a report
    adds): raises RecordError."""
    if not isinstance(rec, dict) or not _GEN_KEYS <= set(rec) or not set(rec) <= _GEN_KEYS | _GEN_OPTIONAL:
        raise RecordError("a record does not have a generated mutant's keys")
    name = rec["mutant"]
    if not isinstance(name, str) or not name or len(name) > MAX_ID_CHARS:
        raise RecordError("a record's mutant id is not a string")
    if rec["status"] not in GEN_STATUSES or not isinstance(rec["killed"], bool) \
            or rec["killed"] != (rec["status"] == "killed"):
        raise RecordError(f"the record of {name[:80]} has status {str(rec['status'])[:20]}, killed {rec['killed']!r}")
    texts = ("file", "description", "category", "output_tail", "equivalent_because", "original", "replacement")
    if not all(isinstance(rec[k], str) for k in texts if k in rec) \
            or not (rec["first_failing_test"] is None or isinstance(rec["first_failing_test"], str)):
        raise RecordError(f"the record of {name[:80]} has a text field that is not a string")
    if rec["status"] == "killed" and not rec["first_failing_test"]:
        raise RecordError(f"the record of {name[:80]} is a kill that names no test")
    sec = rec["seconds"]
    if isinstance(sec, bool) or not isinstance(sec, (int, float)) or not math.isfinite(sec) or sec < 0:
        raise RecordError(f"the record of {name[:80]} has seconds {str(sec)[:30]}")
    if "line" in rec and (isinstance(rec["line"], bool) or not isinstance(rec["line"], int)):
        raise RecordError(f"the record of {name[:80]} has a line that is not an integer")
    if "previous_run" in rec and not isinstance(rec["previous_run"], bool):
        raise RecordError(f"the record of {name[:80]} has previous_run {rec['previous_run']!r}")
    return rec


def check_report(doc, where: str) -> dict:
    """The parts of a mutation-generated.json a later run reads: ``mutants`` (a list of
    records), ``runs`` (a list of {command, seconds, ...}), ``modules_not_run`` (strings) and
    ``modules`` ({file: {coverage: {lines, branches}}}). Raises RecordError."""
    if not isinstance(doc, dict):
        raise RecordError(f"{where}: a report is a JSON object, not {type(doc).__name__}")
    recs = doc.get("mutants")
    if not isinstance(recs, list):
        raise RecordError(f"{where}: 'mutants' is not a list of records")
    for i, r in enumerate(recs):
        try:
            check_generated_record(r)
        except RecordError as exc:
            raise RecordError(f"{where}: mutants[{i}]: {exc}") from None
    runs = doc.get("runs", [])
    if not isinstance(runs, list) or not all(
            isinstance(r, dict) and isinstance(r.get("command", ""), str)
            and isinstance(r.get("seconds", 0), (int, float)) and not isinstance(r.get("seconds", 0), bool)
            for r in runs):
        raise RecordError(f"{where}: 'runs' is not a list of {{command, seconds}}")
    nr = doc.get("modules_not_run", [])
    if not isinstance(nr, list) or not all(isinstance(x, str) for x in nr):
        raise RecordError(f"{where}: 'modules_not_run' is not a list of strings")
    mods = doc.get("modules", {})
    if not isinstance(mods, dict):
        raise RecordError(f"{where}: 'modules' is not a mapping")
    for f, c in mods.items():
        cov = c.get("coverage", {}) if isinstance(c, dict) else None
        if not isinstance(cov, dict) or not all(
                isinstance(cov.get(k, [0, 0]), list) and len(cov.get(k, [0, 0])) == 2
                and all(isinstance(x, int) and not isinstance(x, bool) for x in cov.get(k, [0, 0]))
                for k in ("lines", "branches")):
            raise RecordError(f"{where}: the coverage of {str(f)[:80]} is not two pairs of counts")
    if "command" in doc and not isinstance(doc["command"], str):
        raise RecordError(f"{where}: 'command' is not a string")
    return doc


def sign_report(doc: dict) -> dict:
    """The report with its writer's signature (``lab.checkpoint.sign_document``)."""
    from ..checkpoint import sign_document
    return sign_document(REPORT_KIND, doc)


def report_signed(doc) -> bool:
    from ..checkpoint import document_signed
    return document_signed(REPORT_KIND, doc)


class Previous:
    """What a run reads back from one ``--keep-killed`` file: ``records`` (schema-checked),
    ``trusted`` (the writer's signature verified: a report signed with this user's key, or a
    checkpoint's records, each with its HMAC) and the report's ``doc`` (None for a checkpoint)."""

    def __init__(self, path, records, trusted, doc=None):
        self.path, self.records, self.trusted, self.doc = str(path), records, trusted, doc


def read_previous(path, say=None) -> Previous:
    """The one reader of an earlier run's records: a report (``mutation-generated.json``) or the
    checkpoint of an interrupted run (``*.partial.jsonl``; only the records whose HMAC verifies)."""
    from ...core.errors import InputError
    from ..checkpoint import Checkpoint
    p = pathlib.Path(path)
    if str(path).endswith(".jsonl"):
        def valid(name, value):
            check_generated_record(value)
            if value["mutant"] != name:
                raise RecordError(f"the record of {name[:80]} names another mutant")
            return True
        try:
            ck = Checkpoint.of_file(p, validate=valid, say=say)
            got = ck.load()
        except InputError as exc:
            raise RecordError(str(exc)) from None
        return Previous(p, list(got.values()), True)
    doc = check_report(read_json(p, "the earlier report"), str(p)[:200])
    return Previous(p, doc["mutants"], report_signed(doc), doc)


# --- kills name tests that exist ---------------------------------------------------------------------
def _defined_tests(path: pathlib.Path) -> set:
    """{'name', 'Class::name'} of the test functions ``path`` defines."""
    try:
        tree = ast.parse(read_text(path, "a test file", MAX_SOURCE_BYTES))
    except (SyntaxError, ValueError, RecordError):
        return set()
    # pytest's default collection: functions named test*, methods test* of classes named Test*
    out = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name.startswith("test"):
            out.add(node.name)
        elif isinstance(node, ast.ClassDef) and node.name.startswith("Test"):
            out.update(f"{node.name}::{f.name}" for f in node.body
                       if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)) and f.name.startswith("test"))
    return out


def names_existing_test(node_id, project, _cache=None) -> bool:
    """True when ``node_id`` ('tests/test_x.py::test_y[param]', 'tests/test_x.py::Cls::test_y' or a
    whole file) names a test of ``project``: a regular ``test_*.py`` under ``tests/`` or
    ``verification/``, inside the project once resolved, defining that function."""
    if not isinstance(node_id, str) or not node_id or len(node_id) > 1000:
        return False
    file, _, rest = node_id.partition("::")
    rel = pathlib.PurePosixPath(file)
    if rel.is_absolute() or ".." in rel.parts or len(rel.parts) < 2 or rel.parts[0] not in TEST_DIRS \
            or not rel.name.startswith("test_") or rel.suffix != ".py":
        return False
    root = pathlib.Path(project).resolve()
    path = (root / rel).resolve()
    try:
        path.relative_to(root)
        if not stat.S_ISREG(os.stat(path).st_mode):
            return False
    except (ValueError, OSError):
        return False
    if not rest:
        return True
    name = rest.split("[", 1)[0]
    cache = _cache if _cache is not None else {}
    if path not in cache:
        cache[path] = _defined_tests(path)
    return name in cache[path]
