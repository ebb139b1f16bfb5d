"""Mutation catalogue, one module per area: each module defines ``MUTANTS``, a tuple of
``ldaspark.lab.mutants.mutation_catalogue.Mutant`` (built with its ``_m`` helper); the catalogue
collects them in module-name order (``mutation_catalogue._area_catalogues``)."""
