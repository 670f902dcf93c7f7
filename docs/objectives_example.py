"""Objective and constraint functions without YAML: a notebook-style walk-through.

Run it with ``python docs/objectives_example.py`` (about half a minute). Every measure a
study can optimise is a plain function ``f(mech, **settings) -> float`` in
``parasynth.objectives``; here we use them to compare the 2021 paper's 5-PUS/UPU design with
a variant, then hand one of them to SciPy directly.
"""

# %% The registry
import numpy as np
from scipy.optimize import minimize_scalar

import parasynth
from parasynth import objectives

for name in objectives.list_objectives():
    m = objectives.get(name)
    print(f"{name:26s} [{m.unit}] {m.sense}")

# %% Two designs, the same evaluation settings (fixed Sobol points: common random numbers)
box = {"x": (-0.2, 0.2), "y": (-0.2, 0.2), "z": (-0.45, 0.30)}  # m, fixed posture alpha = beta = 0
settings = dict(ranges=box, n=8192, seed=0)
paper = parasynth.load_mechanism("5pus_upu")  # L = 205 mm, R = 135 mm, hinge scheme 1
variant = paper.with_params(slider_radius=0.115)

for label, mech in (("paper", paper), ("R = 115 mm", variant)):
    vol = objectives.get("workspace_volume")(mech, **settings)
    lti = objectives.get("min_lti")(mech, quantile=0.05, **settings)
    force = objectives.get("max_actuator_force")(mech, mass=2.0, **settings)
    margin = objectives.get("singularity_margin_min")(mech, quantile=0.05, **settings)
    print(f"{label:12s} volume {vol * 1e6:8.0f} cm^3  LTI(5%) {lti:.3f}  "
          f"max force {force:6.1f} N  margin(5%) {margin:.3f}")

# %% The workspace behind those numbers (cached: the measures above sampled it once)
ws = objectives.workspace_of(paper, **settings)
print(ws.summary())
print("largest inscribed box:", ws.largest_box(coords="position"))

# %% A design constraint is a measure with a bound: margin = value - min (>= 0 feasible)
footprint = objectives.get("footprint_radius")(variant)
print(f"footprint {footprint * 1e3:.0f} mm, margin to a 150 mm limit: {(0.150 - footprint) * 1e3:.0f} mm")


# %% Measures are ordinary functions: optimise one with SciPy
def negative_volume(link_length: float) -> float:
    return -objectives.get("workspace_volume")(paper.with_params(link_length=link_length), **settings)


best = minimize_scalar(negative_volume, bounds=(0.165, 0.225), method="bounded", options={"xatol": 1e-3})
print(f"link length maximising the volume in [165, 225] mm: {best.x * 1e3:.1f} mm "
      f"({-best.fun * 1e6:.0f} cm^3)")
