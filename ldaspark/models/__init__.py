"""The model library: the systems the suite integrates, apart from the solver that integrates them.

scenes (the scenes of section 8 and the general and nonideal ones: a system (1) with initial data,
closed forms and parameters; ``get_scene`` and the ``SCENES`` registry), systems_classic (classic
nonholonomic systems written with ``sympy.physics.mechanics``: Chaplygin sleigh and sphere, tilted
disk, Suslov, contact oscillator, ball on a turntable), bicycle (the Whipple bicycle) and
bicycle_benchmark (the linearised benchmark bicycle of Meijaard et al. 2007, Appendix A), kane_rolling (a rolling disc
and a Chaplygin ball written with Kane's minimal speeds, as KanesMethod models).

Imports ``ldaspark.core`` only.
"""
