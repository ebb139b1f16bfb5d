"""Generated source is parsed and compiled one thread at a time (``gensource.SOURCE_LOCK``):
CPython 3.11 shares the AST constructor's recursion counter between threads (python/cpython#106905),
so two threads compiling models at once (an ensemble on a ThreadPoolExecutor) could fail with
"SystemError: AST constructor recursion depth mismatch", reported as a model that does not compile."""
import ast
import threading
import uuid

import pytest

from ldaspark.compiled import cache, native
from ldaspark.core import gensource
from ldaspark.core.gensource import SOURCE_LOCK


@pytest.fixture
def seen(monkeypatch):
    """Every parse and compile of the modules under test, recorded with whether the lock was held."""
    out = []
    real_parse, real_compile = ast.parse, compile

    def parse(*a, **k):
        out.append(("parse", SOURCE_LOCK._is_owned()))
        return real_parse(*a, **k)

    def comp(*a, **k):
        out.append(("compile", SOURCE_LOCK._is_owned()))
        return real_compile(*a, **k)
    monkeypatch.setattr(ast, "parse", parse)
    for mod in (gensource, native, cache):
        monkeypatch.setattr(mod, "compile", comp, raising=False)
    return out


def test_every_parse_and_compile_holds_the_lock(seen, tmp_path, monkeypatch):
    tag = uuid.uuid4().hex
    gensource._compile(f"a_{tag} = 1\n")
    native._tree.cache_clear()
    native._tree(f"b_{tag} = 2\n")
    native.python_module(f"c_{tag} = 3\n")
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(tmp_path / "c"))
    mod = cache.load_source(f"d_{tag} = 4\n")
    assert getattr(mod, f"d_{tag}") == 4
    kinds = {k for k, _ in seen}
    assert kinds == {"parse", "compile"} and len(seen) >= 4
    assert all(held for _, held in seen), seen


def test_the_recorder_sees_an_unlocked_parse(seen):
    # negative control: a parse outside the lock is recorded as such
    ast.parse("x = 1\n")
    assert seen == [("parse", False)]


def test_models_parsed_in_threads_at_once():
    """Eight threads turning distinct deep sources into modules at once: no SystemError."""
    errors = []
    start = threading.Barrier(8)

    def work(i):
        start.wait()
        try:
            for j in range(10):
                src = f"y_{i}_{j} = " + "+".join(f"({k} * 1.5)" for k in range(300)) + "\n"
                native.python_module(src)
        except Exception as exc:    # noqa: BLE001 (the failure is the finding)
            errors.append(repr(exc))
    threads = [threading.Thread(target=work, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors[:3]
