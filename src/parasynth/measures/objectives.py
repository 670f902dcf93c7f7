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
:class:`~parasynth.measures.workspace.WorkspaceSample` (``ranges`` {coordinate: (lo, hi)} SI, default
the model's ``default_ranges()``; ``n`` samples; ``method`` "sobol", "grid" or "random";
``seed``; ``fixed`` coordinates), passed whole::

    from parasynth.workspace import WorkspaceSample
    s = WorkspaceSample(n=4096, seed=0)
    objectives.get("position_error_max")(mech, sample=s, method="monte_carlo")

besides their own settings, of which ``constraints`` (pose constraint names, default all) and
``engine`` ("compiled" or "numpy") are common to all. The older call form naming the sample's
fields among the settings (``measure(mech, n=4096, seed=0)``) still works; there a field shares
its name with a measure's own setting of that name (the accuracy measures' ``method``, their
error model).

Each :class:`Measure` declares its settings as typed :class:`~parasynth.measures.measure_spec.Setting`
values (``measure.params``: kind, range or choices, default, and for a setting that overrides a
field of the workspace sample in a study, that field); one validator
(:meth:`Measure.check_settings`) checks a study's settings against them and names the field
path. ``sample`` says whether the measure takes a sample, ``own_settings`` its settings apart
from the sample's fields, ``settings`` every name the older form accepts. With a fixed seed the
same sample points are used for every design
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
from .dynamics import force_decoupling, grinding_trajectory
from ..engine import effective_engine
from ..engine import solved_unknowns as engine_solved_unknowns
from .indices import (global_conditioning_index, gravity_wrench, local_transmission_index, point_force_wrench,
                      static_forces)
from .indices import wrench_capability as _wrench_capability
from .stiffness import STIFFNESS_SETTINGS as _STIFF_SETTINGS
from .measure_spec import Setting, SettingError, as_setting, check_settings
from .stiffness import part_stiffness, point_deflection, stiffness_along
from .usable import DEFAULT_FLOOR_FRACTION, usable_of
from ..common.validation import MAX_SAMPLES, MAX_SEED, check_count, check_mechanism, check_names
from ..common.stats import quantile as quantile_of
from ..common.units import actuator_unit_kind, actuators_summary
from .workspace import WorkspaceSample, freeze, params_key, workspace

__all__ = [
    "solve_compiled",
    "Measure",
    "register",
    "get",
    "list_objectives",
    "OBJECTIVES",
    "workspace_of",
    "usable_workspace_of",
    "USABLE_MEASURES",
    "TRAJECTORIES",
    "grinding_max_force",
    "grinding_decoupling_ratio",
    "SAMPLE_SETTINGS",
    "SAMPLE_PARAMS",
    "COMMON_PARAMS",
    "Setting",
]


