from system_fakes import _binding
"""Rules of ``ldaspark.lab.mutants.mutation`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""


# --- fingerprints: every component of a run's identity ---------------------------------------------------


def test_the_catalogue_binds_every_setting_that_changes_a_verdict(monkeypatch):
    from ldaspark.lab.mutants import mutation
    m = [mutation.by_id(mutation.QUICK[0])]
    base = dict(hints_only=False, exclude=(), targets=None, timeout=300)
    fp0 = _binding(monkeypatch, lambda ck: mutation.run_catalogue(m, 1, checkpoint=ck, **base))
    for k, v in dict(hints_only=True, exclude=("tests/core/test_spark.py",), targets={m[0].id: ["tests/test_x.py"]},
                     timeout=60).items():
        fp = _binding(monkeypatch, lambda ck: mutation.run_catalogue(m, 1, checkpoint=ck, **dict(base, **{k: v})))
        assert fp != fp0, k       # a shorter timeout turns slow kills into timeouts: another verdict
