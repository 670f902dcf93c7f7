"""Named, importable design measures: objectives and design constraints.

Every measure is a plain function ``f(mech, **settings) -> float`` registered under a name,
usable from Python without any YAML::

    from parasynth import load_mechanism, objectives
    mech = load_mechanism("5pus_upu", link_length=0.205)
    v = objectives.get("workspace_volume")(mech, n=4096, seed=0)

A study turns a measure into an objective (minimise or maximise) or into a design constraint
with a bound (``min`` or ``max``): its margin is ``value - min`` or ``max - value`` (>= 0
feasible), in the measure's unit.

Workspace-based measures take a workspace sample: a
:class:`~parasynth.workspace.WorkspaceSample` (``ranges`` {coordinate: (lo, hi)} SI, default
the model's ``default_ranges()``; ``n`` samples; ``method`` "sobol", "grid" or "random";
``seed``; ``fixed`` coordinates), passed whole::

    from parasynth.workspace import WorkspaceSample
    s = WorkspaceSample(n=4096, seed=0)
    objectives.get("position_error_max")(mech, sample=s, method="monte_carlo")

besides their own settings, of which ``constraints`` (pose constraint names, default all) and
``engine`` ("compiled" or "numpy") are common to all. The older call form naming the sample's
fields among the settings (``measure(mech, n=4096, seed=0)``) still works; there a field shares
its name with a measure's own setting of that name (the accuracy measures' ``method``, their
error model). Each :class:`Measure` declares ``sample`` (whether it takes one) and
``own_settings`` (its settings apart from the sample's fields); ``settings`` lists every name
the older form accepts. With a fixed seed the same sample points are used for every design
(common random numbers), so an optimiser sees a deterministic function. Workspaces are cached
per (mechanism parameters, sample, constraints, engine) so that several measures of one design
sample it once.
"""

from __future__ import annotations

import dataclasses
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .accuracy import TOLERANCE_SETTINGS as _TOL_SETTINGS
from .accuracy import pose_error_bound, pose_error_monte_carlo
from .dynamics import force_decoupling
from .engine import effective_engine
from .indices import (global_conditioning_index, gravity_wrench, local_transmission_index, point_force_wrench,
                      static_forces)
from .indices import wrench_capability as _wrench_capability
from .stiffness import STIFFNESS_SETTINGS as _STIFF_SETTINGS
from .stiffness import part_stiffness, point_deflection, stiffness_along
from .validation import MAX_SAMPLES, check_count, check_mechanism, check_names
from .workspace import WorkspaceSample, workspace

__all__ = [
    "Measure",
    "register",
    "get",
    "list_objectives",
    "OBJECTIVES",
    "workspace_of",
    "SAMPLE_SETTINGS",
]


@dataclass(frozen=True)
class Measure:
    """A registered measure.

    ``unit``: unit of the value (SI, e.g. "m^3", "N", "1"); ``kind``: quantity kind for
    display ("length", "force", ... or None); ``sense``: the natural direction
    ("maximize" or "minimize"); ``settings``: {setting name: kind} accepted by the function
    (kinds: "length", "angle", "force", "mass", "int", "float", "str", "bool", "ranges",
    "dict", "list"); ``models``: model names it applies to (None = all); ``cost``: "cheap"
    or "workspace" (needs a workspace sample) or "expensive"; ``sample``: whether it takes a
    :class:`~parasynth.workspace.WorkspaceSample` (``measure(mech, sample=..., **own)``);
    ``own_settings``: its settings apart from the sample's fields (``settings`` also lists
    those, accepted by name in the older call form).
    """

    name: str
    func: Callable
    unit: str
    sense: str
    doc: str
    kind: str | None = None
    settings: dict = field(default_factory=dict)
    models: tuple | None = None
    cost: str = "workspace"
    sample: bool = False
    own_settings: dict = field(default_factory=dict)

    def __call__(self, mech, sample: WorkspaceSample | None = None, **settings) -> float:
        check_mechanism("mech", mech)
        if "constraints" in settings:
            check_names("constraints", settings["constraints"])
        if self.models is not None and mech.name not in self.models:
            raise ValueError(f"measure {self.name!r} applies to {list(self.models)}, not to {mech.name!r}")
        if sample is not None:
            if not self.sample:
                raise ValueError(f"measure {self.name!r} takes no workspace sample")
            if isinstance(sample, Mapping):
                sample = WorkspaceSample(**sample)
            if not isinstance(sample, WorkspaceSample):
                raise ValueError(f"measure {self.name!r}: sample must be a WorkspaceSample, got {sample!r}")
            beside = sorted(set(settings) & (set(SAMPLE_SETTINGS) - set(self.own_settings)))
            if beside:
                raise ValueError(f"measure {self.name!r}: {beside} belong to the workspace sample; give them in it, "
                                 f"not beside it")
            unknown = sorted(set(settings) - set(self.own_settings))
            if unknown:
                raise ValueError(f"measure {self.name!r}: unknown setting(s) {unknown}; allowed with a sample: "
                                 f"{sorted(self.own_settings) or '(none)'}")
            return float(self.func(mech, sample=sample, **settings))
        unknown = sorted(set(settings) - set(self.settings))
        if unknown:
            raise ValueError(
                f"measure {self.name!r}: unknown setting(s) {unknown}; allowed: {sorted(self.settings) or '(none)'}"
            )
        return float(self.func(mech, **settings))


