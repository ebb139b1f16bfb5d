"""Result files (.json contract, .npz, .h5) read back by load_result; the CLI's --out, --engine
and --every; plots that never touch the backend; packaging."""
import re
import builtins
import json
import os

import numpy as np
import pytest

import ldaspark
from ldaspark.cli import main
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark.core.resultio import load_result, save_result

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture(scope="module")
def res():
    return ldaspark.integrate("skate", "gauss-2", n_steps=6, h=0.1, engine="generic")


@pytest.mark.parametrize("ext", [".json", ".npz", ".h5"])
def test_roundtrip(res, tmp_path, ext):
    p = tmp_path / f"r{ext}"
    save_result(res, p)
    back = load_result(p)
    for name in ("t", "q", "v", "energy", "constraint", "psi"):
        assert np.array_equal(getattr(back, name), getattr(res, name)), name
    assert (back.method, back.scene, back.h, back.dps, back.status, back.engine) == \
           ("gauss-2", "skate", 0.1, None, 0, "generic")
    assert back.nfev == res.nfev and back.success


def test_roundtrip_mpmath_keeps_digits(tmp_path):
    r = ldaspark.integrate("skate", "gauss-2", n_steps=2, h="0.1", dps=40)
    for ext in (".npz", ".json"):
        save_result(r, tmp_path / f"m{ext}")
        back = load_result(tmp_path / f"m{ext}")
        assert back.dps == 40 and back.q.dtype == object
        import mpmath
        with mpmath.workdps(40):
            assert abs(back.q[-1, 0] - r.q[-1, 0]) < mpmath.mpf(10) ** -38


def test_h5_without_h5py_is_a_clear_error(res, tmp_path, monkeypatch):
    real = builtins.__import__

    def no_h5py(name, *a, **k):
        if name == "h5py":
            raise ImportError("no h5py")
        return real(name, *a, **k)
    monkeypatch.setattr(builtins, "__import__", no_h5py)
    with pytest.raises(InputError, match=r"ldaspark\[h5\]"):
        save_result(res, tmp_path / "r.h5")
    assert not (tmp_path / "r.h5").exists()


def test_other_extension_is_json_and_bad_file(res, tmp_path):
    save_result(res, tmp_path / "r.txt")
    assert json.loads((tmp_path / "r.txt").read_text())["method"] == "gauss-2"
    assert np.array_equal(load_result(tmp_path / "r.txt").q, res.q)
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="cannot read"):
        load_result(tmp_path / "bad.npz")


def test_ensemble_npz(tmp_path):
    ens = ldaspark.integrate("particle", "gauss-1", n_steps=3, h=0.1, q0=[[1, 0, 0], [2, 0, 0]],
                             v0=[[0, 1, 0], [0, 2, 0]], engine="generic")
    save_result(ens, tmp_path / "e.npz")
    back = load_result(tmp_path / "e.npz")
    assert back.q.shape == (2, 4, 3) and np.array_equal(back.q, ens.q) and list(back.status) == [0, 0]


