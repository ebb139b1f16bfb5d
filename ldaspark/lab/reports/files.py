"""The one reader of the JSON files the reports are rendered from (``reports/*.json``, written
by the main job and the benchmarks): through ``core.validate.read_regular`` like every file the
library reads, so that a FIFO, a device or a runaway file in ``reports/`` is refused in one line
instead of blocking or filling memory."""
from __future__ import annotations

import hashlib
import json
import os

from ...core.validate import read_regular

#: the largest report file read (the biggest committed one, mutation-generated.json, is ~4 MB)
REPORT_MAX_BYTES = 2 ** 28


def load_json(path, what: str = "report file"):
    """The JSON document in ``path`` (a regular file of at most REPORT_MAX_BYTES bytes); None
    when the file is absent. A malformed document raises ``ValueError`` as ``json.loads`` does."""
    if not os.path.exists(path):
        return None
    return json.loads(read_regular(path, REPORT_MAX_BYTES, what).decode("utf-8"))


def sha256(path, what: str = "report file") -> str:
    """The SHA-256 of the bytes of ``path`` (read as ``load_json`` reads)."""
    return hashlib.sha256(read_regular(path, REPORT_MAX_BYTES, what)).hexdigest()