OBJECTIVES: "OrderedDict[str, Measure]" = OrderedDict()

#: The fields of a :class:`~parasynth.workspace.WorkspaceSample` as settings (the older call form).
SAMPLE_SETTINGS = {"ranges": "ranges", "n": "int", "method": "str", "seed": "int", "fixed": "dict"}
_WS_SETTINGS = {**SAMPLE_SETTINGS, "constraints": "list", "engine": "str"}


def register(name: str, unit: str, sense: str, settings: dict | None = None, kind: str | None = None,
             models: tuple | None = None, cost: str = "workspace", sample: bool | None = None, own: tuple = ()):
    """Decorator registering ``f(mech, **settings) -> float`` as measure ``name``.

    ``settings``: {name: kind} of every setting the measure accepts by name. ``sample``:
    whether it takes a workspace sample (default: when ``settings`` has every field of
    :data:`SAMPLE_SETTINGS`); such a measure's function receives either the sample's fields by
    name (older call form) or ``sample=`` a :class:`~parasynth.workspace.WorkspaceSample`.
    ``own``: settings named like a sample field that are the measure's own (e.g. an error
    model's ``method``): with a sample they are passed to the function, not taken from it."""
    if sense not in ("maximize", "minimize"):
        raise ValueError(f"sense must be 'maximize' or 'minimize', got {sense!r}")
    settings = dict(settings or {})
    if sample is None:
        sample = set(SAMPLE_SETTINGS) <= set(settings)
    own_settings = {k: v for k, v in settings.items() if not sample or k not in SAMPLE_SETTINGS or k in own}

    def deco(func):
        OBJECTIVES[name] = Measure(name, func, unit, sense, (func.__doc__ or "").strip(), kind,
                                   settings, models, cost, bool(sample), own_settings)
        return func

    return deco


def get(name: str) -> Measure:
    """The measure registered as ``name`` (ValueError listing the valid names otherwise)."""
    if name not in OBJECTIVES:
        raise ValueError(f"unknown objective {name!r}; valid: {', '.join(OBJECTIVES)}")
    return OBJECTIVES[name]


def list_objectives() -> list[str]:
    return list(OBJECTIVES)


# -- workspace cache ------------------------------------------------------------------------------
_CACHE: "OrderedDict[tuple, object]" = OrderedDict()
_CACHE_SIZE = 8


def _freeze(v):
    if isinstance(v, dict):
        return tuple(sorted((k, _freeze(x)) for k, x in v.items()))
    if isinstance(v, (list, tuple)):
        return tuple(_freeze(x) for x in v)
    if isinstance(v, np.ndarray):
        return tuple(v.ravel().tolist())
    return v


