"""JSON booleans where a number belongs are refused, naming the value and what is expected
(docs/reliability.md "JSON booleans are not numbers"): NumPy reads true / false as 1.0 / 0.0."""
import json

import pytest

import ldaspark
from ldaspark.core.errors import InputError


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    res = ldaspark.integrate("particle", "gauss-1", t_span=(0, 1), h=0.5, engine="generic", params={})
    path = tmp_path_factory.mktemp("r") / "r.json"
    ldaspark.save_result(res, path)
    return json.loads(path.read_text())


@pytest.mark.parametrize("where", [("q", 0, 0), ("t", 0), ("v", 1, 2), ("energy", 2), ("constraint", 0, 0)])
@pytest.mark.parametrize("value", [True, False])
def test_a_boolean_in_an_array_is_refused(tmp_path, written, where, value):
    d = json.loads(json.dumps(written))
    slot = d[where[0]]
    for i in where[1:-1]:
        slot = slot[i]
    slot[where[-1]] = value
    p = tmp_path / "b.json"
    p.write_text(json.dumps(d))
    with pytest.raises(InputError) as ei:
        ldaspark.load_result(p)
    msg = str(ei.value)
    assert f"JSON boolean {str(value).lower()}" in msg and "not a number" in msg and where[0] in msg
    # negative control: the same place holding the number it stands for is read
    slot[where[-1]] = float(value)
    p.write_text(json.dumps(d))
    assert ldaspark.load_result(p).t.shape == (3,)


def test_a_boolean_parameter_value_is_refused(tmp_path, written):
    d = json.loads(json.dumps(written))
    d["params"] = {"m": True}
    p = tmp_path / "b.json"
    p.write_text(json.dumps(d))
    with pytest.raises(InputError, match=r"params\['m'\] is the JSON boolean true"):
        ldaspark.load_result(p)
    d["params"] = {"m": 1.0}
    p.write_text(json.dumps(d))
    assert ldaspark.load_result(p).params == {"m": 1.0}


def test_metadata_values_of_the_wrong_type_are_named_with_their_type(tmp_path):
    """A result file whose status is the string "0" was refused with "status must be an integer
    in -4..1 ..., got 0": the message printed the string without quotes, so it read as refusing a
    valid status. Now it names the type and the repr ("str '0'"). Control: the file with the
    integer 0 loads."""
    import json
    import ldaspark
    from ldaspark.core.errors import InputError
    r = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=3)
    path = tmp_path / "r.json"
    ldaspark.save_result(r, str(path))
    d = json.loads(path.read_text())
    assert ldaspark.load_result(str(path)).status == 0
    d["status"] = "0"
    path.write_text(json.dumps(d))
    with pytest.raises(InputError, match=r"status must be an integer in -4\.\.1 .*got str '0'"):
        ldaspark.load_result(str(path))


def test_saving_a_run_many_ensemble_says_how(tmp_path):
    """save_result(run_many's EnsembleResult) said only "needs a Result, got EnsembleResult"; it
    now names core.result.from_ensemble, and what that makes saves and loads back (control)."""
    import numpy as np
    import ldaspark
    from ldaspark.core.errors import InputError
    from ldaspark.core.result import from_ensemble
    from ldaspark.ensemble import RunSpec, run_many
    sc = ldaspark.get_scene("particle")
    t0, q0, v0 = (float(sc.initial()[0]), [float(x) for x in sc.initial()[1]], [float(x) for x in sc.initial()[2]])
    (ens,) = run_many([RunSpec(sc.system, "gauss-2", t0, [q0, q0], [v0, v0], 0.1, 4)])
    path = str(tmp_path / "e.npz")
    with pytest.raises(InputError, match="from_ensemble"):
        ldaspark.save_result(ens, path)
    ldaspark.save_result(from_ensemble(ens, method="gauss-2", h=0.1), path)
    assert np.array_equal(ldaspark.load_result(path).q, np.asarray(ens.q))
