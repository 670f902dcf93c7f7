"""Measures of a mechanism: sampled workspaces (:mod:`.workspace`), the usable workspace
(:mod:`.usable`), transmission, conditioning and statics (:mod:`.indices`), stiffness
(:mod:`.stiffness`), accuracy (:mod:`.accuracy`), dynamics (:mod:`.dynamics`), the registry of
named measures (:mod:`.objectives`, settings declared with :mod:`.measure_spec`), measures under
scatter (:mod:`.robustness`) and display units (:mod:`.display`)."""

from . import objectives
from . import task  # registers the task measures
from .dynamics import GRINDING_INERTIA, InertiaModel, force_decoupling, inverse_dynamics
from .indices import (StaticForces, global_conditioning_index, local_condition_number, local_transmission_index,
                      min_max_forces, pressure_angle_indices, singularity_margin_stats, static_forces,
                      transmission_indices, wrench_capability)
from .robustness import robust
from .stiffness import stiffness_matrix
from .workspace import WorkspaceResult, WorkspaceSample  # not the function workspace: it would hide the module

__all__ = ["objectives", "GRINDING_INERTIA", "InertiaModel", "force_decoupling", "inverse_dynamics", "StaticForces",
           "global_conditioning_index", "local_condition_number", "local_transmission_index", "min_max_forces",
           "pressure_angle_indices", "singularity_margin_stats", "static_forces", "transmission_indices",
           "wrench_capability", "robust", "stiffness_matrix", "WorkspaceResult", "WorkspaceSample"]
