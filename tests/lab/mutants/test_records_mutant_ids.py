"""``records.check_generated_record`` bounds a mutant id (``MAX_ID_CHARS``) far above the ids the
generator makes: an id holds the replaced source text, and a ``return`` of a long literal gives
ids of thousands of characters (peers.py's ``_study_dict``: 2430). The committed report, which
holds such ids, must read back (it could not when the bound was 1000: every ``--keep-killed
reports/mutation-generated.json`` failed on it)."""
from __future__ import annotations

import functools
import json
import pathlib

import pytest

from ldaspark.lab.mutants import mutgen, records
from ldaspark.lab.mutants.records import sign_report

ROOT = pathlib.Path(__file__).resolve().parents[3]
PEERS = "lab/reports/peers.py"


@functools.lru_cache(maxsize=1)
def _longest_generated_id():
    return max((m for m in mutgen.generate(PEERS, check=False)), key=lambda m: len(m.id))


def test_the_generators_longest_ids_read_back_from_a_signed_report(tmp_path):
    m = _longest_generated_id()
    assert len(m.id) > 1000                     # the case the old bound refused
    assert len(m.id) < records.MAX_ID_CHARS
    rec = mutgen._rec(m, "not-run", None, 0.0)
    rep = tmp_path / "prev.json"
    rep.write_text(json.dumps(sign_report({"mutants": [rec], "runs": [{"command": "c", "seconds": 1.0}]})))
    prev = records.read_previous(rep)
    assert prev.trusted and [r["mutant"] for r in prev.records] == [m.id]


def test_an_id_past_the_bound_is_refused():
    m = _longest_generated_id()
    rec = dict(mutgen._rec(m, "not-run", None, 0.0), mutant="x" * (records.MAX_ID_CHARS + 1))
    with pytest.raises(records.RecordError, match="mutant id is not a string"):
        records.check_generated_record(rec)
    records.check_generated_record(dict(rec, mutant="x" * records.MAX_ID_CHARS))      # at the bound: read


def test_the_committed_report_reads_back():
    prev = records.read_previous(ROOT / "reports" / "mutation-generated.json")
    assert len(prev.records) > 1000
