"""README's "From sympy.physics.mechanics" example runs as written and is the skate of 8.2."""
import pathlib
import re

import numpy as np

import ldaspark

README = pathlib.Path(__file__).resolve().parents[2] / "README.md"


def _block():
    text = README.read_text()
    assert "## From sympy.physics.mechanics" in text
    section = text.split("## From sympy.physics.mechanics", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert len(blocks) == 1
    return blocks[0]


def test_readme_mechanics_example_is_the_skate(capsys):
    ns = {}
    exec(compile(_block(), "README.md", "exec"), ns)
    res = ns["res"]
    assert res.success and res.coordinate_names == ["x", "y", "theta"]
    assert np.abs(res.constraint).max() < 1e-13
    ref = ldaspark.integrate("skate", "gauss-2", t_span=(0, 10), q0=[0, 0, 0], v0=[0, 0, 1], h=0.05)
    assert np.abs(res.q - ref.q).max() < 1e-12 and np.abs(res.v - ref.v).max() < 1e-12
    # control: the same example with the load reversed is another motion
    ns2 = {}
    exec(compile(_block().replace("forcelist=[(P, -N.x)]", "forcelist=[(P, N.x)]"), "README.md", "exec"), ns2)
    assert np.abs(ns2["res"].q - ref.q).max() > 1e-2
