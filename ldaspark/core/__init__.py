"""The solver core: what a SPARK integration of (1) needs and nothing more.

errors (exception hierarchy), backend (float64 / mpmath arithmetic), tableau (SparkTableau (21),
the families gauss / lobatto_iiia_iiib / lobatto_iiia_iiib_iiid / euler_i / euler_ii, the method
registry ``get_method``, tableau files), system (LagrangianSystem: L, k and what sympy derives from
them), spark (the step (21a-f) and the loop ``integrate``), comparators (sections 7-8), io (atomic
file writes), result (the Result type of every engine), dense (dense output and events), resultio
(Result files .json / .npz / .h5), mechanics (adapter from sympy.physics.mechanics models),
validate (argument checks shared with the compiled path).

Imports only numpy, scipy, mpmath, sympy and itself: the bottom layer (the scenes are in
``ldaspark.models``, distribution in ``ldaspark.dist``).
"""
