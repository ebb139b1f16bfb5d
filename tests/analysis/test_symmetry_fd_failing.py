"""The f_d^+ / f_d^- rules of the symmetry check (``theory.symmetry.check_symmetry``, (23)) fed
their failing values: a method that is not symmetric, on the skate, whose multipliers make the
discrete forces f_d^-, f_d^+ nonzero on the tangent variations (the restricted norms, checked
> 1e-6, so the identity is not won by 0 = 0). The f_d residuals must then be far above the
claim's tolerance (verification/test_symmetry_23.py checks the failing L_d and Phi for the
Euler methods only)."""
from __future__ import annotations

import functools

import pytest

from ldaspark.lab.claims.ledger import TOL_SYMMETRY, perturbed_initial
from ldaspark.core.families import get_method
from ldaspark.models.scenes import get_scene
from ldaspark.analysis.discrete import SINGULAR
from ldaspark.analysis.symmetry import check_symmetry


@functools.lru_cache(maxsize=None)
def _check(name, a_tilde=None):
    tab = get_method(name, exact=True)
    if a_tilde is not None:
        tab = tab.with_entry("A_tilde", 0, 1, a_tilde)
    scene = get_scene("skate")
    t0, q0, v0 = perturbed_initial(scene, 60)
    return check_symmetry(scene.system, tab, t0, q0, v0, "0.1", dps=30)


@pytest.mark.parametrize("name, a_tilde", [("euler-i", None), ("gauss-2", "1/10")])
def test_fd_symmetry_fails_for_a_method_that_is_not_symmetric(name, a_tilde):
    r = _check(name, a_tilde)
    assert r["wellposed"] != SINGULAR
    assert max(r["fd_restricted_norm"]) > 1e-6, r          # the discrete forces are not zero here
    assert max(r["symmetry-fd-plus"], r["symmetry-fd-minus"]) > 1e3 * TOL_SYMMETRY, r


def test_fd_symmetry_holds_for_gauss_2_on_the_same_data():
    """The positive side on the same scene and data: the rule passes where (23) holds."""
    r = _check("gauss-2")
    assert min(r["fd_restricted_norm"]) > 1e-6
    assert max(r["symmetry-fd-plus"], r["symmetry-fd-minus"]) <= TOL_SYMMETRY, r
