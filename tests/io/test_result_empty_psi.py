"""A run that fails at its first step (status < 0, S = 1 saved point) has psi of shape
(0, s, m): the engine forms the stage multipliers, there are none yet. Every format must give
that array back (an empty array of the same shape and kind), not None, which means "this engine
forms no psi" (the semi-implicit kernel of (25)): the reader turned every empty psi into None,
so the three formats' files of such a run read back as a different Result. Cost ~3 s."""
import warnings

import numpy as np
import pytest

import ldaspark
from ldaspark.core.resultio import load_result, save_result

FORMATS = (".json", ".npz", ".h5")


def _failed_at_step_0(**kw):
    # one Newton iteration cannot solve (21) at h = 0.5 (residual 0.5 after it): status -1 at step 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=kw.pop("h", 0.5),
                                  newton=ldaspark.Newton(max_iter=1), **kw)


@pytest.mark.parametrize("ext", FORMATS)
@pytest.mark.parametrize("kw", [dict(engine="generic"), dict(engine="compiled"), dict(h="0.5", dps=30)],
                         ids=["generic", "compiled", "dps30"])
def test_the_empty_psi_of_a_run_failed_at_step_0_round_trips(tmp_path, ext, kw):
    if ext == ".h5":
        pytest.importorskip("h5py")
    r = _failed_at_step_0(**kw)
    assert r.status < 0 and len(r.t) == 1 and r.psi is not None and r.psi.shape == (0, 2, 1)
    save_result(r, tmp_path / f"r{ext}")
    back = load_result(tmp_path / f"r{ext}")
    assert back.psi is not None, "an empty psi read back as None (no psi formed)"
    assert back.psi.shape == r.psi.shape and back.psi.dtype == r.psi.dtype
    assert (back.status, back.message) == (r.status, r.message)
    assert np.array_equal(np.asarray(back.q, float), np.asarray(r.q, float))


@pytest.mark.parametrize("ext", FORMATS)
def test_control_a_kernel_without_psi_still_reads_back_as_none(tmp_path, ext):
    """Control: the semi-implicit kernel of (25) forms no psi (None): it stays None."""
    if ext == ".h5":
        pytest.importorskip("h5py")
    r = ldaspark.integrate("skate", "lobatto-iiia-iiib-2", t_span=(0, 1), h=0.5, engine="compiled")
    assert r.psi is None
    save_result(r, tmp_path / f"r{ext}")
    assert load_result(tmp_path / f"r{ext}").psi is None


@pytest.mark.parametrize("ext", FORMATS)
def test_a_completed_run_keeps_its_psi(tmp_path, ext):
    """Control: a run with steps keeps psi bit for bit (the path the fix leaves alone)."""
    if ext == ".h5":
        pytest.importorskip("h5py")
    r = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.5, engine="generic")
    save_result(r, tmp_path / f"r{ext}")
    back = load_result(tmp_path / f"r{ext}")
    assert back.psi.shape == r.psi.shape == (2, 2, 1) and np.array_equal(back.psi, r.psi)


def test_a_json_psi_shape_that_does_not_fit_is_refused(tmp_path):
    """The .json key psi_shape (written for an empty psi only) is checked like every other field."""
    import json
    r = _failed_at_step_0(engine="generic")
    save_result(r, tmp_path / "r.json")
    d = json.loads((tmp_path / "r.json").read_text())
    assert d["psi"] == [] and d["psi_shape"] == [0, 2, 1]
    for bad in ([1, 2, 1], [0, -2, 1], "x", [0, 2], [True, 2, 1]):
        d["psi_shape"] = bad
        (tmp_path / "b.json").write_text(json.dumps(d))
        with pytest.raises(ldaspark.core.errors.LdasparkError, match="psi"):
            load_result(tmp_path / "b.json")


@pytest.mark.parametrize("ext", (".npz", ".h5"))
def test_an_ensemble_failed_at_step_0_keeps_its_members_empty_psi(tmp_path, ext):
    """Every member fails at step 0: each member's psi is (0, s, m); the batch's psi was None
    (``core.result.stack`` stacked psi only for S > 1), so the members read back from the file
    had psi None. The batch's psi is now (B, 0, s, m) and the members' come back as they were."""
    if ext == ".h5":
        pytest.importorskip("h5py")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.5, q0=[[0, 0, 0], [0, 0, 0]],
                               v0=[[1, 0, 1], [2, 0, 1]], newton=ldaspark.Newton(max_iter=1))
    assert list(r.status) == [-1, -1] and [m.psi.shape for m in r.members] == [(0, 2, 1)] * 2
    assert r.psi is not None and r.psi.shape == (2, 0, 2, 1)
    save_result(r, tmp_path / f"r{ext}")
    back = load_result(tmp_path / f"r{ext}")
    assert back.psi.shape == (2, 0, 2, 1)
    assert [m.psi.shape for m in back.members] == [(0, 2, 1)] * 2
