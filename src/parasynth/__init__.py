"""parasynth: dimensional synthesis of parallel mechanisms.

Quick use::

    import parasynth
    mech = parasynth.load_mechanism("2rpu_2sps")
    ik = mech.inverse_kinematics(mech.home)
"""

from .legs import LEG_TYPES, PUS, RPS, RPU, SPS, UPS, UPU, Leg
from .mechanism import ForwardKinematicsError, IKResult, Mechanism, Mobility
from .mechanisms import list_mechanisms, load_mechanism

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
]
