"""Rules of ``ldaspark.compiled.fast`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

from ldaspark.lab.reports import peers
import pytest
import sympy
import ldaspark
from ldaspark.core.errors import SystemDefinitionError
from scene_fakes import _Scene


# =============================================================================================
# peers: stand-ins
# =============================================================================================


# =============================================================================================
# peers: rows of a run
# =============================================================================================


def test_mechanical_needs_the_mechanical_compiled_form(monkeypatch):
    import ldaspark.compiled.fast as fast
    for answer, want in (((True, "mechanical"), True), ((True, "general"), False), ((False, "mechanical"), False)):
        monkeypatch.setattr(fast, "can_compile", lambda system, a=answer: a)
        assert peers._mechanical(_Scene()) is want


# --- root 4: silent wrong numbers --------------------------------------------------------------
X, Y, VX, VY = sympy.symbols("x y vx vy")


def test_mechanical_m_set_by_hand_is_checked_by_the_compiled_engine_too():
    from ldaspark.compiled.fast import mechanical_parts
    sysm = ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - X ** 2 / 2, [VX + VY], [X, Y], [VX, VY])
    sysm.mechanical = {"M": sympy.Matrix([[1, 1], [0, 1]]), "U": X ** 2 / 2, "K": sympy.Matrix([[1, 1]]),
                       "b": sympy.zeros(1, 1)}
    with pytest.raises(SystemDefinitionError, match="not symmetric"):
        mechanical_parts(sysm)
    sysm.mechanical = {"M": sympy.Matrix([[2, 0], [0, 1]]), "U": X ** 2 / 2, "K": sympy.Matrix([[1, 1]]),
                       "b": sympy.zeros(1, 1)}
    with pytest.raises(SystemDefinitionError, match="L_vv"):
        mechanical_parts(sysm)                   # symmetric, but not the M of L
    sysm.mechanical = {"M": sympy.eye(2), "U": X ** 2 / 2, "K": sympy.Matrix([[1, 1]]), "b": sympy.zeros(1, 1)}
    assert mechanical_parts(sysm)["M"] == sympy.eye(2)
