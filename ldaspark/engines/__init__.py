"""The engines behind ``ldaspark.integrate``: one protocol (``Engine``, ``ldaspark.engines.base``)
and its implementations, registered in ``ENGINES``:

* ``"generic"`` (``GenericEngine``): the SPARK step (21a-f) in float64 or mpmath, step by step;
* ``"compiled"`` (``CompiledEngine``): the numba kernels (mechanical, general, sparse, the
  semi-implicit kernel (25), the root-finder kinds of ``compiled.runner.KIND_RUNNERS``), in blocks;
* ``"comparator"`` (``ComparatorEngine``): the comparators of sections 7-8, in blocks.

The driver (``ldaspark.solve``) chooses one, checks the root finder against it, runs the one
initial-point check and drives it; nothing else calls an engine. Walk of a system:
``solve.integrate`` -> ``solve._single`` (the driver) -> ``Engine.prepare`` / ``steps`` or ``run`` ->
``core.spark`` / ``compiled.fast.run_engine`` -> the kernels / ``core.comparators``.
"""
from .base import ENGINES, Engine, Prepared, Step, get_engine, register
from .comparator import ComparatorEngine
from .compiled import CompiledEngine
from .generic import GenericEngine

register(GenericEngine())
register(CompiledEngine())
register(ComparatorEngine())

__all__ = ["ENGINES", "Engine", "Prepared", "Step", "get_engine", "register", "GenericEngine", "CompiledEngine",
           "ComparatorEngine"]
