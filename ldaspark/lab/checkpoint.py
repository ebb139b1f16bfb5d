"""Checkpoints of the paper lab's long jobs (the claims ledger, the mutation catalogue, the main
job): a ``Checkpoint`` file records each finished unit as it comes in, authenticated with this
user's key (``checkpoint_key``), under a ``source_fingerprint`` of the code, the environment and
the job's configuration, so that a rerun of an interrupted or partly failed job resumes from it
(``run_resumable``: ``ldaspark.executors.run_units`` with a checkpoint); ``sign_document`` /
``document_signed`` sign the reports read back.

Moved here from ``ldaspark.executors`` (the library's "where work runs"), which this module uses:
the library never imports the lab (``tests/project/test_layers.py``), so the old names
``ldaspark.executors.Checkpoint`` etc. are gone (docs/changelog.md).
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import pathlib
import re
from typing import Callable

from ..core.errors import InputError, LdasparkError
from ..core.io import atomic_write_text
from ..executors import Unit, run_units

# --- checkpoints --------------------------------------------------------------------------------
#: the distributions whose versions change what a unit computes (the ledger's digits, the
#: mutation verdicts): part of every fingerprint, as the package's own source is
_FINGERPRINT_DISTS = ("numpy", "scipy", "mpmath", "sympy", "numba", "python-flint", "gmpy2", "pytest", "hypothesis",
                     "h5py", "llvmlite")
#: names under ``paths`` that never enter a fingerprint: caches, and the checkpoints themselves
#: (a checkpoint in a fingerprinted directory would change its own fingerprint as it is written)
_FINGERPRINT_SKIP = ("__pycache__", ".hypothesis", ".pytest_cache", ".git")
_FINGERPRINT_SKIP_SUFFIX = (".pyc", ".partial.jsonl", ".tmp")


def _environment_identity() -> list:
    import importlib.metadata
    import sys
    out = [sys.version, sys.platform]
    for name in _FINGERPRINT_DISTS:
        try:
            out.append(f"{name}=={importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            out.append(f"{name} absent")
    return out


def _hash_file(h, path: pathlib.Path, st) -> None:
    """The bytes of the regular file ``path`` (``st``: its lstat), read without following a link
    and without blocking; a file that changed kind since ``st`` is hashed as a special entry."""
    import stat
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        h.update(b"unreadable\0" + str(exc.errno).encode())
        return
    if not stat.S_ISREG(os.fstat(fd).st_mode):      # before fdopen, which refuses a directory
        os.close(fd)
        h.update(b"special\0")
        return
    with os.fdopen(fd, "rb") as fh:
        d = hashlib.sha256()
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            d.update(chunk)
    h.update(d.digest())


def _hash_tree(h, root: pathlib.Path, pattern: str) -> None:
    """Every file under ``root`` matching ``pattern`` (caches and checkpoints left out), by its
    path and bytes. A link is hashed as its target's text, never followed (a link to /dev/zero or
    out of the tree is not read); FIFOs, sockets and devices enter by name only, never opened."""
    import stat
    try:
        top = os.lstat(root)
    except OSError:
        h.update(b"absent\0" + str(root.name).encode() + b"\0")
        return
    if not stat.S_ISDIR(top.st_mode):
        h.update(b"file\0" + root.name.encode() + b"\0")
        if stat.S_ISREG(top.st_mode):
            _hash_file(h, root, top)
        elif stat.S_ISLNK(top.st_mode):
            h.update(b"link\0" + os.readlink(root).encode(errors="surrogateescape"))
        else:
            h.update(b"special\0")
        return
    for p in sorted(root.rglob(pattern)):      # rglob does not descend into linked directories
        rel = p.relative_to(root)
        if any(part in _FINGERPRINT_SKIP for part in rel.parts) or p.name.endswith(_FINGERPRINT_SKIP_SUFFIX):
            continue
        try:
            st = os.lstat(p)
        except OSError:
            continue
        if stat.S_ISDIR(st.st_mode):
            continue
        h.update(str(rel).encode(errors="surrogateescape") + b"\0")
        if stat.S_ISREG(st.st_mode):
            _hash_file(h, p, st)
        elif stat.S_ISLNK(st.st_mode):
            h.update(b"link\0" + os.readlink(p).encode(errors="surrogateescape"))
        else:                                   # FIFOs, sockets, devices: never opened
            h.update(b"special\0")


def source_fingerprint(*config, dirs=(), paths=()) -> str:
    """sha256 over every file of this package (source and data: the tableaux a verdict reads),
    the ``*.py`` files under ``dirs``, every file
    under ``paths`` (files or directories, caches and checkpoints left out), the Python version
    and the versions of the libraries the results depend on (``_FINGERPRINT_DISTS``), and
    ``config`` (JSON): a checkpoint written by other code, another environment or for another
    configuration is never resumed from. The fingerprint is an identity, not a secret: anyone
    can recompute it, so ``Checkpoint`` authenticates its records with a key of its own."""
    h = hashlib.sha256()
    pkg = pathlib.Path(__file__).resolve().parent.parent   # the package ldaspark (this file: ldaspark/lab/)
    h.update(b"package\0")
    _hash_tree(h, pkg, "*")
    for root in map(pathlib.Path, dirs):
        h.update(b"dir\0")
        _hash_tree(h, root, "*.py")
    for root in map(pathlib.Path, paths):
        h.update(b"path\0")
        _hash_tree(h, root, "*")
    h.update(json.dumps(_environment_identity()).encode())
    h.update(json.dumps(config, sort_keys=True, default=str).encode())
    return h.hexdigest()


#: bounds of the checkpoint reader: a longer line, a deeper value or the part of the file past
#: MAX_CHECKPOINT_BYTES is not resumed (the units are computed again). A ledger unit's records
#: are ~20 KB on one line, a mutant's record ~3 KB, nested 4 deep.
MAX_CHECKPOINT_LINE = 8 * 2 ** 20
MAX_CHECKPOINT_BYTES = 512 * 2 ** 20
MAX_CHECKPOINT_DEPTH = 64
_KEY_NAME = "checkpoint-hmac.key"
_KEY_HEX = re.compile(rb"^[0-9a-f]{64}\n$")
_MAC_HEX = re.compile(r"^[0-9a-f]{64}$")
_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.S)
_KEYS: dict = {}


class CheckpointKeyError(LdasparkError):
    """No trusted place for the checkpoints' key (records are then never resumed)."""