@dataclass(frozen=True)
class Measure:
    """A registered measure.

    ``unit``: unit of the value (SI, e.g. "m^3", "N", "1"); ``kind``: quantity kind for
    display ("length", "force", ... or None); ``sense``: the natural direction
    ("maximize" or "minimize"); ``settings``: {setting name: kind} accepted by the function
    (kinds: :data:`parasynth.measures.measure_spec.KINDS`, e.g. "length", "int", "str", "ranges",
    "pose"); ``models``: model names it applies to (None = all); ``cost``: "cheap"
    or "workspace" (needs a workspace sample) or "expensive"; ``sample``: whether it takes a
    :class:`~parasynth.measures.workspace.WorkspaceSample` (``measure(mech, sample=..., **own)``);
    ``own_settings``: its settings apart from the sample's fields (``settings`` also lists
    those, accepted by name in the older call form); ``params``: {setting name:
    :class:`~parasynth.measures.measure_spec.Setting`}, the typed declaration of every setting (kinds,
    ranges, choices, defaults; which settings override a field of the workspace sample).
    ``kind_by``: for a measure whose quantity follows a setting, ``(setting, {choice: kind})``
    (``stiffness_min``: ``part`` translational -> stiffness, rotational -> rotational_stiffness);
    :meth:`kind_of` gives the kind for given settings.
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
    params: dict = field(default_factory=dict)
    #: how the value depends on the points it is computed on (:data:`ESTIMATES`); None: derived
    #: by :meth:`estimate_of` from ``sample`` and a ``quantile`` setting
    estimate: str | None = None

    def estimate_of(self, settings: Mapping | None = None) -> str:
        """How the value with ``settings`` depends on the points it is computed on, the kind the
        verification of a recommended design (:mod:`parasynth.study.verify`) gives a tolerance:

        * ``"statistic"`` -- an estimate from random samples (a volume, a mean, an inner
          quantile): another seed moves it by its standard error;
        * ``"extreme"`` -- the least or largest value over the points (quantile 0 or 1): more
          points only make it worse, so a relative tolerance applies;
        * ``"grid"`` -- computed on a deterministic grid: exact on that grid, not resampled;
        * ``"exact"`` -- no sample at all (a pose, a path, the home pose)."""
        if "region" in self.params and self.estimate == "grid":
            # an inscribed box: on the usable grid, or on the raster of the seeded feasible sample
            region = (settings or {}).get("region", self.params["region"].default)
            return "grid" if region == "usable" else "statistic"
        if self.estimate is not None and self.estimate != "statistic":
            return self.estimate
        if "quantile" in self.params:
            q = (settings or {}).get("quantile", self.params["quantile"].default)
            if q is not None and float(q) in (0.0, 1.0):
                return "extreme"
            return "statistic"
        if self.estimate is not None:
            return self.estimate
        return "statistic" if self.sample else "exact"

    kind_by: tuple | None = None
    #: for a measure that takes a ``task``: the models on which it also runs without one (its
    #: built-in path or load, e.g. the grinding path of ``max_force_trajectory`` on ``4ups_1rps``);
    #: ``()`` when it needs a task on every model
    without_task: tuple = ()

    def runs_without_task(self, model: str) -> bool:
        """Whether the measure gives a value on ``model`` without a task: always for a measure
        that takes none, else when ``model`` is one of :attr:`without_task`."""
        if not any(p.kind == "task" for p in self.params.values()):
            return True
        return model in self.without_task

    def kind_of(self, settings: Mapping | None = None) -> str | None:
        """The quantity kind of the value for these settings: :attr:`kind`, or for a measure
        whose kind follows a setting (:attr:`kind_by`) the kind of the setting's value (its
        default when not given)."""
        if self.kind_by is None:
            return self.kind
        name, kinds = self.kind_by
        value = (settings or {}).get(name, self.params[name].default if name in self.params else None)
        return kinds.get(value, self.kind)

    def kind_setting(self) -> str | None:
        """The setting the kind follows (None when it is fixed)."""
        return None if self.kind_by is None else self.kind_by[0]

    def check_settings(self, settings: Mapping, path: str = "settings", resolve=None) -> dict:
        """``settings`` checked against the declared :attr:`params` (with ``resolve``, the
        study loader's, converted to SI); :class:`~parasynth.measures.measure_spec.SettingError` (a
        ValueError) naming ``<path>.<setting>`` and what is allowed."""
        return check_settings(self.name, self.params, settings, path, resolve)

    def sample_overrides(self, settings: Mapping) -> dict:
        """The fields of the workspace sample that ``settings`` override, {field: value}
        (settings declared with a ``sample_field``)."""
        return {self.params[k].sample_field: v for k, v in settings.items()
                if k in self.params and self.params[k].sample_field}

    def own(self, settings: Mapping) -> dict:
        """``settings`` without those that override a field of the workspace sample: the
        keyword settings of the function beside ``sample=``."""
        return {k: v for k, v in settings.items() if not (k in self.params and self.params[k].sample_field)}

    def _settings_key(self, settings: dict):
        """``settings`` as a key of the settings already checked (a study asks the same settings
        for every design), or None when a value is not hashable."""
        key = tuple(sorted((k, type(v), v) for k, v in settings.items()))
        try:
            hash(key)
        except TypeError:
            return None
        return key

    @property
    def _checked(self) -> set:
        """The settings keys (:meth:`_settings_key`; with a leading None when checked without a
        sample) that passed the checks."""
        return self.__dict__.setdefault("_checked_settings", set())

    def __call__(self, mech, sample: WorkspaceSample | None = None, **settings) -> float:
        check_mechanism("mech", mech)
        if "constraints" in settings:
            check_names("constraints", settings["constraints"])
        if self.models is not None and mech.name not in self.models:
            raise ValueError(f"measure {self.name!r} applies to {list(self.models)}, not to {mech.name!r}")
        if sample is not None:
            if not self.sample:
                raise ValueError(f"measure {self.name!r} takes no workspace sample")
            if type(sample) is not WorkspaceSample and isinstance(sample, Mapping):  # (the ABC test is slow)
                sample = WorkspaceSample(**sample)
            if not isinstance(sample, WorkspaceSample):
                raise ValueError(f"measure {self.name!r}: sample must be a WorkspaceSample, got {sample!r}")
            key = self._settings_key(settings)
            if key is None or key not in self._checked:
                beside = sorted(set(settings) - set(self.own_settings) & set(self.params))
                if beside:
                    fields = ", ".join(f"sample.{self.params[k].sample_field}" for k in beside)
                    raise ValueError(f"measure {self.name!r}: {beside} belong to the workspace sample; give them in "
                                     f"it ({fields}), not beside it")
                unknown = sorted(set(settings) - set(self.own_settings))
                if unknown:
                    raise ValueError(f"measure {self.name!r}: unknown setting(s) {unknown}; allowed with a sample: "
                                     f"{sorted(self.own_settings) or '(none)'}")
                self.check_settings(settings, self.name)
                if key is not None:
                    if len(self._checked) >= 256:
                        self._checked.clear()
                    self._checked.add(key)
            return float(self.func(mech, sample=sample, **settings))
        key = self._settings_key(settings)
        if key is not None:
            key = (None,) + key  # checked without a sample (another rule than with one)
        if key is None or key not in self._checked:
            unknown = sorted(set(settings) - set(self.settings))
            if unknown:
                raise ValueError(
                    f"measure {self.name!r}: unknown setting(s) {unknown}; allowed: {sorted(self.settings) or '(none)'}"
                )
            # the older form: a sample field's name may stand for a setting of the measure's own
            # (the accuracy measures' method), checked by the measure itself
            self.check_settings({k: v for k, v in settings.items() if k not in SAMPLE_PARAMS}, self.name)
            if key is not None:
                if len(self._checked) >= 256:
                    self._checked.clear()
                self._checked.add(key)
        return float(self.func(mech, **settings))


OBJECTIVES: "OrderedDict[str, Measure]" = OrderedDict()

#: The kinds of :meth:`Measure.estimate_of`.
ESTIMATES = ("statistic", "extreme", "grid", "exact")

#: Workspace sampling methods, as a study names them.
SAMPLING_METHODS = ("sobol", "grid", "random")

#: The fields of a :class:`~parasynth.measures.workspace.WorkspaceSample` as settings of a measure: in a
#: study, each overrides that field of the measure's sample; in the older call form they name
#: the sample's fields among the settings.
SAMPLE_PARAMS = {
    "ranges": Setting("ranges", sample_field="ranges", doc="sampled task box {coordinate: [low, high]}"),
    "n": Setting("int", default=4096, low=1, high=MAX_SAMPLES, sample_field="n", doc="workspace samples"),
    "method": Setting("str", default="sobol", choices=SAMPLING_METHODS, sample_field="method",
                      doc="the sampling method"),
    "seed": Setting("int", default=0, low=0, high=MAX_SEED, sample_field="seed", doc="seed of the sample"),
    "fixed": Setting("pose", sample_field="fixed", doc="task coordinates held fixed {coordinate: value}"),
}
#: The fields of a :class:`~parasynth.measures.workspace.WorkspaceSample` as settings, {name: kind}.
SAMPLE_SETTINGS = {k: s.kind for k, s in SAMPLE_PARAMS.items()}
#: Settings common to the workspace measures, given by the study's evaluation section unless the
#: measure's settings give them.
COMMON_PARAMS = {
    "constraints": Setting("pose_constraints", evaluation_key="constraints",
                           doc="pose constraints that define the workspace (default all)"),
    "engine": Setting("str", default="compiled", choices=("compiled", "numpy"), evaluation_key="engine",
                      doc="the evaluation engine"),
}
_WS_SETTINGS = {**SAMPLE_PARAMS, **COMMON_PARAMS}


def register(name: str, unit: str, sense: str, settings: dict | None = None, kind: str | None = None,
             models: tuple | None = None, cost: str = "workspace", sample: bool | None = None, own: tuple = (),
             estimate: str | None = None, kind_by: tuple | None = None, without_task: tuple = ()):
    """Decorator registering ``f(mech, **settings) -> float`` as measure ``name``.

    ``settings``: {name: :class:`~parasynth.measures.measure_spec.Setting` or kind name} of every
    setting the measure accepts by name (a kind name, e.g. ``"bool"`` or ``"length"``, declares
    a setting of that kind without range or default; a kind name for a field of
    :data:`SAMPLE_SETTINGS` declares that field). ``sample``: whether it takes a workspace
    sample (default: when a setting overrides a field of the sample, e.g. every field of
    :data:`SAMPLE_SETTINGS` is declared); such a measure's function receives either the
    sample's fields by name (older call form) or ``sample=`` a
    :class:`~parasynth.measures.workspace.WorkspaceSample`. ``own``: settings named like a sample field
    that are the measure's own (e.g. an error model's ``method``): with a sample they are
    passed to the function, not taken from it. ``estimate``: how the value depends on the
    points it is computed on (:data:`ESTIMATES`, see :meth:`Measure.estimate_of`; default
    derived from ``sample`` and a ``quantile`` setting). ``kind_by``: ``(setting, {choice: kind})``
    when the quantity's kind follows a setting (:meth:`Measure.kind_of`). ``without_task``: for a
    measure taking a ``task``, the models on which it also runs without one
    (:meth:`Measure.runs_without_task`)."""
    if estimate is not None and estimate not in ESTIMATES:
        raise ValueError(f"estimate must be one of {ESTIMATES}, got {estimate!r}")
    if sense not in ("maximize", "minimize"):
        raise ValueError(f"sense must be 'maximize' or 'minimize', got {sense!r}")
    params = {}
    for k, spec in (settings or {}).items():
        if not isinstance(spec, Setting) and k in _WS_SETTINGS and k not in own:
            spec = _WS_SETTINGS[k]  # a sample field or a common setting named by its kind
        params[k] = as_setting(spec)
    if sample is None:
        sample = any(s.sample_field for s in params.values())
    elif not sample:
        params = {k: dataclasses.replace(s, sample_field=None) for k, s in params.items()}
    kinds = {k: s.kind for k, s in params.items()}
    own_settings = {k: s.kind for k, s in params.items() if not s.sample_field}

    def deco(func):
        OBJECTIVES[name] = Measure(name, func, unit, sense, (func.__doc__ or "").strip(), kind,
                                   kinds, models, cost, bool(sample), own_settings, params, estimate=estimate,
                                   kind_by=kind_by, without_task=tuple(without_task))
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


def workspace_of(mech, ranges=None, n: int = 4096, method: str = "sobol", seed: int = 0, fixed=None,
                 constraints=None, engine: str = "compiled", sample: WorkspaceSample | None = None):
    """The (cached) workspace of ``mech`` for these settings; see :func:`parasynth.workspace`
    (``engine``: "compiled" or "numpy", the evaluation engine). ``sample``: a
    :class:`~parasynth.measures.workspace.WorkspaceSample`, which then gives ``ranges``, ``n``,
    ``method``, ``seed`` and ``fixed`` (the same workspace, and cache entry, as those
    arguments)."""
    frozen = None
    if sample is not None:
        if not isinstance(sample, WorkspaceSample):
            raise ValueError(f"sample must be a WorkspaceSample, got {sample!r}")
        # validated by the sample; its mappings as dicts (WorkspaceSample.kwargs)
        ranges = None if sample.ranges is None else dict(sample.ranges)
        fixed = None if sample.fixed is None else dict(sample.fixed)
        n, method, seed = sample.n, sample.method, sample.seed
        frozen = sample.__dict__.get("_frozen_key")
        if frozen is None:  # the sample's part of the key, once per sample (a study has one)
            frozen = (freeze(ranges) if ranges else None, freeze(fixed))
            object.__setattr__(sample, "_frozen_key", frozen)
    else:
        n = check_count("n", n, 1, MAX_SAMPLES, what="a sample count")  # no truncation of 2.5, True, "100"
        seed = check_count("seed", seed, 0, what="an integer seed")
    if ranges:
        ranges = dict(ranges)
        franges = frozen[0] if frozen is not None else freeze(ranges)
    else:
        ranges = mech.default_ranges()
        franges = freeze(ranges)
    # the engine that evaluates ("numpy" inside engine.reference() and engine.needs()): a probe
    # on the NumPy reference never answers for a compiled evaluation of the same settings
    key = (type(mech), params_key(mech), franges, int(n), method,
           int(seed), frozen[1] if frozen is not None else freeze(fixed), freeze(constraints), effective_engine(engine),
           tuple(repr(c) for c in getattr(mech, "added_constraints", ())), getattr(mech, "scatter_key", None))
    # a scatter draw of a robust measure keeps its own workspaces (parasynth.measures.robustness): the
    # measures of one design share them without pushing the nominal ones out of this cache
    cache = getattr(mech, "_workspace_memo", None)
    cache = _CACHE if cache is None else cache
    hit = cache.get(key)
    if hit is not None:
        cache.move_to_end(key)
        return hit
    ws = workspace(mech, ranges, n=int(n), method=method, seed=int(seed), fixed=fixed, constraints=constraints,
                   engine=engine)
    cache[key] = ws
    if len(cache) > _CACHE_SIZE:
        cache.popitem(last=False)
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


#: Typed settings shared by several measures.
_QUANTILE = Setting("float", default=0.0, low=0.0, high=1.0, doc="quantile over the feasible samples (0: the least)")
_AXIS = Setting("str", default="z", choices=("x", "y", "z"), doc="base axis")
_RESOLUTION = Setting("int", low=1, high=4096, doc="raster cells per axis (default the sampling raster)")
_COORDS = Setting("str", default="position", doc="the sampled coordinates of the box ('position' or all)")


@register("extent", unit="m", kind="length", sense="maximize", settings={**_WS_SETTINGS, "axis": _AXIS})
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


#: Settings of the usable-workspace measures (parasynth.measures.usable): the margin floor and the
#: reference pose of the component.
_USABLE_SETTINGS = {
    "floor": Setting("float", low=0.0, high=0.999999, doc="singularity-margin floor (default floor_fraction of "
                                                        "the margin at home)"),
    "floor_fraction": Setting("float", default=DEFAULT_FLOOR_FRACTION, low=0.0, high=1.0,
                              doc="default floor as a fraction of the margin at home"),
    "home": Setting("pose", doc="reference pose of the component {coordinate: value} (default the home pose)"),
}
_REGION = Setting("str", default="feasible", choices=("feasible", "usable"),
                  doc="the box inside the feasible set or inside the usable component")


def _usable(mech, kw, resolution=None):
    """The usable workspace (:func:`parasynth.measures.usable.usable_of`) of a measure's settings."""
    sample = kw.get("sample")
    if sample is None:
        sample = WorkspaceSample.from_settings(kw)
    return usable_of(mech, sample, constraints=kw.get("constraints"), engine=kw.get("engine", "compiled"),
                     resolution=resolution, floor=kw.get("floor"),
                     floor_fraction=kw.get("floor_fraction", DEFAULT_FLOOR_FRACTION), home=kw.get("home"))


