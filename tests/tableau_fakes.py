"""Tableau stand-ins shared by the rule tests of core.tableau, analysis and the claims: small
exact tableaux built through ``from_json_dict`` with fields overridden, and a relative ``approx``."""
from __future__ import annotations

import pytest

from ldaspark.core.tableau_file import from_json_dict


def approx(expected, rel=1e-9, abs=0.0):
    """pytest.approx without its default absolute tolerance 1e-12, which would let every residual
    of these tests (1e-15 .. 1e-30) equal every other."""
    return pytest.approx(expected, rel=rel, abs=abs)


def _tab(**over):
    d = {"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]],
         "b": [1], "b_hat": [1], "b_tilde": [1]}
    d.update(over)
    return from_json_dict(d, "t")


def _lobatto2(**over):
    d = {"c": [0, 1], "A": [[0, 0], ["1/2", "1/2"]], "A_hat": [["1/2", 0], ["1/2", 0]],
         "A_tilde": [["1/2", 0], ["1/2", 0]], "b": ["1/2", "1/2"], "b_hat": ["1/2", "1/2"],
         "b_tilde": ["1/2", "1/2"]}
    d.update(over)
    return from_json_dict(d, "l2")