def _read_key(path: str) -> bytes | None:
    """The key in ``path`` when it is a regular file of this user that nobody else can read or
    write (opened without following a link, without blocking), holding 64 hex digits; else None."""
    import stat
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        uid = os.getuid() if hasattr(os, "getuid") else None
        if not stat.S_ISREG(st.st_mode) or st.st_size != 65 or st.st_mode & 0o077 or \
                (uid is not None and st.st_uid != uid):
            return None
        raw = os.read(fd, 66)
    except OSError:
        return None
    finally:
        os.close(fd)
    return bytes.fromhex(raw[:64].decode("ascii")) if _KEY_HEX.match(raw) else None


def checkpoint_key(directory: str | None = None) -> bytes:
    """This user's secret key for the checkpoints' HMACs: ``checkpoint-hmac.key`` in the trusted
    directory of the compiled cache (``ldaspark.compiled.cache.cache_dir``: owned by this user,
    mode 0700, every component of its path safe), created on first use (mode 0600, O_EXCL |
    O_NOFOLLOW, then linked into place, so a concurrent creator's key is never half read). A key
    file that is a link, not this user's, readable by others or malformed is replaced (records
    signed with it are then recomputed). Raises CheckpointKeyError without a trusted directory."""
    import secrets

    from ..compiled.cache import CacheDirectoryError, cache_dir, path_trust, remove_entry
    try:
        d = directory if directory is not None else cache_dir()
    except CacheDirectoryError as exc:
        raise CheckpointKeyError(str(exc)) from None
    why = path_trust(d)
    if why:
        raise CheckpointKeyError(f"the checkpoint key's directory is not trusted: {why}")
    path = os.path.join(d, _KEY_NAME)
    if path in _KEYS:
        return _KEYS[path]
    nofollow = getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    for _ in range(3):
        key = _read_key(path)
        if key is not None:
            _KEYS[path] = key
            return key
        if os.path.lexists(path):
            with contextlib.suppress(OSError):
                remove_entry(path)              # planted, shared or damaged: never used
        tmp = os.path.join(d, f".{_KEY_NAME}.{secrets.token_hex(8)}")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | nofollow, 0o600)
            try:
                os.write(fd, secrets.token_hex(32).encode("ascii") + b"\n")
                os.fsync(fd)
            finally:
                os.close(fd)
            try:
                os.link(tmp, path)              # never replaces a key another process made
            except FileExistsError:
                pass
            except OSError:                     # no hard links here: create it in place, O_EXCL
                fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | nofollow, 0o600)
                try:
                    os.write(fd, secrets.token_hex(32).encode("ascii") + b"\n")
                    os.fsync(fd)
                finally:
                    os.close(fd)
        except OSError as exc:
            raise CheckpointKeyError(f"cannot create the checkpoint key {path}: {exc.strerror or exc}") from None
        finally:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    raise CheckpointKeyError(f"the checkpoint key {path} cannot be made trustworthy")


