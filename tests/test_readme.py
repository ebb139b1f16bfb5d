"""The README's example must run as written and do what it says."""
import pathlib
import re

import numpy as np

README = pathlib.Path(__file__).resolve().parents[1] / "README.md"


def test_readme_rolling_disk_example_runs(capsys):
    text = README.read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks, "README has no python example"
    ns = {}
    exec(compile(blocks[0], "README.md", "exec"), ns)
    sol = ns["sol"]
    assert np.abs(sol.constraint).max() < 1e-13
    assert np.abs(sol.energy - sol.energy[0]).max() < 1e-10   # free rolling: energy is conserved
    assert sol.q.shape == (101, 4)


def test_readme_commands_match_ci():
    text = README.read_text()
    ci = (README.parent / ".ci" / "run").read_text()
    assert "ldaspark report" in text
    assert "python -m pytest -q" in text and "python -m pytest -q" in ci
    assert 'pip install -q -e ".[test]"' in ci and 'pip install -e ".[test]"' in text
