"""Shared pytest options: --exhaustive runs the slow sweeps; hypothesis profile "ci"
(derandomized, no deadline) is the default. A run of many tests (or under pytest-xdist, ``-n 2``)
first compiles the package's four numba kernels, two processes at a time, into numba's on-disk
cache: on a fresh checkout they cost ~170 s CPU (spark_run, general_run and spark_sparse_run
~50 s each, lf2_run ~11 s), which the test that happens to need each first would otherwise pay,
and under xdist every worker would pay for the same kernel at the same time."""
import os
import sys

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile("ci", derandomize=True, deadline=None, max_examples=25,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("dev", deadline=None, max_examples=100)
settings.load_profile("ci")

# no background build of the specialised quasi-Newton kernels (ldaspark.compiled.specialised) while
# the suite runs: it would take one of the 2 cores for ~30 s at a moment that depends on the order
# of the tests. tests/compiled/test_specialised.py turns it on where it is the subject.
os.environ["LDASPARK_SPECIALISE"] = "0"

# tests/ mirrors the package in folders; their shared helpers (run_helpers, *_fakes) live in tests/
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "tests"))


def pytest_addoption(parser):
    parser.addoption("--exhaustive", action="store_true", default=False,
                     help="run the exhaustive sweeps (marker 'exhaustive')")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--exhaustive"):
        return
    skip = pytest.mark.skip(reason="exhaustive sweep: run with --exhaustive")
    for item in items:
        if "exhaustive" in item.keywords:
            item.add_marker(skip)


#: warm the kernels before a run of at least this many tests (a single file runs without it)
WARM_MIN_TESTS = 300
#: the two processes' shares, balanced by their compile times on a fresh checkout
WARM_GROUPS = (("spark_run", "lf2_run"), ("general_run", "spark_sparse_run"))


def _warm_kernels_in_parallel():
    if os.environ.get("LDASPARK_TEST_NO_WARM"):
        return
    from ldaspark.compiled.fast import warm_kernels      # a package function: the pool pickles it
    from ldaspark.core.lifecycle import make_process_pool
    with make_process_pool(max_workers=len(WARM_GROUPS)) as ex:
        list(ex.map(warm_kernels, WARM_GROUPS))


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_setupnodes(config, specs):
    """Under xdist: before the workers start (the controller runs no test)."""
    _warm_kernels_in_parallel()


def pytest_collection_finish(session):
    """Without xdist: once the run is known to be large."""
    if not hasattr(session.config, "workerinput") and not session.config.pluginmanager.hasplugin("dsession") \
            and len(session.items) >= WARM_MIN_TESTS:
        _warm_kernels_in_parallel()
