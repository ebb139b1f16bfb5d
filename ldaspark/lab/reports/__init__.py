"""The report writers of ``ldaspark report``: one module per section (convergence, energy with
fig4, claims, work_precision, stability with stability_checks / stability_scenes /
stability_figures), the driver and its job runner (jobs), and shared helpers: markdown (tables
with escaped cells, number formats), plotting (constrained layout, distinct colours), timing
(wall and CPU time), summary (the values README quotes).

Imports every layer below it (core, models, compiled, dist, solve, theory, claims); never
``ldaspark.cli``. The mutation catalogue is ``ldaspark.lab.mutants``.
"""
