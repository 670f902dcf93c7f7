"""Foundations that import no other part of parasynth: quantities with units and the one units
table (:mod:`.units`), argument checks and resource limits (:mod:`.validation`), the safe YAML
reader (:mod:`.yamlio`), quasi-random samples (:mod:`.qmc`) and Pareto maths (:mod:`.pareto`)."""
