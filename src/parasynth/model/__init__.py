"""The NumPy model of a parallel mechanism, the reference for every compiled evaluation:
rotations and screws (:mod:`.spatial`), leg types (:mod:`.legs`), the mechanism (:mod:`.mechanism`),
pose constraints as margins (:mod:`.constraints`) and the geometry checks of a mechanism's
parameters (:mod:`.geometry_checks`). It imports only :mod:`parasynth.common`."""

from .legs import CAPABILITIES, LEG_TYPES, PRS, PUS, RPS, RPU, RUS, SPS, UPS, UPU, Leg, LegCapabilities, LegCapabilityError
from . import chains  # noqa: F401  (registers the chain limbs of the vocabulary in LEG_TYPES)
from .mechanism import EngineFallbackWarning, ForwardKinematicsError, IKResult, Mechanism, Mobility

__all__ = ["CAPABILITIES", "LegCapabilities", "LegCapabilityError",
           "LEG_TYPES", "PRS", "PUS", "RPS", "RPU", "RUS", "SPS", "UPS", "UPU", "Leg", "EngineFallbackWarning",
           "ForwardKinematicsError", "IKResult", "Mechanism", "Mobility"]