@pytest.mark.parametrize("ext", [".npz", ".h5"])
def test_an_ensemble_with_a_failed_member_reads_back_as_saved(tmp_path, ext):
    """An ensemble's file kept the padded arrays and statuses but not ``n_valid`` nor the members:
    the loaded Result had batch None, n_valid None (the repeated rows after a failure looked like
    valid samples) and its raise_for_status raised numpy's ValueError ("truth value of an array is
    ambiguous") instead of the member's failure. Now n_valid is in the metadata and the members are
    rebuilt from their valid rows."""
    import sympy as sp
    x, y, vx, vy = sp.symbols("x y vx vy")
    # U = sqrt(x): the second member walks into x < 0 (a step failure), the first does not
    root = ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - sp.sqrt(x), [vy - x * vx], [x, y], [vx, vy],
                                     name="root")
    ens = ldaspark.integrate(root, "gauss-2", t_span=(0, 2), h=0.1, q0=[[1.0, 0.0], [0.3, 0.0]],
                             v0=[[0.1, 0.1], [-1.0, -0.3]], guard=False, engine="generic")
    assert ens.status[0] == 0 and ens.status[1] < 0 and ens.n_valid[1] < ens.n_valid[0]
    save_result(ens, tmp_path / f"e{ext}")
    back = load_result(tmp_path / f"e{ext}")
    assert back.batch == ens.batch == 2 and list(back.n_valid) == list(ens.n_valid)
    for a, b in zip(ens.members, back.members):
        assert (a.status, a.message, a.nfev, a.method, a.h) == (b.status, b.message, b.nfev, b.method, b.h)
        for name in ("t", "q", "v", "energy", "constraint", "psi"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
    with pytest.raises(LdasparkError, match="step"):
        back.raise_for_status()
    ok = ldaspark.integrate("particle", "gauss-1", n_steps=3, h=0.1, q0=[[1, 0, 0], [2, 0, 0]],
                            v0=[[0, 1, 0], [0, 2, 0]], engine="generic")
    save_result(ok, tmp_path / f"ok{ext}")
    assert load_result(tmp_path / f"ok{ext}").raise_for_status().success


@pytest.mark.parametrize("method, engine", [("gauss-2", "compiled"), ("gauss-2", "generic"),
                                            ("gauss-irk-2", "generic")])
def test_a_member_failing_in_its_first_step_keeps_the_others_multipliers(tmp_path, method, engine):
    """A member that failed in step 0 had psi None on the compiled engine (and for a comparator):
    the batch psi became None, and the file lost every member's multipliers."""
    import sympy as sp
    x, y, vx, vy = sp.symbols("x y vx vy")
    root = ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - sp.sqrt(x), [vy - x * vx], [x, y], [vx, vy],
                                     name="root")
    # the second member leaves x >= 0 within its first step (x0 = 0.02, vx = -1, h = 0.1)
    ens = ldaspark.integrate(root, method, t_span=(0, 2), h=0.1, q0=[[1.0, 0.0], [0.02, 0.0]],
                             v0=[[0.1, 0.1], [-1.0, -0.02]], guard=False, engine=engine)
    assert list(ens.status) == [0, -3] and list(ens.n_valid) == [21, 1]
    good = ens.members[0].psi
    assert good is not None and good.shape == (20, 2, 1)
    assert ens.psi is not None and np.array_equal(ens.psi[0], good) and not ens.psi[1].any()
    save_result(ens, tmp_path / "e.npz")
    back = load_result(tmp_path / "e.npz")
    assert np.array_equal(back.psi, ens.psi) and np.array_equal(back.members[0].psi, good)
    assert len(back.members[1].psi) == 0


@pytest.mark.parametrize("ext", [".npz", ".h5"])
def test_an_ensembles_events_and_dense_output_read_back(tmp_path, ext):
    """save_result dropped an ensemble's events and dense output without a word (the loaded
    Result had t_events [] and sol None, the saved one an event per member and an EnsembleDense);
    now each member's are stored under member<j>_ and the batch's rebuilt from them."""
    def down(t, q, v):
        return q[0] + 0.1
    down.direction = -1
    ens = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.1, engine="generic", events=[down],
                             q0=[[0, 0, 0], [0.05, 0, 0]], v0=[[0, 0, 1.0], [0, 0, 1.0]], dense_output=True)
    assert [len(te) for te in ens.t_events[0]] == [1, 1] and ens.sol is not None
    save_result(ens, tmp_path / f"e{ext}")
    back = load_result(tmp_path / f"e{ext}")
    for name in ("t_events", "q_events", "v_events"):
        got, want = getattr(back, name), getattr(ens, name)
        assert len(got) == len(want) == 1 and all(np.array_equal(a, b) for a, b in zip(got[0], want[0])), name
    tt = np.linspace(0, 1, 13)
    assert all(np.array_equal(a, b) for a, b in zip(ens.sol(tt), back.sol(tt)))
    assert np.array_equal(back.members[1].t_events[0], ens.members[1].t_events[0])


