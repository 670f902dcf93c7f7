"""Structural synthesis: which limbs, actuated where and arranged how, give a motion type.

:mod:`.vocabulary` holds the limb types (a registry), their arrangements, the shared
parametrisation and the motion templates; :mod:`.synthesis` enumerates candidates from it, writes
each as a mechanism description and checks it numerically. See docs/structures.md.

This layer sits above the mechanism registry (it builds described mechanisms) and below the
study layer.
"""

import sys
import types

from .synthesis import (DROP_REASONS, EQUIVALENT_LIMBS, MAX_POSE_CHECKS, MAX_POSES, MAX_STRUCTURE_LEGS,
                        SINGULARITY_FLOOR, Group, Structure, StructureList, candidates, parse_axes, structures,
                        verdict_text)
from .vocabulary import (ARRANGEMENTS, HOME_TILTS, LIMB_TYPES, PARAMETERS, TEMPLATES, Arrangement, LimbType,
                         StructureError, StructureWarning, Template, limb_type, parse_motion, register_limb)

__all__ = ["structures", "Structure", "StructureList", "Group", "candidates", "parse_axes", "DROP_REASONS", "LIMB_TYPES",
           "EQUIVALENT_LIMBS", "SINGULARITY_FLOOR", "HOME_TILTS", "verdict_text",
           "ARRANGEMENTS", "PARAMETERS", "TEMPLATES", "Arrangement", "LimbType", "Template", "limb_type",
           "parse_motion", "register_limb", "StructureError", "StructureWarning", "MAX_POSES", "MAX_POSE_CHECKS",
           "MAX_STRUCTURE_LEGS"]


class _StructuresModule(types.ModuleType):
    """``parasynth.structures`` is this package and, called, :func:`structures`: the package
    keeps its name (``import parasynth.structures``, ``parasynth.structures.LIMB_TYPES``) and
    ``parasynth.structures("3T2R", ...)`` enumerates."""

    def __call__(self, motion, **kwargs) -> StructureList:
        return structures(motion, **kwargs)


_StructuresModule.__call__.__doc__ = structures.__doc__
sys.modules[__name__].__class__ = _StructuresModule
