"""The manual: numpydoc docstrings on every public name, their examples, the tutorials, and the
Sphinx build with warnings as errors (offline)."""
from __future__ import annotations

import doctest
import inspect
import os
import pathlib
import re

import pytest

import ldaspark
import ldaspark.plot

ROOT = pathlib.Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
TUTORIALS = sorted((DOCS / "tutorials").glob("*.md"))
#: the sections a numpydoc reader expects: every parameter documented (PR01) and no phantom one
#: (PR02), a Returns section (RT01), a one-line summary (SS01), a docstring (GL08), an example (EX01)
CHECKS = {"PR01", "PR02", "RT01", "SS01", "GL08", "EX01"}


def _public_objects():
    out = []
    for name in ldaspark.__all__:
        if name in ("__version__", "plot"):
            continue
        out.append((f"ldaspark.{name}", getattr(ldaspark, name)))
    for name, fn in inspect.getmembers(ldaspark.plot, inspect.isfunction):
        if fn.__module__ == "ldaspark.plot" and not name.startswith("_"):
            out.append((f"ldaspark.plot.{name}", fn))
    return out


PUBLIC = _public_objects()


def _numpydoc_errors(obj_name):
    validate = pytest.importorskip("numpydoc.validate")
    res = validate.validate(obj_name)
    return [(code, msg) for code, msg in res["errors"] if code in CHECKS
            and not (code == "RT01" and inspect.isclass(_resolve(obj_name)))]


def _resolve(obj_name):
    mod, _, attr = obj_name.rpartition(".")
    return getattr(__import__(mod, fromlist=[attr]), attr)


@pytest.mark.parametrize("obj_name", [n for n, _ in PUBLIC])
def test_public_docstring_is_numpydoc(obj_name):
    assert _numpydoc_errors(obj_name) == []


def test_numpydoc_check_sees_an_undocumented_parameter():
    # negative control: a docstring without Parameters / Returns / Examples is reported
    assert {c for c, _ in _numpydoc_errors("tests.project.test_docs._prose_only")} >= {"PR01", "RT01", "EX01"}


def _prose_only(system, h):
    """Integrate system with step h and return the result."""
    return system, h


@pytest.mark.parametrize("obj_name,obj", PUBLIC, ids=[n for n, _ in PUBLIC])
def test_public_docstring_examples_run(obj_name, obj, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    tests = doctest.DocTestFinder(recurse=False).find(obj, obj_name, globs={})
    examples = [ex for t in tests for ex in t.examples]
    assert examples, f"{obj_name} has no example"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for t in tests:
        runner.run(t)
    assert runner.summarize(verbose=False).failed == 0


def test_doctest_runner_fails_on_a_wrong_example():
    # negative control of the runner above: a wrong expected output counts as a failure
    t = doctest.DocTestParser().get_doctest(">>> 1 + 1\n3\n", {}, "bad", "bad", 0)
    runner = doctest.DocTestRunner()
    runner.run(t, out=lambda s: None)
    assert runner.summarize(verbose=False).failed == 1


def _blocks(path):
    return re.findall(r"```python\n(.*?)```", path.read_text(), re.S)


@pytest.mark.parametrize("path", TUTORIALS, ids=[p.stem for p in TUTORIALS])
def test_tutorial_runs(path, tmp_path, monkeypatch, capsys):
    if path.stem == "mechanics_dask":
        pytest.importorskip("distributed")
    blocks = _blocks(path)
    assert len(blocks) >= 2 and any("assert" in b for b in blocks)
    monkeypatch.chdir(tmp_path)
    ns = {"__name__": "__tutorial__"}
    for b in blocks:
        exec(compile(b, str(path), "exec"), ns)


def test_four_tutorials_and_an_api_page_for_every_public_name():
    assert {p.stem for p in TUTORIALS} == {"first_system", "audit_tableau", "convergence_report",
                                           "mechanics_dask"}
    index = (DOCS / "api" / "index.rst").read_text()
    for name, _ in PUBLIC:
        short = name.split(".", 1)[1]
        page = "plot" if short.startswith("plot.") else short
        assert (DOCS / "api" / f"{page}.rst").is_file(), name
        assert re.search(rf"^\s+{re.escape(page)}$", index, re.M), name
    toc = (DOCS / "index.md").read_text()
    for note in ("verification", "audit", "convergence", "stability", "performance", "reliability"):
        assert note in toc and (DOCS / f"{note}.md").is_file()


def test_sphinx_build_has_no_warning(tmp_path):
    pytest.importorskip("numpydoc")
    pytest.importorskip("myst_parser")
    pytest.importorskip("pydata_sphinx_theme")
    build = pytest.importorskip("sphinx.cmd.build")
    out = tmp_path / "html"
    rc = build.build_main(["-W", "--keep-going", "-E", "-a", "-q", "-b", "html", str(DOCS), str(out),
                           "-d", str(tmp_path / "doctrees")])
    assert rc == 0
    assert (out / "api" / "integrate.html").is_file()
    assert "Parameters" in (out / "api" / "integrate.html").read_text(encoding="utf-8")


def test_first_system_tutorial_says_what_the_disk_energy_does():
    """The vertical rolling disk of docs/tutorials/first_system.md: the tutorial said its energy
    error "stays bounded and shrinks like h^4", but gauss-2 keeps the energy (8) exactly (the
    rolling and turning speeds stay constant): max |E - E0| over [0, 10] is 0 at 30 digits for
    h = 0.5, 0.25 and 0.125 (no h^4 to see); the text must say round-off, not an order."""
    import sympy

    import ldaspark
    x, y, th, ph = sympy.symbols("x y theta phi")
    vx, vy, vth, vph = sympy.symbols("vx vy vtheta vphi")
    L = (vx ** 2 + vy ** 2) / 2 + vth ** 2 / 4 + vph ** 2 / 8
    k = [vx - sympy.cos(ph) * vth, vy - sympy.sin(ph) * vth]
    disk = ldaspark.LagrangianSystem(L, k, [x, y, th, ph], [vx, vy, vth, vph], name="disk")
    for h in ("0.5", "0.25"):
        r = ldaspark.integrate(disk, "gauss-2", t_span=(0, 10), q0=[0, 0, 0, 0], v0=[1, 0, 1, 0.5], h=h, dps=30)
        assert max(abs(e - r.energy[0]) for e in r.energy) <= 1e-28
    text = (DOCS / "tutorials" / "first_system.md").read_text()
    assert "shrinks like h^4" not in text and "round-off at every step size" in text
