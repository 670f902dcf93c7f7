"""What a design of a study is, in one place, below the study schema and the evaluator:

* :func:`design_params` -- design values -> the mechanism's parameters (the study's fixed
  parameters, the design variables, and the tied parameters that follow a variable);
* :func:`design_key` -- the identity of a design (two rows or records with the same key are
  the same design);
* :func:`box_centre` -- the centre of the variable box (log scale and integers respected);
* :func:`measure_settings` -- the settings a measure is called with for a design: the study's
  workspace sample where the measure takes it, then the measure's own settings.

The functions take a resolved study (:class:`~parasynth.study.spec.ResolvedStudy`) by its
attributes; of the study layer this module imports only the design space
(:mod:`parasynth.study.space`, where the identity and the centre are defined).
"""

from __future__ import annotations

from ..objectives import get as get_measure
from .space import BOX_CENTRE_U, DesignSpace, centre_value
from .space import design_key as key_of

__all__ = ["design_params", "design_key", "BOX_CENTRE_U", "centre_value", "box_centre", "measure_settings",
           "WORKSPACE_SETTINGS"]


def design_params(study, values: dict) -> dict:
    """Parameters of the mechanism for design ``values``: the fixed parameters, the design
    values, and each tied parameter set to the variable it follows."""
    params = {**study.fixed, **values}
    for k, src in study.tied.items():
        if src in values:
            params[k] = values[src]
    return params


def design_key(study, values) -> tuple:
    """Identity of a design of ``study`` (:func:`parasynth.study.space.design_key` over the
    study's variables). ``values`` is a mapping or a table row."""
    return key_of(study.variables, values)


def box_centre(study) -> dict:
    """The centre of the variable box, {variable: value} (see :func:`centre_value`)."""
    return DesignSpace(study.variables).centre()


#: Study evaluation keys -> measure setting names: the workspace sample shared by the measures.
WORKSPACE_SETTINGS = {"ranges": "ranges", "n": "n", "method": "method", "seed": "seed", "fixed": "fixed",
                      "constraints": "constraints", "engine": "engine"}


def measure_settings(study, measure_name: str, own: dict, n: int | None = None, seed: int | None = None) -> dict:
    """Settings of measure ``measure_name``: the study's evaluation settings the measure takes
    (``n`` and ``seed`` replaced when given), then ``own`` (the objective's or constraint's
    settings), then ``n`` and ``seed`` again when given (they win over ``own``)."""
    m = get_measure(measure_name)
    ev = study.evaluation
    base = {}
    for key in WORKSPACE_SETTINGS:
        if key in m.settings:
            v = ev.get(key)
            if key == "n" and n is not None:
                v = n
            if key == "seed" and seed is not None:
                v = seed
            if v is not None:
                base[key] = v
    base.update(own)
    if n is not None and "n" in m.settings:
        base["n"] = n
    if seed is not None and "seed" in m.settings:
        base["seed"] = seed
    return base