#: The measures over the usable component (``inscribed_box_*`` too with ``region: usable``).
USABLE_MEASURES = ("usable_workspace_volume", "usable_workspace_fraction", "singularity_free_radius")


def usable_workspace_of(mech, resolution=None, **settings):
    """The (cached) :class:`~parasynth.measures.usable.UsableWorkspace` of a usable measure's settings
    (``sample=`` a WorkspaceSample, or the sample's fields by name; ``constraints``, ``engine``,
    ``floor``, ``floor_fraction``, ``home``); other settings of the measure are ignored."""
    return _usable(mech, settings, resolution)


def _box(mech, kw, resolution, coords, region, axis=None):
    """The largest box of a measure's settings (None when no cell is feasible); with ``axis``
    (``inscribed_box_size``), the axis is checked against the box's coordinates first, so that
    an axis the box does not have is refused whether or not the box is empty."""
    if region not in ("feasible", "usable"):
        raise ValueError(f"region must be 'feasible' or 'usable', got {region!r}")
    if axis is not None and axis not in mech.task_coordinates:
        raise SettingError(f"inscribed_box_size.axis: must be one of the box's coordinates, a task coordinate of "
                           f"{mech.name} ({', '.join(mech.task_coordinates)}), got {axis!r}")
    if region == "usable":
        usable = _usable(mech, kw, resolution)
        names = usable._names(coords, "coords")
    else:
        ws = _ws(mech, kw)
        names = ws._box_coords(coords)
    if axis is not None and axis not in names:
        raise SettingError(f"inscribed_box_size.axis: must be one of the box's coordinates {names} (coords "
                           f"{coords!r}), got {axis!r}")
    if region == "usable":
        return usable.largest_box(coords=coords)
    return ws.largest_box(coords=coords, resolution=resolution)


