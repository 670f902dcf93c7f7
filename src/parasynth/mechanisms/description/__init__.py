"""Mechanisms described in YAML, or in the equivalent Python dict.

A description gives a mechanism's design parameters (with units), its base and platform
anchor points (explicit or by patterns), its legs (types from :mod:`parasynth.model.legs`, joint
axes, actuated joint), its task coordinates and how they map to the platform pose, and its
pose constraints. :func:`description_class` turns it into a :class:`~parasynth.model.mechanism.Mechanism`
subclass whose ``Params`` is a frozen dataclass with ``UNITS``, so that
``load_mechanism("my_mech.yaml", radius=0.2)`` and YAML studies treat it like a built-in
model. The format is documented in ``docs/mechanisms.md``; a short example::

    name: my_3rps
    parameters: {base_radius: 300 mm, platform_radius: 150 mm, q_min: 300 mm, q_max: 700 mm}
    base:     {B: {pattern: polygon, n: 3, radius: base_radius}}
    platform: {A: {pattern: polygon, n: 3, radius: platform_radius}}
    legs:
      - {type: RPS, base: B, platform: A, r_axis: tangent, actuated: P}
    task:
      coordinates: {z: length, alpha: angle, beta: angle}
      define: {gamma: "-atan2(sin(alpha)*sin(beta), cos(alpha) + cos(beta))"}
      position: ["platform_radius/2*(R11 - R22)", "-platform_radius*R21", z]
      orientation: {convention: xyz, angles: [alpha, beta, gamma]}
      home: {z: 500 mm, alpha: 0 deg, beta: 0 deg}
    constraints:
      - {name: stroke, type: actuator_range, min: q_min, max: q_max}

Modules (one per section of a description)::

    errors.py       DescriptionError, DescriptionWarning
    expressions.py  the expression language (ast-based, no eval) and its dual numbers
    parameters.py   scalars with units, the parameters: section
    anchors.py      base: and platform: anchor sets and patterns
    legs.py         legs: leg types, joint axes, actuation
    task.py         task: coordinates, defined names, position, orientation
    constraints.py  constraints:
    variants.py     variants: named structural choices overlaid on the base description
    outputs.py      outputs: named pose quantities (tool points, dependent coordinates) as methods
    stiffness.py    stiffness: the legs' spring values (or the estimate's rod and material)
    schema.py       Description: the whole document, validated; the generated Params class
    mechanism.py    DescribedMechanism, DescribedMobility
    loading.py      description_class, load_description, from_description
"""

from __future__ import annotations

from .errors import DescriptionError, DescriptionWarning
from .expressions import POSE_NAMES, R_NAMES, RESERVED, UNIT_FACTORS, Expression, _Dual, _grad, _Scope, _val  # noqa: F401
from .parameters import _Param, _Scalar  # noqa: F401
from .legs import LEG_OPTIONS, PASSIVE_CAPABLE
from .constraints import ExpressionConstraint
from .schema import Description
from .mechanism import DescribedMechanism, DescribedMobility
from .loading import description_class, from_description, load_description

__all__ = [
    "DescriptionError",
    "DescriptionWarning",
    "DescribedMechanism",
    "DescribedMobility",
    "Description",
    "ExpressionConstraint",
    "Expression",
    "LEG_OPTIONS",
    "PASSIVE_CAPABLE",
    "POSE_NAMES",
    "R_NAMES",
    "RESERVED",
    "UNIT_FACTORS",
    "description_class",
    "load_description",
    "from_description",
]
