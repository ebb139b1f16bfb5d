"""The report writers of ``ldaspark report``: one module per section (convergence, energy,
claims, work_precision, stability, fig4) and the driver.

Imports ``ldaspark.core``, ``ldaspark.theory`` and ``ldaspark.compiled``; never ``ldaspark.cli``.
"""