@register("inscribed_box_volume", unit="sampled units", sense="maximize", estimate="grid",
          settings={**_WS_SETTINGS, "resolution": _RESOLUTION, "coords": _COORDS, "region": _REGION,
                    **_USABLE_SETTINGS})
def inscribed_box_volume(mech, resolution: int | None = None, coords="position", region: str = "feasible",
                         **kw) -> float:
    """Volume of the largest axis-aligned box inside the feasible set, over the sampled
    position coordinates by default (``coords``; positions feasible for every sampled
    orientation), computed on a raster (``resolution`` cells per axis, default the
    sampling raster). ``region="usable"``: inside the usable component instead
    (``usable_workspace_volume``; its grid and floor settings)."""
    box = _box(mech, kw, resolution, coords, region)
    return float(np.prod(box.sizes)) if box is not None else 0.0


@register("inscribed_box_size", unit="sampled unit", sense="maximize", estimate="grid",
          settings={**_WS_SETTINGS, "resolution": _RESOLUTION, "axis": Setting("str", default="z", doc="a sampled coordinate"),
                    "coords": _COORDS, "region": _REGION, **_USABLE_SETTINGS})
def inscribed_box_size(mech, axis: str = "z", resolution: int | None = None, coords="position",
                       region: str = "feasible", **kw) -> float:
    """Side along coordinate ``axis`` of the largest inscribed axis-aligned box (``region``
    as ``inscribed_box_volume``). ``axis`` must be one of the box's coordinates (``coords``),
    also when no box fits (0.0): ``SettingError`` naming it otherwise."""
    box = _box(mech, kw, resolution, coords, region, axis=axis)
    if box is None:
        return 0.0
    return float(box.sizes[list(box.coordinates).index(axis)])


