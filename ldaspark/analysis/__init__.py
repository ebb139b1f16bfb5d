"""Analysis tools of the library: the discrete Lagrangian (13) and Theorem 1 residuals
(discrete), well-posedness of the boundary-value solve, symmetry (23), the exact conditions (22)
and (23) (conditions), order conditions by trees (order_conditions), the step map's Jacobian
(flow_jacobian) and the memo of repeated solves (memo).

Imports ``ldaspark.core``, ``ldaspark.models`` and ``ldaspark.solve``.
"""