def _json_depth(text: str) -> int:
    """Deepest nesting of [ and { in a JSON text (strings skipped), without parsing it."""
    # linear: the strings are skipped from quote to quote (str.find), the brackets outside them
    # counted by NumPy in one pass (a regular expression for the strings retried an unclosed
    # string at every quote: quadratic, hours for one forged 8 MiB line)
    import numpy as np
    outside, i, n = [], 0, len(text)
    while i < n:
        j = text.find('"', i)
        if j < 0:
            outside.append(text[i:])
            break
        outside.append(text[i:j])
        i = j + 1
        while True:                     # to the next quote not escaped
            j = text.find('"', i)
            if j < 0:
                i = n                   # unclosed: json.loads refuses it
                break
            k = j
            while k > i and text[k - 1] == "\\":
                k -= 1
            i = j + 1
            if (j - k) % 2 == 0:
                break
    b = np.frombuffer("".join(outside).encode("utf-8", "replace"), dtype=np.uint8)
    step = (b == ord("[")).astype(np.int64) + (b == ord("{")) - (b == ord("]")) - (b == ord("}"))
    return int(max(0, np.cumsum(step).max(initial=0)))


def _reject_constant(name):
    raise ValueError(f"{name} is not a finite number")


def _finite_float(text):
    import math
    x = float(text)
    if not math.isfinite(x):                    # 1e999
        raise ValueError(f"{text[:20]} is not a finite number")
    return x


def _canonical(obj) -> bytes:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False).encode()