def workspace_of(mech, ranges=None, n: int = 4096, method: str = "sobol", seed: int = 0, fixed=None,
                 constraints=None, engine: str = "compiled", sample: WorkspaceSample | None = None):
    """The (cached) workspace of ``mech`` for these settings; see :func:`parasynth.workspace`
    (``engine``: "compiled" or "numpy", the evaluation engine). ``sample``: a
    :class:`~parasynth.workspace.WorkspaceSample`, which then gives ``ranges``, ``n``,
    ``method``, ``seed`` and ``fixed`` (the same workspace, and cache entry, as those
    arguments)."""
    if sample is not None:
        if not isinstance(sample, WorkspaceSample):
            raise ValueError(f"sample must be a WorkspaceSample, got {sample!r}")
        ranges, n, method, seed, fixed = (sample.kwargs()[k] for k in WorkspaceSample.FIELDS)
    n = check_count("n", n, 1, MAX_SAMPLES, what="a sample count")  # no truncation of 2.5, True, "100"
    seed = check_count("seed", seed, 0, what="an integer seed")
    ranges = dict(ranges) if ranges else mech.default_ranges()
    # the engine that evaluates ("numpy" inside engine.reference() and engine.needs()): a probe
    # on the NumPy reference never answers for a compiled evaluation of the same settings
    key = (type(mech).__name__, _freeze(dataclasses.asdict(mech.params)), _freeze(ranges), int(n), method,
           int(seed), _freeze(fixed), _freeze(constraints), effective_engine(engine))
    hit = _CACHE.get(key)
    if hit is not None:
        _CACHE.move_to_end(key)
        return hit
    ws = workspace(mech, ranges, n=int(n), method=method, seed=int(seed), fixed=fixed, constraints=constraints,
                   engine=engine)
    _CACHE[key] = ws
    if len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return ws


def _ws(mech, kw):
    """The workspace of a measure's settings ``kw``: its ``sample`` (a WorkspaceSample) or the
    sample's fields named among the settings (older call form)."""
    if kw.get("sample") is not None:
        return workspace_of(mech, constraints=kw.get("constraints"), engine=kw.get("engine", "compiled"),
                            sample=kw["sample"])
    return workspace_of(mech, **{k: v for k, v in kw.items() if k in _WS_SETTINGS})


# -- workspace measures ----------------------------------------------------------------------------
@register("workspace_volume", unit="sampled units", sense="maximize", settings=_WS_SETTINGS)
def workspace_volume(mech, **kw) -> float:
    """Volume of the feasible set in the sampled task box (product of the sampled
    coordinates' units: m^3 for a fixed-orientation position box)."""
    return _ws(mech, kw).volume


@register("workspace_fraction", unit="1", sense="maximize", settings=_WS_SETTINGS)
def workspace_fraction(mech, **kw) -> float:
    """Fraction of the sampled task box that is feasible."""
    return _ws(mech, kw).fraction


@register("workspace_face_fraction", unit="1", sense="minimize", settings=_WS_SETTINGS)
def workspace_face_fraction(mech, **kw) -> float:
    """Share of the feasible samples within 1 % of a coordinate's range from a face of the
    sampled box: above a few per cent the box cuts the workspace (widen evaluation.ranges)."""
    return _ws(mech, kw).face_fraction(0.01)


def _extent(ws, axis):
    lo, hi = ws.extents[axis]
    return 0.0 if not np.isfinite(hi - lo) else float(hi - lo)


@register("extent", unit="m", kind="length", sense="maximize", settings={**_WS_SETTINGS, "axis": "str"})
def extent(mech, axis: str = "z", **kw) -> float:
    """Range (m) of the platform reference point along base axis ``axis`` ("x", "y" or
    "z") over the feasible samples (a projection size, like the papers' XOY sizes)."""
    if axis not in ("x", "y", "z"):
        raise ValueError(f"extent: axis must be 'x', 'y' or 'z', got {axis!r}")
    return _extent(_ws(mech, kw), axis)


@register("xy_isotropy", unit="1", sense="maximize", settings=_WS_SETTINGS)
def xy_isotropy(mech, **kw) -> float:
    """min/max of the X and Y extents of the feasible platform positions (1 = as wide as
    long): the 2021 paper's "better isotropy in the workspace of the XOY plane"."""
    ws = _ws(mech, kw)
    ex, ey = _extent(ws, "x"), _extent(ws, "y")
    return 0.0 if max(ex, ey) == 0 else min(ex, ey) / max(ex, ey)


@register("inscribed_box_volume", unit="sampled units", sense="maximize",
          settings={**_WS_SETTINGS, "resolution": "int", "coords": "str"})
def inscribed_box_volume(mech, resolution: int | None = None, coords="position", **kw) -> float:
    """Volume of the largest axis-aligned box inside the feasible set, over the sampled
    position coordinates by default (``coords``; positions feasible for every sampled
    orientation), computed on a raster (``resolution`` cells per axis, default the
    sampling raster)."""
    box = _ws(mech, kw).largest_box(coords=coords, resolution=resolution)
    return float(np.prod(box.sizes)) if box is not None else 0.0


