"""Rules of ``ldaspark.models.bicycle`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import types
import numpy as np


def test_spark_eigenvalues_passes_the_lateral_restriction(monkeypatch):
    import sympy
    from ldaspark.models import bicycle as bc
    from ldaspark.lab.theory import bicycle_flow as bf
    seen = {}

    def fj(system, method, q0, v0, h, dps=None, coords=None, rates=None, dependent=None):
        seen.update(system=system, method=method, q0=q0, v0=v0, h=h, dps=dps, coords=coords, rates=rates,
                    dependent=dependent)
        return types.SimpleNamespace(eigenvalues=lambda: [np.complex128(1 + 2j), -3.0])
    monkeypatch.setattr(bf, "flow_jacobian", fj)
    model = types.SimpleNamespace(system="S", upright=lambda v: ([sympy.Rational(1, 3), sympy.Integer(0)],
                                                                 [sympy.Integer(v), -sympy.Rational(v, 3)]))
    ev = bf.spark_eigenvalues(5, model=model)
    assert ev == [1 + 2j, -3 + 0j] and all(type(z) is complex for z in ev)
    assert seen["h"] == 0.01 and seen["method"] == "gauss-2" and seen["dps"] is None and seen["system"] == "S"
    assert seen["q0"] == [1 / 3, 0.0] and seen["v0"] == [5.0, -5 / 3]
    assert seen["coords"] == bf.LATERAL == seen["rates"] and seen["dependent"] == list(bc.DEPENDENT_V)
    bf.spark_eigenvalues(5, "gauss-3", 0.02, dps=30, model=model)
    assert seen["q0"][0].startswith("0.33333333333333333333333333333333333333") and seen["dps"] == 30
    assert seen["h"] == 0.02 and seen["method"] == "gauss-3"