_UNGRID = {"resolution": dataclasses.replace(_RESOLUTION, doc="grid cells per axis (default: the sample's n cells "
                                                                "in all)"), **_USABLE_SETTINGS}


@register("usable_workspace_volume", unit="sampled units", sense="maximize", settings={**_WS_SETTINGS, **_UNGRID},
          estimate="grid")
def usable_workspace_volume(mech, resolution: int | None = None, **kw) -> float:
    """Volume of the usable workspace: the connected component, containing the home pose, of
    the feasible poses whose singularity margin is at least ``floor``, on a grid over the
    sampled box (the sample's ``n`` cells, or ``resolution`` per axis), neighbouring cells
    connected only where the singularity function keeps its sign (parasynth.measures.usable)."""
    return _usable(mech, kw, resolution).volume


@register("usable_workspace_fraction", unit="1", sense="maximize", settings={**_WS_SETTINGS, **_UNGRID},
          estimate="grid")
def usable_workspace_fraction(mech, resolution: int | None = None, **kw) -> float:
    """Usable workspace volume over the feasible volume of the same grid (0 for an empty
    workspace)."""
    return _usable(mech, kw, resolution).fraction


@register("singularity_free_radius", unit="sampled unit", sense="maximize", estimate="grid",
          settings={**_WS_SETTINGS, **_UNGRID,
                    "coords": dataclasses.replace(_COORDS, doc="'position' or sampled coordinates of one unit, "
                                                               "separated by commas ('psi, theta')")})