@register("inscribed_box_size", unit="sampled unit", sense="maximize",
          settings={**_WS_SETTINGS, "resolution": "int", "axis": "str", "coords": "str"})
def inscribed_box_size(mech, axis: str = "z", resolution: int | None = None, coords="position", **kw) -> float:
    """Side along coordinate ``axis`` of the largest inscribed axis-aligned box."""
    ws = _ws(mech, kw)
    box = ws.largest_box(coords=coords, resolution=resolution)
    if box is None:
        return 0.0
    if axis not in box.coordinates:
        raise ValueError(f"inscribed_box_size: axis must be one of {list(box.coordinates)}, got {axis!r}")
    return float(box.sizes[list(box.coordinates).index(axis)])


@register("singularity_margin_min", unit="1", sense="maximize",
          settings={**_WS_SETTINGS, "quantile": "float", "engine": "str"})
def singularity_margin_min(mech, quantile: float = 0.0, **kw) -> float:
    """Smallest (or the given quantile of the) singularity margin over the feasible
    workspace samples; 0 for an empty workspace. ``engine``: "compiled" (default) or "numpy"
    (see :meth:`Mechanism.singularity_margin`)."""
    ws = _ws(mech, kw)
    if ws.n_feasible == 0:
        return 0.0
    pts = ws.points
    if len(pts) > 20000:
        pts = pts[np.linspace(0, len(pts) - 1, 20000).astype(int)]
    m = mech.singularity_margin(pts, engine=kw.get("engine", "compiled"))
    m = m[np.isfinite(m)]
    return float(np.quantile(m, quantile)) if m.size else 0.0


# -- cheap measures --------------------------------------------------------------------------------
@register("home_singularity_margin", unit="1", sense="maximize", cost="cheap")
def home_singularity_margin(mech) -> float:
    """Singularity margin at the model's home pose."""
    v = mech.singularity_margin(mech.home)
    return float(v) if np.isfinite(v) else 0.0


@register("home_feasibility", unit="mixed", sense="maximize", cost="cheap")
def home_feasibility(mech) -> float:
    """Smallest pose-constraint margin at the home pose (>= 0: home is feasible). Margins of
    different constraints have their own units (m or rad); use it as a sign test."""
    m = mech.constraint_margins(mech.home)
    vals = [float(v) for v in m.values()] or [0.0 if mech.inverse_kinematics(mech.home).reachable else -np.inf]
    v = min(vals)
    return v if np.isfinite(v) else -1.0


@register("footprint_radius", unit="m", kind="length", sense="minimize", cost="cheap")
def footprint_radius(mech) -> float:
    """Largest distance of a base anchor from the base Z axis (m): the machine's footprint."""
    return float(max(np.hypot(leg.base[0], leg.base[1]) for leg in mech.legs))


@register("max_leg_length_home", unit="m", kind="length", sense="minimize", cost="cheap")
def max_leg_length_home(mech) -> float:
    """Longest leg (distance between end joint centres, m) at the home pose: a size measure."""
    _, states, _ = mech.leg_states(mech.home[None, :])
    return float(max(st.length[0] for st in states))


# -- transmission, conditioning, forces -------------------------------------------------------------
_SUB_SETTINGS = {**_WS_SETTINGS, "max_points": "int"}
#: Index measures choose the compiled or the NumPy pose-wise indices ("compiled" default).
_IDX_SETTINGS = {**_SUB_SETTINGS, "engine": "str"}


def _points(mech, kw, default_max=4096):
    """Feasible workspace points, evenly subsampled to at most ``max_points``."""
    ws = _ws(mech, kw)
    pts = ws.points
    m = int(kw.get("max_points", default_max))
    if len(pts) > m:
        pts = pts[np.linspace(0, len(pts) - 1, m).astype(int)]
    return ws, pts


@register("min_lti", unit="1", sense="maximize", settings={**_IDX_SETTINGS, "quantile": "float"})
def min_lti(mech, quantile: float = 0.0, **kw) -> float:
    """Smallest (or the given quantile of the) local transmission index (Wang, Liu, Wang &
    Gosselin 2010: min of input and output transmission indices) over the feasible workspace
    samples; 0 for an empty workspace."""
    _, pts = _points(mech, kw)
    if not len(pts):
        return 0.0
    v = local_transmission_index(mech, pts, engine=kw.get("engine", "compiled"))
    v = v[np.isfinite(v)]
    return float(np.quantile(v, quantile)) if v.size else 0.0


