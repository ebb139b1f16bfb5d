"""Rules of ``ldaspark.solve`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import types
import numpy as np


def test_nonlinear_run_defaults_and_outputs(monkeypatch):
    import sympy
    import ldaspark.solve
    from ldaspark.models import bicycle as bc
    from ldaspark.lab.theory import bicycle_flow as bf
    seen = {}
    n = len(bc.COORDS)
    qs = sympy.symbols(f"x0:{n}")

    def integrate(sc, method, t_span, h, engine, raise_on_failure):
        seen.update(sc=sc, method=method, t_span=t_span, h=h, engine=engine, raise_on_failure=raise_on_failure)
        q = np.zeros((2, n)); q[1, bc.LEAN] = 0.1; q[1, bc.STEER] = -0.2; q[1, 0] = 3.0
        return types.SimpleNamespace(t=[0.0, 0.01], q=q, energy=[1.0, 1.0], constraint=np.array([[1e-16, -2e-16], [0.0, 3e-16]]))
    monkeypatch.setattr(ldaspark.solve, "integrate", integrate)
    model = types.SimpleNamespace(q=list(qs), f=qs[0] ** 2, scene=lambda speed, lean_rate: ("scene", speed, lean_rate))
    out = bf.nonlinear_run(model=model)
    assert seen == {"sc": ("scene", 5, 0.5), "method": "gauss-2", "t_span": (0, 5.0), "h": 0.01, "engine": "auto",
                    "raise_on_failure": True}
    assert list(out["lean"]) == [0.0, 0.1] and list(out["steer"]) == [0.0, -0.2]
    assert list(out["k"]) == [2e-16, 3e-16] and list(out["f"]) == [0.0, 9.0] and list(out["t"]) == [0.0, 0.01]
