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


def test_time_grid_at_dps_is_counted_at_the_working_precision():
    """The number of steps to t_end was counted in float64 with a fixed 1e-9 tolerance also at
    dps: h = "1e-420" at 400 digits (a nonzero number there) was refused as 'step size h must
    be finite and nonzero, got 0.0', and t_span = ("0", "1") with h = "0.10000000001" at 30 digits
    ran 10 steps to t = 1.0000000001 (status 0) instead of refusing a t_end that is not on the
    grid. Two-sided: the exact multiples run and end on t_end to the digits."""
    import mpmath
    import pytest
    import ldaspark
    from ldaspark.core.errors import InputError
    r = ldaspark.integrate("particle", "gauss-1", t_span=("0", "2e-420"), h="1e-420", dps=400, engine="generic")
    assert r.status == 0 and len(r.t) == 3
    with mpmath.workdps(400):
        assert abs(r.t[-1] - mpmath.mpf("2e-420")) <= mpmath.mpf("1e-819")
    with pytest.raises(InputError, match="not an integer multiple"):
        ldaspark.integrate("particle", "gauss-1", t_span=("0", "1"), h="0.10000000001", dps=30, engine="generic")
    r = ldaspark.integrate("particle", "gauss-1", t_span=("0", "1"), h="0.1", dps=30, engine="generic")
    assert r.status == 0 and len(r.t) == 11
    with mpmath.workdps(30):
        assert abs(r.t[-1] - 1) <= mpmath.mpf("1e-29")


def test_a_block_engine_at_dps_counts_its_steps_in_the_run_numbers():
    """The comparators (a block engine) counted Result.stats['steps'] as (t_end - t0) / h in
    float64: at 30 digits h = "1e-400" is 0.0 there, and the run ended in ZeroDivisionError after
    its steps. Counted in mpf now; control: the same run at h = "0.1" and in float64."""
    import mpmath
    import ldaspark
    for h, dps in (("1e-400", 30), ("0.1", 30), (0.1, None)):
        r = ldaspark.integrate("skate", "gauss-irk-2", h=h, n_steps=3, dps=dps, engine="generic")
        assert r.status == 0 and r.stats["steps"] == 3 and len(r.t) == 4
    with mpmath.workdps(30):
        assert r.t[-1] == 0.30000000000000004          # float64 control: t0 + 3 h in float64
        tiny = ldaspark.integrate("skate", "gauss-irk-2", h="1e-400", n_steps=3, dps=30, engine="generic")
        assert abs(tiny.t[-1] - mpmath.mpf("3e-400")) <= mpmath.mpf("1e-429")


def test_time_grid_in_float64_has_t_end_on_the_grid_to_round_off():
    """The float64 count accepted |N h - (t_end - t0)| up to 1e-9 max(1, |span|), an absolute
    1e-9 for short spans: t_span = (0, 1e-12), h = 3e-13 ran 3 steps to t = 9e-13 (status 0,
    10% short of t_end), and h = 0.10000000001 to t_end = 1 ended at 1.0000000001. The
    allowance is now the float rounding of the inputs (half an ulp each of t0, t_end and N h).
    Two-sided: h = 0.1 to 1, h = 1e-13 to 1e-12 and h = span / N in float still run."""
    import pytest
    import ldaspark
    from ldaspark.core.errors import InputError
    for span, h in [(1e-12, 3e-13), (1.0, 0.10000000001)]:
        with pytest.raises(InputError, match="not an integer multiple"):
            ldaspark.integrate("particle", "gauss-1", t_span=(0, span), h=h, engine="generic")
    for t0, t_end, N in [(0.0, 1.0, 10), (0.0, 1e-12, 10), (0.3, 7.1, 37), (1e6, 1e6 + 3.7, 123), (0.0, 2.0, 40)]:
        r = ldaspark.integrate("particle", "gauss-1", t_span=(t0, t_end), h=(t_end - t0) / N, engine="generic")
        assert r.status == 0 and len(r.t) == N + 1
