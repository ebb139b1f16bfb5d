"""``ldaspark.core.errors``: every LdasparkError's message is one line, whatever user text it
quotes. The exhaustive harness (tests/api/test_api_harness.py) drew ``load_result(path="\\n")``
and got "no such result file: \\n" back, two lines; the path is now quoted with its line break
escaped. Negative control: a plain Exception keeps the break."""
from __future__ import annotations

import pickle

import pytest

import ldaspark
from ldaspark.core.errors import InputError, LdasparkError, NewtonError, NonFiniteError, one_line

BREAKS = ["\n", "\r", "\r\n", "\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\u2029"]


@pytest.mark.parametrize("brk", BREAKS)
def test_every_line_break_becomes_an_escape(brk):
    for cls in (LdasparkError, InputError):
        msg = str(cls(f"no such file: a{brk}b"))
        assert len(msg.splitlines()) == 1 and msg.startswith("no such file: a") and msg.endswith("b")
    assert len(str(Exception(f"a{brk}b")).splitlines()) == 2          # the control


def test_controls_are_escaped_text_stays():
    assert one_line("a\x1b[31mb\x00c\x7fd") == "a\\x1b[31mb\\x00c\\x7fd"
    assert one_line("tab\tand ÆZu¡ and \\n") == "tab\tand ÆZu¡ and \\n"     # a tab, letters, a backslash
    assert one_line(one_line("a\nb")) == one_line("a\nb")                   # idempotent (pickling)


def test_subclasses_with_fields_keep_them_and_pickle():
    e = NewtonError("step\n3", step=3, time=0.5)
    assert str(e) == "step\\n3" and e.step == 3 and e.time == 0.5
    f = pickle.loads(pickle.dumps(NonFiniteError("x\ny", step=1)))
    assert str(f) == "x\\ny"
    assert LdasparkError().args == () and LdasparkError(3).args == (3,)     # a non-text message as it is


@pytest.mark.parametrize("path", ["\n", "a\nb.json", "x\u2028.json", "\x1b[2J.json"])
def test_load_result_and_load_tableau_name_such_paths_in_one_line(path):
    for fn in (ldaspark.load_result, ldaspark.load_tableau):
        with pytest.raises(LdasparkError) as ei:
            fn(path)
        msg = str(ei.value)
        assert msg and len(msg.splitlines()) == 1 and "\x1b" not in msg, msg


def test_the_command_line_prints_the_escaped_path(capsys, tmp_path):
    from ldaspark.cli import main
    rc = main(["audit", str(tmp_path / "a\nb.json")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "a\\nb.json" in err, err


def test_a_warning_quoting_a_name_is_one_line_too():
    """The neighbour of the path in an error: a user's parameter name in an LdasparkWarning
    (``params={"a\\nb": 1.0}``: not a parameter of the skate). Control: a plain UserWarning."""
    import warnings

    from ldaspark.core.errors import LdasparkWarning
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=2, engine="generic", params={"a\nb": 1.0})
    msgs = [str(x.message) for x in w if issubclass(x.category, LdasparkWarning)]
    assert msgs and all(len(m.splitlines()) == 1 for m in msgs) and "a\\nb" in msgs[0], msgs
    assert len(str(UserWarning("a\nb")).splitlines()) == 2
