"""``lab.reports.files``: the reports' JSON files are read through the checked opener."""
from __future__ import annotations

import json
import os
import threading

import pytest

from ldaspark.core.errors import InputError
from ldaspark.lab.reports import files, summary


def test_a_report_file_is_read_and_an_absent_one_is_none(tmp_path):
    p = tmp_path / "r.json"
    p.write_text(json.dumps({"rows": [1, 2.5]}))
    assert files.load_json(p) == {"rows": [1, 2.5]}
    assert files.load_json(tmp_path / "absent.json") is None
    assert files.sha256(p) == __import__("hashlib").sha256(p.read_bytes()).hexdigest()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_in_place_of_a_report_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "claims.json"
    os.mkfifo(fifo)
    out = []
    # a reader that opened the FIFO would block until a writer came: run it in a thread with a deadline
    th = threading.Thread(target=lambda: out.append(_refusal(fifo)), daemon=True)
    th.start()
    th.join(30)
    assert not th.is_alive(), "reading a FIFO report blocked"
    assert out and isinstance(out[0], InputError) and "claims.json" in str(out[0])
    with pytest.raises(InputError):
        summary._load(str(tmp_path), "claims.json")      # the summary's reader goes through it


def _refusal(path):
    try:
        files.load_json(path)
    except InputError as exc:
        return exc
    return None


def test_a_report_past_the_size_limit_is_refused(tmp_path, monkeypatch):
    p = tmp_path / "big.json"
    p.write_text(json.dumps(list(range(100))))
    assert files.load_json(p)[-1] == 99                   # control: within the limit it is read
    monkeypatch.setattr(files, "REPORT_MAX_BYTES", 10)
    with pytest.raises(InputError, match="big.json"):
        files.load_json(p)