def singularity_free_radius(mech, resolution: int | None = None, coords="position", **kw) -> float:
    """Radius of the largest ball around the home pose inside the usable component: in the
    sampled position coordinates at the home orientation (``coords="position"``, m) or in the
    given sampled coordinates of one unit ("psi, theta", rad); at most the distance to the
    sampled box."""
    return _usable(mech, kw, resolution).free_radius(coords)[0]


@register("singularity_margin_min", unit="1", sense="maximize",
          settings={**_WS_SETTINGS, "quantile": _QUANTILE})
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
    fin = np.isfinite(m)
    if not fin.all():  # (every margin finite, the usual case: no copy)
        m = m[fin]
    return quantile_of(m, quantile) if m.size else 0.0


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
    B = np.array([leg.base for leg in mech.legs], dtype=float).reshape(-1, 3)
    return float(np.hypot(B[:, 0], B[:, 1]).max())  # per leg as np.hypot of its two floats


@register("joint_spacing_min", unit="m", kind="length", sense="maximize", cost="cheap")
def joint_spacing_min(mech) -> float:
    """Smallest distance between the centres of two legs' joints on the same body (m): between
    any two base anchors and between any two platform anchors (the platform's own frame). Room
    for the joints' housings: a paired layout whose pairs close up scores near 0 long before its
    legs' centre lines meet, which the pose-wise interference check (centre lines at least a leg
    diameter apart) does not see at the anchors' own scale. As a constraint (``min``) it keeps a
    design buildable with joints of a given size."""
    out = np.inf
    for pts in (np.array([leg.base for leg in mech.legs], float), np.array([leg.platform for leg in mech.legs], float)):
        d = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=-1)
        d[np.diag_indices(len(pts))] = np.inf
        out = min(out, float(d.min()))
    return out


@register("max_leg_length_home", unit="m", kind="length", sense="minimize", cost="cheap")
def max_leg_length_home(mech) -> float:
    """Longest leg (distance between end joint centres, m) at the home pose: a size measure."""
    _, states, _ = mech.leg_states(mech.home[None, :])
    return float(max(st.length[0] for st in states))


# -- transmission, conditioning, forces -------------------------------------------------------------
_SUB_SETTINGS = {**_WS_SETTINGS, "max_points": Setting("int", low=1, high=MAX_SAMPLES,
                                                      doc="feasible points used at most (evenly subsampled)")}
#: Index measures choose the compiled or the NumPy pose-wise indices (``engine``, "compiled" default).
_IDX_SETTINGS = _SUB_SETTINGS


def _points(mech, kw, default_max=4096):
    """Feasible workspace points, evenly subsampled to at most ``max_points``. A description
    with ``task.solve`` (parasitic coordinates) gets their unknowns from the compiled solve
    when the engine is the compiled one (:func:`solve_compiled`)."""
    ws = _ws(mech, kw)
    pts = ws.points
    m = int(kw.get("max_points", default_max))
    if len(pts) > m:
        pts = pts[np.linspace(0, len(pts) - 1, m).astype(int)]
    solve_compiled(mech, pts, kw.get("engine", "compiled"))
    return ws, pts


def solve_compiled(mech, pts, engine: str = "compiled") -> None:
    """Let the NumPy model of ``mech`` take the compiled solve's unknowns at ``pts`` (see
    ``DescribedMechanism.use_solved_unknowns``), solved when it first asks for them: the
    measures that evaluate it there (static forces, stiffness, ...) then skip its NumPy
    Gauss-Newton solve (~40 us a pose against ~2 us); those on the compiled engine never ask.
    The NumPy solve runs where the compiled engine does not answer or a pose's solve is not
    valid."""
    use = getattr(mech, "use_solved_unknowns", None)
    if use is None or not len(pts) or mech.description.task.solve is None:
        return

    def compiled():
        out = engine_solved_unknowns(mech, pts, engine)
        return out[1] if out is not None and out[0].all() else None

    use(pts, compiled)


@register("min_lti", unit="1", sense="maximize", settings={**_IDX_SETTINGS, "quantile": _QUANTILE})
def min_lti(mech, quantile: float = 0.0, **kw) -> float:
    """Smallest (or the given quantile of the) local transmission index (Wang, Liu, Wang &
    Gosselin 2010: min of input and output transmission indices) over the feasible workspace
    samples; 0 for an empty workspace."""
    _, pts = _points(mech, kw)
    if not len(pts):
        return 0.0
    v = local_transmission_index(mech, pts, engine=kw.get("engine", "compiled"))
    v = v[np.isfinite(v)]
    return quantile_of(v, quantile) if v.size else 0.0


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
          settings={**_IDX_SETTINGS, "threshold": Setting("float", default=0.7, low=0.0, doc="LTI threshold")})
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