@register("mean_lti", unit="1", sense="maximize", settings=_IDX_SETTINGS)
def mean_lti(mech, **kw) -> float:
    """Mean local transmission index over the feasible workspace samples."""
    _, pts = _points(mech, kw)
    if not len(pts):
        return 0.0
    v = local_transmission_index(mech, pts, engine=kw.get("engine", "compiled"))
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else 0.0


@register("good_transmission_volume", unit="sampled units", sense="maximize",
          settings={**_IDX_SETTINGS, "threshold": "float"})
def good_transmission_volume(mech, threshold: float = 0.7, **kw) -> float:
    """Volume of the part of the workspace where LTI >= ``threshold`` (default 0.7):
    workspace volume times the fraction of feasible samples above the threshold."""
    ws, pts = _points(mech, kw)
    if not len(pts):
        return 0.0
    v = local_transmission_index(mech, pts, engine=kw.get("engine", "compiled"))
    return float(ws.volume * np.mean(np.nan_to_num(v, nan=0.0) >= threshold))


@register("gci", unit="1", sense="maximize", settings=_IDX_SETTINGS)
def gci(mech, **kw) -> float:
    """Global conditioning index (Gosselin & Angeles): mean of the inverse condition number
    of the dimensionally homogeneous actuator Jacobian over the feasible workspace."""
    _, pts = _points(mech, kw)
    if not len(pts):
        return 0.0
    return float(global_conditioning_index(mech, pts, engine=kw.get("engine", "compiled")).value)


_LOAD_SETTINGS = {**_SUB_SETTINGS, "mass": "mass", "force": "force", "com": "length"}


def _load(mech, X, mass, force, com):
    com = tuple(com) if com is not None else (0.0, 0.0, 0.0)
    w = gravity_wrench(mech, X, float(mass), com=com)
    if force is not None:
        w = w + point_force_wrench(mech, X, np.asarray(force, dtype=float), com)
    return w


@register("max_actuator_force", unit="N", kind="force", sense="minimize",
          settings={**_LOAD_SETTINGS})
def max_actuator_force(mech, mass: float = 5.0, force=None, com=None, **kw) -> float:
    """Largest static actuator force (N) over the feasible workspace samples for a payload of
    ``mass`` kg at ``com`` (platform frame, m) under gravity plus an optional external
    ``force`` [Fx, Fy, Fz] (N, base frame) at the same point. For an under-actuated model the
    least-squares balance is used (see indices.static_forces). 0 for an empty workspace."""
    _, pts = _points(mech, kw, default_max=1024)
    if not len(pts):
        return 0.0
    sf = static_forces(mech, pts, _load(mech, pts, mass, force, com))
    return float(np.nanmax(np.abs(sf.actuator)))


@register("wrench_capability", unit="N", kind="force", sense="maximize",
          settings={**_SUB_SETTINGS, "force_limit": "force", "directions": "list", "mass": "mass"})
