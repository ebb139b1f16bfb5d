"""Mutants of where work runs (``ldaspark.executors``: retries, failures by name) and of the lab's
checkpoints (``ldaspark.lab.checkpoint``: resume, fingerprint)."""
from ..mutant import _m

TD = "tests/ensemble/test_executors_dask.py"
KILLER = TD + "::test_a_unit_that_always_kills_its_worker_is_reported_by_name_and_the_rest_kept"
POOL = TD + "::test_a_worker_killed_mid_run_loses_nothing_on_the_local_pool"
RESUME = TD + "::test_a_rerun_resumes_from_the_checkpoint_of_a_failed_run"
ERROR = TD + "::test_an_error_in_a_unit_is_not_retried_and_names_the_unit"

MUTANTS = (
    _m("workers-retry-off-by-one", "executors.py",
       "if attempts[u.name] <= retries:", "if attempts[u.name] < retries:",
       "a unit whose worker died is retried one time fewer than promised", "workers", KILLER),
    _m("workers-lost-worker-is-an-error", "executors.py",
       'return isinstance(exc, BrokenProcessPool) or type(exc).__name__ in ("KilledWorker", "CommClosedError")',
       'return type(exc).__name__ in ("KilledWorker", "CommClosedError")',
       "a broken local pool (a worker killed) counted as the unit's own error: not retried", "workers", POOL),
    _m("workers-resume-ignored", "lab/checkpoint.py",
       "done = {u.name: done[u.name] for u in units if u.name in done}",
       "done = {}",
       "a rerun recomputes every unit instead of resuming from the checkpoint", "workers", RESUME),
    _m("workers-fingerprint-without-config", "lab/checkpoint.py",
       "h.update(json.dumps(config, sort_keys=True, default=str).encode())", "pass",
       "checkpoint fingerprint ignores the run's options: a run with other options resumes", "workers", RESUME),
    _m("workers-error-retried", "executors.py",
       "            if not _worker_lost(exc):\n                failed[u.name]",
       "            if False:\n                failed[u.name]",
       "a unit that raises is retried as if its worker had died (and runs again)", "workers", ERROR),
)
