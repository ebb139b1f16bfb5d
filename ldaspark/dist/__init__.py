"""Where work runs: workers (one way to name a local pool, a Dask scheduler or any Executor, with
retries, failures by name and checkpoints) and ensemble (many initial data of one system over an
executor, ``run_many``). The claims ledger, the mutation catalogue and the report jobs hand their
work units to ``workers`` as well.

Imports ``ldaspark.core``, ``ldaspark.models`` and ``ldaspark.compiled``.
"""
