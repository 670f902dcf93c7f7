"""The optimisers, one module each (sweep, nlopt, optuna, scipy, ...), registered by kind; the
contract and the registry are in :mod:`parasynth.study.optimizers.base`."""

from .base import ALGORITHMS, BaseOptimizer, kinds, optimizer_class, register, registered

__all__ = ["ALGORITHMS", "BaseOptimizer", "kinds", "optimizer_class", "register", "registered"]
