"""parasynth: dimensional synthesis of parallel mechanisms.

Quick use::

    import parasynth
    mech = parasynth.load_mechanism("2rpu_2sps")
    ik = mech.inverse_kinematics(mech.home)
"""

from .model.legs import LEG_TYPES, PRS, PUS, RPS, RPU, RUS, SPS, UPS, UPU, Leg
from .model.mechanism import ForwardKinematicsError, IKResult, Mechanism, Mobility
from .mechanisms import list_mechanisms, load_mechanism
from .measures.workspace import WorkspaceResult, workspace
from .measures.indices import (StaticForces, global_conditioning_index, local_condition_number,
                               local_transmission_index, min_max_forces, pressure_angle_indices,
                               singularity_margin_stats, static_forces, transmission_indices, wrench_capability)
from .measures.stiffness import stiffness_matrix
from .measures.dynamics import GRINDING_INERTIA, InertiaModel, force_decoupling, inverse_dynamics
from .measures.robustness import robust
from . import structures  # the package, callable as parasynth.structures(motion, ...)
from .structures import Structure
from .measures import objectives
from .model.task import Task, TaskError
from . import _compat

_compat.install()  # the flat module paths of earlier releases import the same modules

__version__ = "0.1.0"

__all__ = [
    "list_mechanisms",
    "load_mechanism",
    "Mechanism",
    "IKResult",
    "Mobility",
    "ForwardKinematicsError",
    "Leg",
    "LEG_TYPES",
    "SPS",
    "UPS",
    "PUS",
    "RPU",
    "RPS",
    "UPU",
    "PRS",
    "RUS",
    "structures",
    "Structure",
    "workspace",
    "WorkspaceResult",
    "StaticForces",
    "static_forces",
    "min_max_forces",
    "wrench_capability",
    "transmission_indices",
    "local_transmission_index",
    "pressure_angle_indices",
    "local_condition_number",
    "global_conditioning_index",
    "singularity_margin_stats",
    "InertiaModel",
    "GRINDING_INERTIA",
    "inverse_dynamics",
    "force_decoupling",
    "stiffness_matrix",
    "robust",
    "objectives",
    "Task",
    "TaskError",
]