_LOAD_SETTINGS = {**_SUB_SETTINGS, "mass": Setting("mass", default=5.0, doc="payload (kg)"),
                  "force": Setting("force", doc="external force [Fx, Fy, Fz] (N, base frame)"),
                  "com": Setting("length", doc="payload centre [x, y, z] (platform frame)")}


def _load(mech, X, mass, force, com):
    com = tuple(com) if com is not None else (0.0, 0.0, 0.0)
    pose = mech.pose(mech._poses(X)[0]) if force is not None else None  # posed once for both loads
    w = gravity_wrench(mech, X, float(mass), com=com, pose=pose)
    if force is not None:
        w = w + point_force_wrench(mech, X, np.asarray(force, dtype=float), com, pose=pose)
    return w


@register("max_actuator_force", unit="N (N*m for cranks)", kind="actuator_force", sense="minimize", estimate="extreme",
          settings={**_LOAD_SETTINGS})
def max_actuator_force(mech, mass: float = 5.0, force=None, com=None, **kw) -> float:
    """Largest static actuator force (N) over the feasible workspace samples for a payload of
    ``mass`` kg at ``com`` (platform frame, m) under gravity plus an optional external
    ``force`` [Fx, Fy, Fz] (N, base frame) at the same point. For an under-actuated model the
    least-squares balance is used (see indices.static_forces). 0 for an empty workspace. On cranks
    (RUS legs) the values are torques (N m); refused on a mechanism with both linear actuators and
    cranks."""
    actuator_unit_kind("actuator_force", actuators_summary(mech.actuator_kinds.values()), "max_actuator_force")
    _, pts = _points(mech, kw, default_max=1024)
    if not len(pts):
        return 0.0
    sf = static_forces(mech, pts, _load(mech, pts, mass, force, com))
    return float(np.nanmax(np.abs(sf.actuator)))


@register("wrench_capability", unit="N", kind="force", sense="maximize", estimate="extreme",
          settings={**_SUB_SETTINGS, "force_limit": Setting("force", default=100.0, doc="actuator force limit"),
                    "directions": Setting("list", doc="force directions (default +-X, +-Y, +-Z)"),
                    "mass": Setting("mass", default=0.0, doc="payload (kg)")})
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


_DECOUPLING_SETTINGS = {
    "dt": Setting("float", default=0.25, low=1e-9, doc="time step of the trajectory (s)"),
    "grinding_force": Setting("force", default=50.0, doc="grinding force along Z"),
    "load_point": Setting("str", default="grinding_point", choices=("grinding_point", "centre")),
}


def grinding_max_force(mech, dt: float = 0.25, grinding_force: float = 50.0,
                       load_point: str = "grinding_point") -> float:
    """Largest driving-leg force (N) along the 2022 paper's trajectory, eqs. (66)-(68), with
    the Table 3 inertias, gravity and the grinding force (N) along Z applied at the grinding
    point (``load_point="grinding_point"``) or at the platform centre (``"centre"``): the value
    of the measure ``max_force_trajectory`` on the ``4ups_1rps`` without a task
    (:mod:`parasynth.measures.task` registers it)."""
    r = _decoupling(mech, dt, grinding_force, load_point)
    return float(np.nanmax(np.abs(r.loaded[float(grinding_force)].actuator)))


def grinding_decoupling_ratio(mech, dt: float = 0.25, grinding_force: float = 50.0,
                              load_point: str = "grinding_point") -> float:
    """How much of the grinding force reaches the driving legs: the largest change of a
    driving-leg force along the eqs. (66)-(68) path when the grinding force (N, along Z) is
    applied, divided by that force (0 = fully decoupled, the paper's claim): the value of the
    measure ``force_decoupling_ratio`` on the ``4ups_1rps`` without a task."""
    r = _decoupling(mech, dt, grinding_force, load_point)
    d = np.nanmax(np.abs(r.loaded[float(grinding_force)].actuator - r.gravity_only.actuator))
    return float(d / grinding_force)


def _grinding_path(n: int):
    """The eqs. (66)-(68) path the trajectory measures follow, at ``n`` instants: times (s) and
    task poses (n, 5)."""
    t = np.linspace(0.0, 50.0, int(n))
    return t, grinding_trajectory(t)[0]


#: Measures that follow a trajectory of the platform: name -> ``f(n)`` giving the times (s) and
#: task poses of ``n`` instants of it (the interactive report moves the platform along it).
TRAJECTORIES: dict[str, Callable] = {"max_force_trajectory": _grinding_path, "force_decoupling_ratio": _grinding_path}


