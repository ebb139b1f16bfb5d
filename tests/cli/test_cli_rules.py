"""Rules of ``ldaspark.cli`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import pytest
import ldaspark


@pytest.mark.parametrize("argv", [["report", "--workers", "0"], ["report", "--workers", "-3"], ["report", "--jobs", "0"],
                                  ["report", "convergence", "--t-end", "nan"],
                                  ["report", "convergence", "--t-end", "inf"],
                                  ["report", "convergence", "--t-end", "-1"],
                                  ["report", "convergence", "--workers", "0"]])
def test_cli_bad_counts_and_times_exit_2_with_one_line(argv, capsys, tmp_path, monkeypatch):
    from ldaspark.cli import main
    monkeypatch.chdir(tmp_path)           # a value let through must not rewrite the repository's reports/
    with pytest.raises(SystemExit) as ei:
        main(argv)
    err = capsys.readouterr().err.strip()
    assert ei.value.code == 2 and err.startswith("ldaspark: error: argument --") and "\n" not in err
    assert argv[-2] in err.split(":")[2].split()[1].split("/")      # names the option given


def test_cli_valid_counts_and_times_parse():
    from ldaspark.cli import build_parser
    assert build_parser("report").parse_args(["report", "--workers", "3"]).workers == 3
    # --jobs, the name of ``ldaspark mutants``' option, is the main job's --workers too (it was read
    # as the section "3": "invalid choice")
    assert build_parser("report").parse_args(["report", "--jobs", "3"]).workers == 3
    assert build_parser("report").parse_args(["report", "convergence", "--t-end", "0.5"]).t_end == 0.5
    b = build_parser("integrate").parse_args(["integrate", "mp-particles", "gauss-1", "--h", "1", "--t-end", "1",
                                              "--out", "x.json", "--ic", "0"])
    assert b.ic == 0


@pytest.mark.parametrize("length", [243, 255])
def test_cli_out_with_a_long_name(length, tmp_path):
    from ldaspark.cli import main
    out = tmp_path / ("r" * (length - 5) + ".json")
    assert len(out.name) == length
    assert main(["integrate", "skate", "gauss-1", "--h", "0.1", "--t-end", "0.2", "--engine", "generic",
                 "--out", str(out)]) == 0
    assert ldaspark.load_result(str(out)).q.shape == (3, 3)
