"""Atomic file output: write to a temporary file in the target directory, fsync, then
os.replace, so an interrupted run or a full disk never leaves a half-written file."""
from __future__ import annotations

import json
import os
import tempfile

from .errors import LdasparkError


def atomic_write_bytes(path, data: bytes) -> None:
    path = os.fspath(path)
    d = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(d, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=os.path.basename(path), dir=d)
    except OSError as exc:
        raise LdasparkError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        os.chmod(tmp, _default_mode(path))  # mkstemp makes 0600; give the mode open() would
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise LdasparkError(f"cannot write {path}: {exc.strerror or exc}") from None
        raise


def _default_mode(path) -> int:
    """Mode of the existing file, else 0666 minus the umask (what a plain open() creates)."""
    try:
        return os.stat(path).st_mode & 0o7777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def atomic_write_text(path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path, obj) -> None:
    try:
        text = json.dumps(obj, indent=1, allow_nan=False)
    except ValueError as exc:  # NaN/inf: refuse before touching the file, as a user-facing error
        raise LdasparkError(f"cannot write {path}: {exc}") from None
    atomic_write_text(path, text + "\n")


def atomic_save_figure(fig, path, dpi: int = 100) -> None:
    """Render a matplotlib figure to PNG in memory, close it, and write it atomically."""
    import io as _io
    import matplotlib.pyplot as plt
    buf = _io.BytesIO()
    try:
        fig.savefig(buf, format="png", dpi=dpi)
    finally:
        plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
