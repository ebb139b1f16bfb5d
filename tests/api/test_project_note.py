"""``project=True`` says what it changed: the largest change of v0 in ``stats`` and, above the
rounding of v0, one LdasparkWarning; consistent data are moved by rounding only and stay silent."""
import warnings

import numpy as np
import pytest

import ldaspark
from ldaspark.core.errors import LdasparkWarning

SKATE = dict(t_span=(0, 0.3), h=0.1, q0=[0, 0, 0])


@pytest.mark.parametrize("kw", [dict(engine="generic"), dict(engine="compiled"), dict(dps=30)])
def test_projection_is_reported(kw):
    # the skate's constraint is sin(theta) v1 - cos(theta) v2 = 0: at theta = 0, v2 must be 0,
    # so the projection of v0 = (0.5, 0.25, 1) moves v2 by 0.25 (and nothing else: L_vv = I on (v1, v2))
    with pytest.warns(LdasparkWarning, match=r"project=True changed v0 by up to 0.25"):
        res = ldaspark.integrate("skate", "gauss-2", v0=[0.5, 0.25, 1], project=True, **SKATE, **kw)
    assert res.stats["projected_v0_change"] == pytest.approx(0.25, rel=1e-12)
    assert abs(float(res.v[0][1])) < 1e-15


def test_consistent_data_are_projected_silently():
    with warnings.catch_warnings():
        warnings.simplefilter("error", LdasparkWarning)
        res = ldaspark.integrate("skate", "gauss-2", v0=[0.5, 0, 1], project=True, **SKATE)
    # the projection of consistent data moves them by rounding at most (64 ulps: the bound of the note)
    assert res.stats["projected_v0_change"] <= 64 * np.finfo(float).eps
    plain = ldaspark.integrate("skate", "gauss-2", v0=[0.5, 0, 1], **SKATE)
    assert "projected_v0_change" not in plain.stats
