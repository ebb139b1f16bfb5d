"""Rules of ``ldaspark.analysis.symmetry`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import types
import numpy as np
from types import SimpleNamespace
import mpmath
import pytest
from ldaspark.lab.theory import audit as au


def test_tangent_projector_null_space_and_rank_threshold():
    from ldaspark.analysis import symmetry as sy
    M = np.array([[1.0, 1.0, 0.0]])
    res = types.SimpleNamespace(extra={"gauge": None, "dk0_dq": [M, None]}, dps=None)
    P, dim = sy._tangent_projector(res, 0)
    assert dim == 2 and np.allclose(P @ M.T, 0, atol=1e-14) and np.allclose(P @ P, P, atol=1e-14)
    assert np.allclose(P @ np.array([1.0, -1.0, 5.0]), [1.0, -1.0, 5.0], atol=1e-14)
    # a second row 1e-9 x the first's size is below the relative rank threshold 1e-8; 1e-7 is not
    for eps, want in ((1e-9, 2), (1e-7, 1)):
        M2 = np.array([[1.0, 1.0, 0.0], [0.0, 0.0, eps]])
        res = types.SimpleNamespace(extra={"gauge": None, "dk0_dq": [None, M2]}, dps=None)
        assert sy._tangent_projector(res, 1)[1] == want
    # relative to the largest singular value: 1e-6 under 1e-8 x 1414 is below the threshold
    M3 = np.array([[1000.0, 1000.0, 0.0], [0.0, 0.0, 1e-6]])
    assert sy._tangent_projector(types.SimpleNamespace(extra={"gauge": None, "dk0_dq": [M3]}, dps=None), 0)[1] == 2
    # never relative to less than 1e-300: a subnormal 5e-309 is not a condition even next to 1e-301
    M4 = np.array([[1e-301, 0.0], [0.0, 5e-309]])
    assert np.linalg.svd(M4)[1][1] == 5e-309
    assert sy._tangent_projector(types.SimpleNamespace(extra={"gauge": None, "dk0_dq": [M4]}, dps=None), 0)[1] == 1
    # a gauge: the conditions are W^T dG/dq, and more rows than coordinates are padded
    W = np.array([[1.0], [0.0], [0.0]])
    G = np.array([[0.0, 2.0], [5.0, 5.0], [7.0, 7.0]])
    g = types.SimpleNamespace(W_left=W)
    res = types.SimpleNamespace(extra={"gauge": g, "dG_dq": [G, None]}, dps=None)
    P, dim = sy._tangent_projector(res, 0)
    assert dim == 1 and np.allclose(P, np.diag([1.0, 0.0]), atol=1e-14)
    res = types.SimpleNamespace(extra={"gauge": None, "dk0_dq": [np.array([[1.0], [2.0], [3.0]])]}, dps=None)
    assert sy._tangent_projector(res, 0)[1] == 0


def _close(x, rel=1e-9):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny numbers."""
    return pytest.approx(x, rel=rel, abs=0.0)


P, F, S, I = au.PASS, au.FAIL, au.SKIP, au.INFO


# --- audit: Theorem 1 / symmetry summaries, the verdict text, the disagreement sentence ----------
def test_symmetry_23_summary_quotes_the_largest_scene_residual(monkeypatch):
    from ldaspark.analysis import symmetry
    vals = {"particle": 1e-30, "skate": 2e-20}

    def fake(system, tab, t0, q0, v0, h, dps):
        x = vals[fake.names.pop(0)]
        return {"symmetry-Ld": x, "symmetry-fd-plus": x / 2, "symmetry-fd-minus": x / 4, "symmetry-Phi": x / 8,
                "wellposed": "well-posed"}
    fake.names = ["particle", "skate"]
    monkeypatch.setattr(symmetry, "check_symmetry", fake)
    tab = SimpleNamespace(source_digits=None)
    checks, _ = au._symmetry_checks(tab, 30, ("particle", "skate"))
    summ = checks[-1]
    assert summ.name == "symmetry" and summ.status == P
    assert summ.residual == _close(2e-20, rel=1e-12)


def test_symmetry_tangent_projector_drops_singular_values_below_1e8_relative():
    from ldaspark.analysis import symmetry
    # dk0/dq with singular values 1 and 1e-12: numerically rank 1, so one tangent direction
    M = np.array([[mpmath.mpf(1), 0], [0, mpmath.mpf("1e-12")]], dtype=object)
    res = SimpleNamespace(extra={"gauge": None, "dk0_dq": [M, M]}, dps=20)
    P, dim = symmetry._tangent_projector(res, 0)
    assert dim == 1
    assert float(abs(P[1, 1] - 1)) < 1e-15 and float(abs(P[0, 0])) < 1e-15
