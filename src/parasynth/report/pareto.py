"""Former home of the Pareto maths, kept so that ``parasynth.report.pareto`` still imports:
everything is defined in :mod:`parasynth.common.pareto`."""

from ..common.pareto import (NoisyComparison, ReferenceStanding, compare_with_noise, crowding_distance,  # noqa: F401
                             default_reference_point, dominates, dominators_of, hypervolume, knee_index,
                             non_dominated_ranks, pareto_mask, reference_standing, spread_by_crowding, to_min)

__all__ = ["to_min", "dominates", "dominators_of", "non_dominated_ranks", "pareto_mask", "hypervolume",
           "default_reference_point", "knee_index", "crowding_distance", "spread_by_crowding", "ReferenceStanding",
           "reference_standing", "NoisyComparison", "compare_with_noise"]
