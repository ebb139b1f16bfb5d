"""Bounds and checks of ``ldaspark.core.validate`` at their edges: the stage ceiling
(``MAX_STAGES_CEILING`` = 100: 100 taken, 101 refused, naming the ceiling) and the future an
executor's ``submit`` returns (``submitted``: both ``result`` and ``cancel`` needed, each alone
refused)."""
from __future__ import annotations

import pytest

from ldaspark.core import validate
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark.core.tableau_file import check_stages


def test_the_stage_ceiling_is_100():
    assert validate.MAX_STAGES_CEILING == 100
    assert validate.check_max_stages(100) == 100
    with pytest.raises(InputError, match="max_stages"):
        validate.check_max_stages(101)
    check_stages(100, 100)                                    # at the ceiling: a limit it takes
    with pytest.raises(LdasparkError, match="between 1 and 100"):
        check_stages(3, 101)


class _Result:
    def result(self):
        return 1


class _Cancel:
    def cancel(self):
        return True


class _Both(_Result, _Cancel):
    pass


@pytest.mark.parametrize("future", [_Result(), _Cancel(), None, object()])
def test_a_submit_that_returns_no_future_is_refused(future):
    with pytest.raises(InputError, match="not a future"):
        validate.submitted(object(), future)


def test_a_future_with_result_and_cancel_is_taken():
    f = _Both()
    assert validate.submitted(object(), f) is f