def _decoupling(mech, dt, grinding_force, load_point):
    if load_point not in ("grinding_point", "centre"):
        raise ValueError(f"load_point must be 'grinding_point' or 'centre', got {load_point!r}")
    lp = (0.0, mech.params.y_t, 0.0) if load_point == "grinding_point" else (0.0, 0.0, 0.0)
    return force_decoupling(mech, dt=dt, grinding_forces=(float(grinding_force),), load_point=lp)


# -- stiffness and accuracy (parasynth.measures.stiffness, parasynth.measures.accuracy) ---------------------------------
_STIFF_MEASURE = {**_SUB_SETTINGS, **{k: Setting(kind) for k, kind in _STIFF_SETTINGS.items()}, "quantile": _QUANTILE}


def _quantile(v, quantile, empty):
    v = np.asarray(v, dtype=float)
    v = v[~np.isnan(v)]
    if not v.size:
        return empty
    q = float(quantile)
    if not 0.0 <= q <= 1.0:
        raise ValueError(f"quantile must be in [0, 1], got {quantile!r}")
    return quantile_of(v, q)  # np.quantile's "linear" ("lower" at q = 0), the same bits


def _split(kw, keys):
    return {k: v for k, v in kw.items() if k in keys}


@register("stiffness_min", unit="N/m (translational) or N*m/rad (rotational)", sense="maximize",
          settings={**_STIFF_MEASURE, "part": Setting("str", default="translational",
                                                      choices=("translational", "rotational"))},
          kind_by=("part", {"translational": "stiffness", "rotational": "rotational_stiffness"}))
def stiffness_min(mech, quantile: float = 0.0, part: str = "translational", **kw) -> float:
    """Smallest (or the ``quantile`` of the) translational (N/m) or rotational (N m/rad)
    stiffness over the feasible workspace samples (``parasynth.measures.stiffness.part_stiffness``):
    1 / largest eigenvalue of the force-to-translation (couple-to-rotation) compliance block.
    Stiffness settings as ``parasynth.stiffness_matrix``. 0 for an empty workspace or where a
    force (couple) is not carried (a singular stiffness matrix)."""
    _, pts = _points(mech, kw, default_max=1024)
    if not len(pts):
        return 0.0
    k = part_stiffness(mech, pts, part=part, **_split(kw, _STIFF_SETTINGS))
    return _quantile(k, quantile, 0.0)


@register("stiffness_along", unit="N/m", kind="stiffness", sense="maximize",
          settings={**_STIFF_MEASURE, "direction": Setting("list", default=(0.0, 0.0, 1.0), doc="unitless components"),
                    "point": Setting("length", default=(0.0, 0.0, 0.0), doc="platform point (platform frame)"),
                    "frame": Setting("str", default="base", choices=("base", "platform"))})
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
          settings={**_STIFF_MEASURE, "force": Setting("force", doc="[Fx, Fy, Fz] (base frame)"),
                    "moment": Setting("torque", doc="[Mx, My, Mz] (base frame)"),
                    "point": Setting("length", default=(0.0, 0.0, 0.0), doc="platform point (platform frame)"),
                    "quantile": dataclasses.replace(_QUANTILE, default=1.0)})
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


_ERROR_METHODS = ("first_order", "monte_carlo")
#: The accuracy measures' settings: ``method`` is their own (the error model); ``sampling`` sets
#: the method of their workspace sample.
_ACC_SETTINGS = {**_SUB_SETTINGS, **{k: Setting(kind, default=0.0, low=0.0) for k, kind in _TOL_SETTINGS.items()},
                 "quantile": dataclasses.replace(_QUANTILE, default=1.0),
                 "method": Setting("str", default="first_order", choices=_ERROR_METHODS, doc="the error model"),
                 "samples": Setting("int", default=200, low=1, high=MAX_SAMPLES, doc="error draws per pose"),
                 "sampling": dataclasses.replace(SAMPLE_PARAMS["method"], default=None,
                                                 doc="the sampling method of the workspace sample")}


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


@register("position_error_max", unit="m", kind="length", sense="minimize", settings=_ACC_SETTINGS)
def position_error_max(mech, **kw) -> float:
    """Largest (or the ``quantile`` of the) position error (m) of the platform point over the
    feasible workspace samples, from actuator errors, manufacturing errors of the legs'
    geometry and S/U joint clearances (tolerance settings, see ``parasynth.measures.accuracy``).
    ``method="first_order"``: the worst-case first-order bound ``||b[:3]||`` per pose;
    ``"monte_carlo"``: the largest sampled error (``samples`` error draws per pose, at most 32
    poses by default). Poses near a singularity give large values, ``inf`` at it."""
    return _pose_errors(mech, "position", **kw)


@register("orientation_error_max", unit="rad", kind="angle", sense="minimize", settings=_ACC_SETTINGS)
def orientation_error_max(mech, **kw) -> float:
    """Largest (or the ``quantile`` of the) orientation error (rad, norm of the rotation
    vector) of the platform over the feasible workspace samples; settings and error model as
    ``position_error_max``."""
    return _pose_errors(mech, "orientation", **kw)