def wrench_capability(mech, force_limit: float = 100.0, directions=None, mass: float = 0.0, **kw) -> float:
    """Smallest, over the feasible workspace samples and the given force ``directions``
    (default +-X, +-Y, +-Z), of the largest force the actuators can balance within
    ``force_limit`` (N) each, with the payload's weight (``mass`` kg) included (cvxpy LP).
    Directions taken entirely by the constraints count as unlimited."""
    _, pts = _points(mech, kw, default_max=32)
    if not len(pts):
        return 0.0
    D = np.asarray(directions if directions is not None else
                   [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    g = gravity_wrench(mech, pts, float(mass)) if mass else None
    c = _wrench_capability(mech, pts, D, float(force_limit), gravity_wrench=g)
    c = np.where(np.isnan(c), 0.0, c)
    return float(np.min(c))


@register("max_force_trajectory", unit="N", kind="force", sense="minimize", models=("4ups_1rps",),
          settings={"dt": "float", "grinding_force": "force", "load_point": "str"})
def max_force_trajectory(mech, dt: float = 0.25, grinding_force: float = 50.0, load_point: str = "grinding_point") -> float:
    """Largest driving-leg force (N) along the 2022 paper's trajectory, eqs. (66)-(68), with
    the Table 3 inertias, gravity and the grinding force (N) along Z applied at the grinding
    point (``load_point="grinding_point"``) or at the platform centre (``"centre"``)."""
    r = _decoupling(mech, dt, grinding_force, load_point)
    return float(np.nanmax(np.abs(r.loaded[float(grinding_force)].actuator)))


@register("force_decoupling_ratio", unit="1", sense="minimize", models=("4ups_1rps",),
          settings={"dt": "float", "grinding_force": "force", "load_point": "str"})
def force_decoupling_ratio(mech, dt: float = 0.25, grinding_force: float = 50.0,
                           load_point: str = "grinding_point") -> float:
    """How much of the grinding force reaches the driving legs: the largest change of a
    driving-leg force along the eqs. (66)-(68) path when the grinding force (N, along Z) is
    applied, divided by that force. 0 = fully decoupled (the paper's claim)."""
    r = _decoupling(mech, dt, grinding_force, load_point)
    d = np.nanmax(np.abs(r.loaded[float(grinding_force)].actuator - r.gravity_only.actuator))
    return float(d / grinding_force)


def _decoupling(mech, dt, grinding_force, load_point):
    if load_point not in ("grinding_point", "centre"):
        raise ValueError(f"load_point must be 'grinding_point' or 'centre', got {load_point!r}")
    lp = (0.0, mech.params.y_t, 0.0) if load_point == "grinding_point" else (0.0, 0.0, 0.0)
    return force_decoupling(mech, dt=dt, grinding_forces=(float(grinding_force),), load_point=lp)


# -- stiffness and accuracy (parasynth.stiffness, parasynth.accuracy) ---------------------------------
_STIFF_MEASURE = {**_SUB_SETTINGS, **_STIFF_SETTINGS, "quantile": "float"}


def _quantile(v, quantile, empty):
    v = np.asarray(v, dtype=float)
    v = v[~np.isnan(v)]
    if not v.size:
        return empty
    q = float(quantile)
    if not 0.0 <= q <= 1.0:
        raise ValueError(f"quantile must be in [0, 1], got {quantile!r}")
    return float(np.quantile(v, q, method="lower" if q == 0.0 else "linear"))


def _split(kw, keys):
    return {k: v for k, v in kw.items() if k in keys}


@register("stiffness_min", unit="N/m (translational) or N*m/rad (rotational)", sense="maximize",
          settings={**_STIFF_MEASURE, "part": "str"})
def stiffness_min(mech, quantile: float = 0.0, part: str = "translational", **kw) -> float:
    """Smallest (or the ``quantile`` of the) translational (N/m) or rotational (N m/rad)
    stiffness over the feasible workspace samples (``parasynth.stiffness.part_stiffness``):
    1 / largest eigenvalue of the force-to-translation (couple-to-rotation) compliance block.
    Stiffness settings as ``parasynth.stiffness_matrix``. 0 for an empty workspace or where a
    force (couple) is not carried (a singular stiffness matrix)."""
    _, pts = _points(mech, kw, default_max=1024)
    if not len(pts):
        return 0.0
    k = part_stiffness(mech, pts, part=part, **_split(kw, _STIFF_SETTINGS))
    return _quantile(k, quantile, 0.0)


@register("stiffness_along", unit="N/m", kind="stiffness", sense="maximize",
          settings={**_STIFF_MEASURE, "direction": "list", "point": "length", "frame": "str"})
def stiffness_along_measure(mech, direction=(0.0, 0.0, 1.0), point=(0.0, 0.0, 0.0), frame: str = "base",
                            quantile: float = 0.0, **kw) -> float:
    """Smallest (or the ``quantile`` of the) stiffness (N/m) of the platform point ``point``
    (platform frame) along ``direction`` (unitless components, ``frame`` "base" or
    "platform"; e.g. the grinding normal at the grinding point) over the feasible workspace
    samples: force along the direction / displacement of the point along it. 0 where such a
    force is not carried; 0 for an empty workspace."""
    _, pts = _points(mech, kw, default_max=1024)
    if not len(pts):
        return 0.0
    k = stiffness_along(mech, pts, direction=direction, point=point, frame=frame, **_split(kw, _STIFF_SETTINGS))
    return _quantile(k, quantile, 0.0)


@register("deflection", unit="m", kind="length", sense="minimize",
          settings={**_STIFF_MEASURE, "force": "force", "moment": "torque", "point": "length"})
def deflection_measure(mech, force=None, moment=None, point=(0.0, 0.0, 0.0), quantile: float = 1.0, **kw) -> float:
    """Largest (or the ``quantile`` of the) displacement (m) of the platform point ``point``
    (platform frame) under a task wrench: ``force`` [Fx, Fy, Fz] (N, base frame) applied at the
    point and a couple ``moment`` [Mx, My, Mz] (N m, base frame), over the feasible workspace
    samples. ``inf`` where the load is not carried (singular stiffness matrix); 0 for an empty
    workspace."""
    if force is None and moment is None:
        raise ValueError("deflection: give force (N) and/or moment (N*m)")
    _, pts = _points(mech, kw, default_max=1024)
    if not len(pts):
        return 0.0
    f = (0.0, 0.0, 0.0) if force is None else force
    m = (0.0, 0.0, 0.0) if moment is None else moment
    u = point_deflection(mech, pts, force=f, moment=m, point=point, **_split(kw, _STIFF_SETTINGS))
    return _quantile(np.linalg.norm(u, axis=-1), quantile, 0.0)


_ACC_SETTINGS = {**_SUB_SETTINGS, **_TOL_SETTINGS, "quantile": "float", "method": "choice", "samples": "int",
                 "sampling": "str"}
_ERROR_METHODS = ("first_order", "monte_carlo")


def _pose_errors(mech, part, method="first_order", quantile=1.0, samples=200, sampling=None, **kw):
    # ``method`` names the error model. In the older call form (no ``sample``), a workspace
    # sampling method passed in its place (a study's evaluation.method merged by name) selects the
    # sampler instead, and the error model stays first order.
    sample = kw.get("sample")
    if sample is None and method in ("sobol", "grid", "random"):
        sampling, method = sampling or method, "first_order"
    if sample is not None and sampling is not None:
        raise ValueError("sampling: give the sampling method in the workspace sample (sample.method)")
    if method not in _ERROR_METHODS and sample is not None:
        raise ValueError(f"method must be one of {', '.join(_ERROR_METHODS)} (the error model), got {method!r}")
    if method not in _ERROR_METHODS:
        raise ValueError(f"method must be one of {', '.join(_ERROR_METHODS)} (the error model; a sampling method "
                         f"sobol, grid or random selects the workspace sampler instead), got {method!r}")
    if sampling is not None:
        kw["method"] = sampling
    tol = _split(kw, _TOL_SETTINGS)
    _, pts = _points(mech, kw, default_max=256 if method == "first_order" else 32)
    if not len(pts):
        return 0.0
    sl = slice(0, 3) if part == "position" else slice(3, 6)
    if method == "first_order":
        e = np.linalg.norm(pose_error_bound(mech, pts, **tol)[:, sl], axis=-1)
    else:
        seed = sample.seed if sample is not None else int(kw.get("seed", 0))
        t, _ = pose_error_monte_carlo(mech, pts, samples=int(samples), seed=seed, **tol)
        e = np.max(np.linalg.norm(t[..., sl], axis=-1), axis=0)
    return _quantile(e, quantile, 0.0)


@register("position_error_max", unit="m", kind="length", sense="minimize", settings=_ACC_SETTINGS, own=("method",))
def position_error_max(mech, **kw) -> float:
    """Largest (or the ``quantile`` of the) position error (m) of the platform point over the
    feasible workspace samples, from actuator errors, manufacturing errors of the legs'
    geometry and S/U joint clearances (tolerance settings, see ``parasynth.accuracy``).
    ``method="first_order"``: the worst-case first-order bound ``||b[:3]||`` per pose;
    ``"monte_carlo"``: the largest sampled error (``samples`` error draws per pose, at most 32
    poses by default). Poses near a singularity give large values, ``inf`` at it."""
    return _pose_errors(mech, "position", **kw)


@register("orientation_error_max", unit="rad", kind="angle", sense="minimize", settings=_ACC_SETTINGS,
          own=("method",))
def orientation_error_max(mech, **kw) -> float:
    """Largest (or the ``quantile`` of the) orientation error (rad, norm of the rotation
    vector) of the platform over the feasible workspace samples; settings and error model as
    ``position_error_max``."""
    return _pose_errors(mech, "orientation", **kw)
