"""Rules of ``ldaspark.lab.mutants.catalogue`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations
from system_fakes import _documented_defaults


# --- documented defaults and the precision the ledger reports ------------------------------------


def test_documented_defaults_are_the_signatures_defaults():
    """Where a docstring states a parameter's default, it is the one the signature has (a working
    precision or a step factor changed in one place and not the other misreports what ran)."""
    import ast
    import importlib
    import inspect
    import pkgutil

    import ldaspark
    seen, bad = 0, []
    for info in pkgutil.walk_packages(ldaspark.__path__, "ldaspark."):
        if info.name.startswith(("ldaspark.lab.mutants.catalogue", "ldaspark.__main__")):
            continue
        mod = importlib.import_module(info.name)
        for fname, obj in vars(mod).items():
            if not inspect.isfunction(obj) or obj.__module__ != mod.__name__:
                continue
            try:
                params = inspect.signature(obj).parameters
            except (TypeError, ValueError):
                continue
            for p, text in _documented_defaults(inspect.getdoc(obj)).items():
                if p not in params or params[p].default in (inspect.Parameter.empty, None):
                    continue          # None: the docstring names the value it stands for
                try:
                    want = ast.literal_eval(text)
                except (ValueError, SyntaxError):
                    continue
                seen += 1
                if params[p].default != want:
                    bad.append(f"{info.name}.{fname}({p}): documented {text}, signature {params[p].default!r}")
    assert seen >= 4 and not bad, bad