class Checkpoint:
    """Finished units of a run, one JSON line each, after a header line with the run's
    fingerprint: ``load()`` gives what a previous run with the same fingerprint finished,
    ``add(name, value)`` appends (flushed, so that a killed parent loses at most the line being
    written), ``discard()`` removes the file once the run's report is written. Values must be
    JSON (the ledger's and the catalogue's records are). A path that exists but is not a regular
    file is refused.

    A checkpoint is data from disk like any other (docs/reliability.md, "Trust model for
    checkpoints and result files"): each record carries an HMAC-SHA256, with this user's key
    (``checkpoint_key``), over the fingerprint, the unit's name and its value, and is resumed only
    when that HMAC is right, the unit is one the run expects, the value is finite JSON within the
    reader's bounds (``MAX_CHECKPOINT_*``) and ``validate(name, value)`` accepts it (the caller's
    schema). Any other line is discarded, with one line through ``say`` (default: stderr) per
    load; its unit is computed again, and the file is rewritten with the accepted records only
    (``open``), so a bad record never survives into the next run. ``key``: the HMAC key (default
    ``checkpoint_key()``)."""

    def __init__(self, path, fingerprint: str, validate: Callable | None = None, say: Callable | None = None,
                 key: bytes | None = None):
        self.path, self.fingerprint = pathlib.Path(path), fingerprint
        self.validate, self.say = validate, say
        self._key, self._key_error = key, None
        self._fh = None
        self._noted = set()

    def bound_to(self, *settings) -> "Checkpoint":
        """The same file with the fingerprint extended by ``settings`` (JSON, ``str`` for the
        rest): a function that takes a checkpoint from its caller binds it to its own
        arguments, so that a record is resumed only by a run of the same settings whatever
        fingerprint the caller chose."""
        fp = hashlib.sha256(self.fingerprint.encode() + b"\0" + json.dumps(
            settings, sort_keys=True, default=str).encode()).hexdigest()
        return Checkpoint(self.path, fp, self.validate, self.say, self._key)

    @classmethod
    def of_file(cls, path, validate: Callable | None = None, say: Callable | None = None) -> "Checkpoint":
        """The checkpoint at ``path`` bound to the fingerprint its header names: to read back
        the records of another run (``ldaspark mutants --keep-killed RUN.partial.jsonl``). The
        fingerprint is taken on trust, the records are not: each is still resumed only with
        this user's HMAC over that fingerprint, its name and its value (``load``). Raises
        InputError for a path that is not a regular file or a header that is not one."""
        import stat
        flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
        try:
            fd = os.open(path, flags)
        except OSError as exc:
            raise InputError(f"checkpoint {path} cannot be read ({exc.strerror or exc})") from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):      # before fdopen, which refuses a directory
            os.close(fd)
            raise InputError(f"checkpoint {path} is not a regular file")
        with os.fdopen(fd, "rb") as fh:
            head = fh.readline(4096)
        try:
            fp = json.loads(head.decode("utf-8"))["fingerprint"]
        except (ValueError, KeyError, TypeError, AttributeError, RecursionError):
            fp = None
        if not isinstance(fp, str) or not _MAC_HEX.match(fp):
            raise InputError(f"checkpoint {path} has no header line {{\"fingerprint\": 64 hex digits}}")
        return cls(path, fp, validate, say)

    # --- authentication and checks of one record ------------------------------------------
    def _mac_key(self) -> bytes | None:
        if self._key is None and self._key_error is None:
            try:
                self._key = checkpoint_key()
            except CheckpointKeyError as exc:
                self._key_error = str(exc)
        return self._key

    def _mac(self, name, value) -> str:
        import hmac
        key = self._mac_key()
        if key is None:
            return ""
        msg = b"ldaspark-checkpoint-v1\0" + self.fingerprint.encode() + b"\0" + _canonical([name, value])
        return hmac.new(key, msg, hashlib.sha256).hexdigest()

    def _note(self, msg):
        (self.say or (lambda m: print(f"ldaspark: {m}", file=__import__("sys").stderr, flush=True)))(msg)

    def _why_not(self, name, value, units) -> str:
        """"" when (name, value) is a record this run would accept, else why not (the checks
        that do not need the HMAC: the writer applies them too)."""
        if not isinstance(name, str) or not name:
            return "the unit name is not a string"
        if units is not None and name not in units:
            return f"unit {name[:60]!r} is not one of this run's"
        try:
            text = _canonical(value)
        except (TypeError, ValueError) as exc:
            return f"the value is not finite JSON ({str(exc)[:60]})"
        if len(text) > MAX_CHECKPOINT_LINE - 200:
            return f"the value has {len(text)} bytes, more than the reader's bound"
        if _json_depth(text.decode("ascii")) > MAX_CHECKPOINT_DEPTH - 2:
            return "the value is nested more deeply than the reader's bound"
        if self.validate is not None:
            try:
                ok = self.validate(name, value)
            except Exception as exc:  # noqa: BLE001  (a schema says no in its own words)
                return f"not a valid record: {str(exc)[:100] or type(exc).__name__}"
            if ok is False:
                return "not a valid record"
        return ""

    def _parse(self, raw: bytes, units):
        """(name, value) of one line of the file, or (None, why it is discarded)."""
        import hmac
        if len(raw) > MAX_CHECKPOINT_LINE or not raw.endswith(b"\n"):
            return None, "longer than the reader's bound" if len(raw) > MAX_CHECKPOINT_LINE else "truncated"
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            return None, "not UTF-8"
        if _json_depth(text) > MAX_CHECKPOINT_DEPTH:
            return None, "nested more deeply than the reader's bound"
        try:
            rec = json.loads(text, parse_constant=_reject_constant, parse_float=_finite_float)
        except (ValueError, RecursionError) as exc:
            return None, f"not finite JSON ({str(exc)[:60]})"
        if not isinstance(rec, dict) or set(rec) != {"unit", "value", "mac"}:
            return None, "not a record {unit, value, mac}"
        name, value, mac = rec["unit"], rec["value"], rec["mac"]
        if not isinstance(mac, str) or not _MAC_HEX.match(mac):
            return None, "no HMAC"
        if not isinstance(name, str) or (units is not None and name not in units):
            return None, self._why_not(name, value, units)
        if self._mac_key() is None:
            return None, f"no key to check it ({self._key_error})"
        try:
            good = hmac.compare_digest(mac, self._mac(name, value))
        except (TypeError, ValueError):
            good = False
        if not good:
            return None, "wrong HMAC (edited, forged or written with another key or fingerprint)"
        why = self._why_not(name, value, units)       # the caller's schema, on authentic data only
        if why:
            return None, why
        return name, value

    # --- the file --------------------------------------------------------------------------
    def load(self, units=None, validate=None) -> dict:
        """{unit name: value} of the accepted records (``units``: the names this run expects,
        None: any; ``validate`` replaces the constructor's schema)."""
        if validate is not None:
            self.validate = validate
        units = None if units is None else set(units)
        if not os.path.lexists(self.path):
            return {}
        self._check_regular()
        flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
        try:
            fd = os.open(self.path, flags)
        except OSError as exc:
            raise InputError(f"checkpoint {self.path} cannot be read ({exc.strerror or exc}); not touched") from None
        import stat
        out, bad, total = {}, [], 0
        if not stat.S_ISREG(os.fstat(fd).st_mode):      # before fdopen, which refuses a directory
            os.close(fd)
            raise InputError(f"checkpoint {self.path} exists and is not a regular file; not touched")
        with os.fdopen(fd, "rb") as fh:
            head = fh.readline(MAX_CHECKPOINT_LINE + 1)
            try:
                ok = json.loads(head.decode("utf-8")).get("fingerprint") == self.fingerprint
            except (ValueError, AttributeError, RecursionError):
                ok = False
            if not ok:
                self._note(f"checkpoint {self.path} was written by other code or for other settings: "
                           "not resumed")
                return {}
            total = len(head)
            lineno = 1
            while True:
                raw = fh.readline(MAX_CHECKPOINT_LINE + 1)
                if not raw:
                    break
                lineno += 1
                total += len(raw)
                if total > MAX_CHECKPOINT_BYTES:
                    bad.append(f"line {lineno} onwards: past {MAX_CHECKPOINT_BYTES} bytes")
                    break
                if len(raw) > MAX_CHECKPOINT_LINE:          # skip the rest of the long line
                    while raw and not raw.endswith(b"\n"):
                        raw = fh.readline(MAX_CHECKPOINT_LINE + 1)
                        total += len(raw)
                    bad.append(f"line {lineno}: longer than the reader's bound")
                    continue
                name, value = self._parse(raw, units)
                if name is None:
                    bad.append(f"line {lineno}: {value}")
                elif name not in out:
                    out[name] = value
        if bad:
            more = f" (and {len(bad) - 2} more)" if len(bad) > 2 else ""
            self._note(f"checkpoint {self.path}: {len(bad)} record(s) discarded and their units computed again: "
                       f"{'; '.join(bad[:2])}{more}")
        return out

    def _line(self, name, value) -> str:
        return json.dumps({"unit": name, "value": value, "mac": self._mac(name, value)}, allow_nan=False) + "\n"

    def _check_regular(self):
        import stat
        st = os.lstat(self.path)
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"checkpoint {self.path} exists and is not a regular file; not touched")

    def open(self, keep: dict):
        """Start the file anew with the header and ``keep`` (the units resumed), then append."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if os.path.lexists(self.path):
            self._check_regular()
        lines = [json.dumps({"fingerprint": self.fingerprint}) + "\n"]
        lines += [self._line(k, v) for k, v in keep.items()]
        atomic_write_text(self.path, "".join(lines))
        self._fh = open(self.path, "a", encoding="utf-8")
        return self

    def add(self, name: str, value):
        """Append a finished unit, unless the reader would refuse it (not finite JSON, too big,
        refused by the schema): then it is not recorded (one note), and a rerun computes it."""
        why = self._why_not(name, value, None)
        if why or self._mac_key() is None:
            if name not in self._noted:
                self._noted.add(name)
                self._note(f"checkpoint {self.path}: unit {name[:60]!r} not recorded "
                           f"({why or self._key_error}); a rerun computes it again")
            return
        self._fh.write(self._line(name, value))
        self._fh.flush()

    def close(self):
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def discard(self):
        """Remove the checkpoint (``--fresh``): a regular file only; a link, FIFO or directory at its
        path is refused as the run without ``--fresh`` refuses it (it unlinked them)."""
        self.close()
        if os.path.lexists(self.path):
            self._check_regular()
        with contextlib.suppress(FileNotFoundError):
            os.remove(self.path)


#: the HMAC domain of a signed document (a report read back, ``sign_document``): a checkpoint
#: record's MAC never verifies as a document's, nor one kind of document's as another's
_DOC_DOMAIN = b"ldaspark-signed-document-v1\0"
SIGNATURE = "signature"


def _document_mac(kind: str, doc: dict, key: bytes) -> str:
    import hmac
    body = {k: v for k, v in doc.items() if k != SIGNATURE}
    return hmac.new(key, _DOC_DOMAIN + kind.encode() + b"\0" + _canonical(body), hashlib.sha256).hexdigest()


def sign_document(kind: str, doc: dict, key: bytes | None = None) -> dict:
    """``doc`` (finite JSON) with a ``signature`` {scheme, mac}: an HMAC-SHA256 with this user's
    checkpoint key (``checkpoint_key``) over ``kind`` and the canonical JSON of the rest, as the
    checkpoints' records carry one. Without a trusted key the document is returned unsigned
    (a reader then treats it as data it cannot trust: ``document_signed`` is False)."""
    body = json.loads(_canonical({k: v for k, v in doc.items() if k != SIGNATURE}))   # as read back
    if key is None:
        try:
            key = checkpoint_key()
        except CheckpointKeyError:
            return body
    return dict(body, **{SIGNATURE: {"scheme": "hmac-sha256", "mac": _document_mac(kind, body, key)}})


def document_signed(kind: str, doc, key: bytes | None = None) -> bool:
    """True when ``doc`` carries a signature of ``kind`` by this user's key over exactly its
    other fields (``sign_document``); False for an unsigned, edited or forged document, one
    signed with another key or as another kind, or without a trusted key here."""
    import hmac
    if not isinstance(doc, dict):
        return False
    sig = doc.get(SIGNATURE)
    if not isinstance(sig, dict) or set(sig) != {"scheme", "mac"} or sig["scheme"] != "hmac-sha256" \
            or not isinstance(sig["mac"], str) or not _MAC_HEX.match(sig["mac"]):
        return False
    if key is None:
        try:
            key = checkpoint_key()
        except CheckpointKeyError:
            return False
    try:
        return hmac.compare_digest(sig["mac"], _document_mac(kind, doc, key))
    except (TypeError, ValueError):
        return False


def run_resumable(units: list[Unit], checkpoint: Checkpoint | None, where=None, jobs=None, retries=2,
                  on_done=None, mp_context=None, say=None, validate=None) -> dict:
    """``run_units`` with a checkpoint: units finished by an earlier run with the same fingerprint
    are taken from it and not run again; each unit finished now is appended as it comes in. On
    failure (``UnitsFailed``, Ctrl-C, ...) the checkpoint keeps everything finished. Only records
    of these units' names that pass ``validate(name, value)`` (the caller's schema: raise or
    return False to refuse) and the checkpoint's own checks are resumed (``Checkpoint``); notes
    on discarded records go to ``say`` (default stderr)."""
    done = {}
    if checkpoint is not None:
        if checkpoint.say is None and say is not None:
            checkpoint.say = say
        done = checkpoint.load([u.name for u in units], validate)
    done = {u.name: done[u.name] for u in units if u.name in done}
    if done and say is not None:
        say(f"resuming: {len(done)} of {len(units)} units from {checkpoint.path}")
    if checkpoint is not None:
        checkpoint.open(done)

    def finished(name, val):
        if checkpoint is not None:
            checkpoint.add(name, val)
        if on_done is not None:
            on_done(name, val)
    try:
        results = run_units([u for u in units if u.name not in done], where, jobs, retries, finished, mp_context)
    finally:
        if checkpoint is not None:
            checkpoint.close()
    results.update(done)
    return results