def test_cli_npz_engines_agree_and_every(tmp_path):
    a, b, c = (tmp_path / n for n in ("a.npz", "b.h5", "c.json"))
    base = ["integrate", "particle", "gauss-2", "--h", "0.01", "--t-end", "1"]
    assert main(base + ["--out", str(a)]) == 0
    assert main(base + ["--engine", "generic", "--out", str(b)]) == 0
    ra, rb = load_result(a), load_result(b)
    assert ra.engine == "compiled" and rb.engine == "generic" and len(ra.t) == 101
    assert np.abs(ra.q - rb.q).max() < 1e-12 and np.abs(ra.v - rb.v).max() < 1e-12
    assert main(base + ["--engine", "generic", "--every", "10", "--out", str(c)]) == 0
    d = json.loads(c.read_text())
    assert len(d["t"]) == 11 and np.array_equal(np.array(d["q"]), rb.q[::10])
    assert len(d["psi"]) == 10 and d["stats"]["steps"] == 100
    for key in ("scene", "method", "h", "dps", "t", "q", "v", "energy", "constraint", "psi", "stats"):
        assert key in d


def test_cli_step_failure_is_one_line_and_no_file(tmp_path, capsys):
    """The CLI keeps its contract (exit 2, one line, no file); the library keeps the prefix."""
    out = tmp_path / "f.npz"
    # h = 6 (measured: the compiled engine fails at step 8 with the quasi-Newton root finder, at
    # step 9 with the kernels' Newton); at h = 2 the compiled engine's fallback chain finishes the
    # run, as the generic engine does
    rc = main(["integrate", "robot", "gauss-2", "--h", "6", "--t-end", "240", "--engine", "compiled",
               "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and re.search(r"at step \d+, t = ", err[0]) and not out.exists()


def test_plots_never_touch_the_backend(res):
    import matplotlib
    from matplotlib.axes import Axes
    import ldaspark.plot as lp
    backend = matplotlib.get_backend()
    dense = ldaspark.integrate("skate", "gauss-2", n_steps=6, h=0.1, engine="generic", dense_output=True)
    axes = [lp.energy(res), lp.constraint(res), lp.trajectory(dense, 0, 1)]
    assert all(isinstance(ax, Axes) for ax in axes)
    assert matplotlib.get_backend() == backend
    assert len(axes[2].lines) == 2 and len(axes[0].lines) == 1
    from matplotlib.figure import Figure
    ax = Figure().add_subplot()
    assert lp.energy(res, ax=ax) is ax
    with pytest.raises(InputError):
        lp.trajectory(res, 0, 5)
    import inspect
    import ldaspark.lab.reports as reports
    for name in ("convergence", "energy", "stability", "work_precision", "fig4"):
        src = inspect.getsource(__import__(f"ldaspark.lab.reports.{name}", fromlist=["x"]))
        assert "matplotlib.use(" not in src, name


def test_packaging(capsys):
    assert open(os.path.join(ROOT, "LICENSE")).read().startswith("MIT License")
    import importlib.resources as ir
    assert (ir.files("ldaspark") / "py.typed").is_file()
    from ldaspark.lab.theory.audit import example_names, example_path
    assert "gauss2" in example_names() and example_path("gauss2").is_file()
    shipped = os.listdir(os.path.join(ROOT, "examples", "tableaux"))
    assert sorted(n[:-5] for n in shipped if n.endswith(".json")) == example_names()
    for n in example_names():          # the package data are copies of examples/tableaux
        assert example_path(n).read_text() == open(os.path.join(ROOT, "examples", "tableaux", n + ".json")).read()
    with pytest.raises(InputError, match="unknown example"):
        example_path("nope")
    with pytest.raises(SystemExit):
        main(["--version"])
    assert ldaspark.__version__ in capsys.readouterr().out
