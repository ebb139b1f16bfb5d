"""The "External peer: odelab" section of work_precision.md (``peer_section``) and the robot of
``benchmarks/peer_odelab.py``. odelab itself is not needed: the section is built from the JSON the
benchmark writes, and the robot is checked against odelab's definitions transcribed below from
``odelab/system/nonholonomic/rolling.py`` (Robot) at commit ee3300c.
Cost: ~1 s (sympy derivation of two robots, two small report writes)."""
import importlib.util
import json
import pathlib

import numpy as np
import pytest
import sympy
from markdown_it import MarkdownIt
from markdown_it.rules_block.table import escapedSplit

from ldaspark.core.comparators import derive_mechanical
from ldaspark.models.scenes import robot
from ldaspark.lab.reports.peer import peer_section
from ldaspark.lab.reports.work_precision import write_report

ROOT = pathlib.Path(__file__).resolve().parents[3]


def _bench():
    spec = importlib.util.spec_from_file_location("peer_odelab", ROOT / "benchmarks" / "peer_odelab.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _run(initial, odelab, method, matched=True):
    drift = {"energy_drift": 0.028, "constraint": 1e-16}
    return {"initial": initial, "v0": [1, 0, 0, 1], "odelab": odelab, "ldaspark": method, "matched": matched,
            "n_steps": 1000, "h": 0.05, "odelab_cpu": 6.0, "generic_cpu": 2.0, "compiled_cpu": 0.004,
            "max_dt": 0.0, "max_dq": 4.6e-14, "max_dv": 7e-14, "tight_max_dq": 1e-14, "odelab_drift": drift,
            "generic_drift": drift}


FIXTURE = {
    "command": "python benchmarks/peer_odelab.py", "date": "2026-12-01", "cpu_count": 2, "machine": "x86_64",
    "versions": {"odelab": {"commit": "ee3300c663f595c2d185a00605bcfb93649352e0",
                            "patch": "benchmarks/peer/odelab-compat.patch"}},
    "scene": "odelab's mobile robot", "timing": "time.process_time",
    "tableau_check": [{"odelab": "Spark2", "ldaspark": "lobatto-iiia-iiib-2", "match": True}],
    "not_compared": {"NonHolonomicLeapFrog": "A(q_i)(v_i + v_i+1) = 0"},
    # a '|' in a cell must be escaped by the table helper, or the row is cut
    "runs": [_run("odelab-test", "Spark2", "lobatto-iiia-iiib-2"),
             _run("|v| = 1", "McLachlan", "lobatto-iiia-iiib-2-leapfrog", matched=False)],
}


def _cells(line):
    cols = escapedSplit(line.strip())
    return [c for i, c in enumerate(cols) if not ((i == 0 or i == len(cols) - 1) and c.strip() == "")]


def _table_rows(lines):
    """Cell counts (header first) of the one table in ``lines``, split as GFM renderers do."""
    text = "\n".join(lines)
    toks = [t for t in MarkdownIt("commonmark").enable("table").parse(text) if t.type == "table_open"]
    assert len(toks) == 1
    start, end = toks[0].map
    rows = text.split("\n")[start:end]
    return [len(_cells(r)) for i, r in enumerate(rows) if i != 1 and r.strip()]


def test_section_renders_from_the_json(tmp_path):
    path = tmp_path / "peer_odelab.json"
    path.write_text(json.dumps(FIXTURE))
    lines = peer_section(str(path))
    text = "\n".join(lines)
    assert "## External peer: odelab" in text
    assert "`python benchmarks/peer_odelab.py` run on 2026-12-01" in text and "not a dependency" in text
    counts = _table_rows(lines)
    assert counts == [counts[0]] * 3 and counts[0] == 13           # header + 2 runs, none cut by '|'
    assert "\\|v\\| = 1" in text and "(another method: control)" in text
    assert "Spark2 = lobatto-iiia-iiib-2: match" in text and "- odelab NonHolonomicLeapFrog" in text


def test_section_is_absent_without_the_json(tmp_path):
    assert peer_section(str(tmp_path / "peer_odelab.json")) == []


def _write(outdir):
    le = {"t_long": 1.0, **{k: {"label": k, "cpu": 1.0, "max_first_half": 1e-3, "max_second_half": 1e-3}
                            for k in ("spark", "dop853", "dop853_projected")}}
    dps = [{"precision": "float64 generic", "seconds_per_step": 1e-3}]
    clock = type("Clock", (), {"wall": 1.0, "cpu": 1.0})()
    return pathlib.Path(write_report(str(outdir), [], [], dps, le, clock)).read_text()


def test_work_precision_report_has_the_section_only_with_the_json(tmp_path):
    assert "External peer" not in _write(tmp_path)                  # negative control: no file, no section
    (tmp_path / "peer_odelab.json").write_text(json.dumps(FIXTURE))
    assert "## External peer: odelab" in _write(tmp_path)


def test_committed_json_renders():
    path = ROOT / "reports" / "peer_odelab.json"
    if not path.exists():
        pytest.skip("reports/peer_odelab.json not committed")
    lines = peer_section(str(path))
    data = json.loads(path.read_text())
    counts = _table_rows(lines)
    assert counts == [13] * (1 + len(data["runs"]))


# --- the robot: odelab's Robot, transcribed (q = u[0:4], v = u[4:8], identity mass matrix) ----------
def odelab_robot_parts(q):
    """M, U, K, b of odelab's Robot: momentum = velocity (M = I), force f[3] = -10 cos q[3] (so
    U = 10 sin q[3], as its energy states), codistribution [[1, 0, 0, -cos q[2]], [0, 1, 0, -sin q[2]]]."""
    K = sympy.Matrix([[1, 0, 0, -sympy.cos(q[2])], [0, 1, 0, -sympy.sin(q[2])]])
    return {"M": sympy.eye(4), "U": 10 * sympy.sin(q[3]), "K": K, "b": sympy.zeros(2, 1)}


def _differences(scene):
    """Names of the parts (M, U, K, b, q0, v0) where ``scene`` differs from odelab's robot with
    the initial data of odelab's own robot test (q0 = 0, v0 = (1, 0, 0, 1))."""
    sysm = scene.system
    mine, theirs = derive_mechanical(sysm), odelab_robot_parts(sysm.q)
    out = [k for k in ("M", "K", "b")
           if sympy.simplify(sympy.Matrix(mine[k]) - theirs[k]) != sympy.zeros(*theirs[k].shape)]
    out += ["U"] if sympy.simplify(mine["U"] - theirs["U"]) != 0 else []
    _, q0, v0 = scene.initial()
    out += ["q0"] if not np.array_equal(q0, [0, 0, 0, 0]) else []
    out += ["v0"] if not np.array_equal(v0, [1, 0, 0, 1]) else []
    return out


def test_benchmark_robot_is_odelabs_robot():
    assert _differences(_bench().odelab_robot_scene()) == []


def test_builtin_robot_differs_only_in_the_wheel_inertia():
    # negative control of the check above, and the stated difference: the paper's I_w = 1 puts
    # 3 I_w = 3 on v4^2 / 2 where odelab's identity mass matrix has 1; I_w = 1/3 is odelab's robot
    assert _differences(robot()) == ["M"]
    assert derive_mechanical(robot().system)["M"] == sympy.diag(1, 1, 1, 3)
    assert _differences(robot(I_w=sympy.Rational(1, 3))) == []
