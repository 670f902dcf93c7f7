"""What a design of a study is, in one place, below the study schema and the evaluator:

* :func:`design_params` -- design values -> the mechanism's parameters (the study's fixed
  parameters, the design variables, and the tied parameters that follow a variable);
* :func:`design_key` -- the identity of a design (two rows or records with the same key are
  the same design);
* :func:`box_centre` -- the centre of the variable box (log scale and integers respected);
* :func:`measure_settings` -- the settings a measure is called with for a design: the study's
  workspace sample where the measure takes it, then the measure's own settings.

The functions take a resolved study (:class:`~parasynth.study.spec.ResolvedStudy`) by its
attributes; this module imports nothing of the study layer.
"""

from __future__ import annotations

import numpy as np

from ..objectives import get as get_measure

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
    """Identity of a design: its design-variable values in the study's order, floats to 12
    significant digits (so that a value read back from CSV or JSON matches the one
    evaluated), NumPy integers as ints. ``values`` is a mapping or a table row."""
    out = []
    for v in study.variables:
        x = values[v.name]
        if isinstance(x, (float, np.floating)) and np.isfinite(x):
            x = float(f"{float(x):.12g}")
        elif isinstance(x, np.integer):
            x = int(x)
        out.append(x)
    return tuple(out)


#: The centre of a variable's range in normalised coordinates (0 = low, 1 = high; on a log
#: scale for ``log`` variables).
BOX_CENTRE_U = 0.5


def centre_value(v):
    """The centre of one variable: the middle of [low, high] on its scale (geometric mean for
    ``log``), rounded for an integer variable; the middle listed value of a variable with
    values only; the first choice of a categorical one."""
    if v.type != "categorical" and v.low is not None and v.high is not None:
        x = v.denormalize(BOX_CENTRE_U)
        return round(x) if v.type == "integer" else x
    if v.values:
        return v.values[len(v.values) // 2]
    if v.choices:
        return v.choices[0]
    return None


def box_centre(study) -> dict:
    """The centre of the variable box, {variable: value} (see :func:`centre_value`)."""
    out = {}
    for v in study.variables:
        x = centre_value(v)
        if x is not None:
            out[v.name] = x
    return out


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
