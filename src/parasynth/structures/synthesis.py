"""Enumeration of candidate structures for a motion type, their descriptions and their
numerical check (docs/structures.md).

A candidate is a tuple of limb groups (:class:`Group`): a ring of ``n`` identical actuated
limbs; a ring plus one passive constraining limb at the centre; or two rings of ``k`` actuated
limbs of two kinds, interleaved. Each candidate is written as a mechanism description with the
shared parameters of :data:`~parasynth.structures.vocabulary.PARAMETERS`, its task section taken
from the motion template its constraining limbs select, or else computed from the limbs' closure
equations (:mod:`parasynth.structures.motion`), then built and checked: the
screw-theory mobility at random poses of its task box must be the requested motion, the
actuators must control it at some pose, and at its default dimensions it must be controlled at
its home pose with a singularity margin of at least :data:`SINGULARITY_FLOOR` (else it is dropped
as ``singular at home``); equivalent structures are folded into one (:data:`EQUIVALENT_LIMBS`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import itertools
import math
import multiprocessing as mp
import signal
import sys
import threading
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..common.validation import (MAX_LEGS, MAX_SEED, InputError, check_count, check_engine, is_real_number,
                                 numpy_reference)
from .. import engine as _engine
from ..common import cache as _cache
from ..common.units import in_display
from ..mechanisms import described_class
from ..measures.usable import SINGULARITY_FLOOR
from ..model.legs import LEG_TYPES
from .motion import HOME_OFFSET_MAX, HOME_TILT_MAX, candidate_rule, remember_rule
from .vocabulary import (ARRANGEMENTS, CHECKS, HOME_TILTS, LIMB_TYPES, PARAMETERS, TEMPLATES, StructureError,
                         StructureWarning, limb_type, parse_motion)

__all__ = ["Group", "Structure", "StructureList", "structures", "DROP_REASONS", "EQUIVALENT_LIMBS", "SINGULARITY_FLOOR",
           "verdict_text", "candidates", "parse_axes", "StructureError", "StructureWarning", "MAX_POSES", "MAX_POSE_CHECKS", "MAX_STRUCTURE_LEGS"]

#: Why a candidate is dropped, in the order the checks run.
DROP_REASONS = {
    "duplicate": "isomorphic to a candidate enumerated before it (same multiset of limbs, joints, actuation "
                 "and arrangement)",
    "no task rule": "its constraining limbs select no motion template and no motion can be computed from their "
                    "closure equations (each one's reason follows it, from StructureList.no_task_rule; computed "
                    "only for a candidate with as many actuators as freedoms)",
    "no home": f"its limbs' closure equations have no solution near the nominal home (the platform within "
               f"{in_display(HOME_TILT_MAX, 'angle', '.0f')} of level, its centre within {HOME_OFFSET_MAX:g} length "
               f"scale(s) of x = y = 0, z = height; each one's nearest solution follows it, from "
               f"StructureList.no_home; computed only for a candidate with as many actuators as freedoms)",
    "other axes": "its freedoms are not along the axes required (axes)",
    "under-actuated": "fewer actuators than the requested freedoms",
    "over-actuated": "more actuators than the requested freedoms (redundant actuation)",
    "not assemblable": "the description cannot be built: its home pose is out of reach of a limb",
    "wrong motion": "the screw-theory mobility at the checked poses is not the requested motion (or the task "
                    "coordinates do not follow the limbs, or one of its limbs has fewer joint freedoms than the "
                    "motion, which no arrangement can give more)",
    "unreachable": "no checked pose of the task box is reachable",
    "singular everywhere": "the actuators do not control the freedoms at any checked pose",
    "singular at home": "at the default dimensions the singularity margin at the home pose is below "
                        "SINGULARITY_FLOOR with the platform level, and at every tilt of HOME_TILTS (not tried "
                        "for a regular ring of four or more limbs, singular by symmetry along its centre line; its "
                        "paired and irregular rings are the structure's layouts)",
    "equivalent": "kinematically equivalent to a kept structure, reported with it (Structure.equivalents)",
}

#: Freedoms of each joint letter.
_JOINT_FREEDOMS = {"R": 1, "P": 1, "U": 2, "S": 3}


def _fewest_freedoms(groups) -> int:
    """The fewest joint freedoms of a limb of ``groups``: a bound on the freedoms of any
    structure holding it (the platform moves within each limb's twists, whatever the axes)."""
    return min(sum(_JOINT_FREEDOMS[j] for j in limb_type(g.limb).joints) for g in groups)


#: Limb types that are another's kinematic equivalent in a structure, with the reason: an SPS
#: differs from a UPS only by an idle spin of the limb about its own axis (a UPS whose universal
#: joint is a sphere: the extra freedom moves no other body and changes no constraint); an SPU is
#: a UPS inverted (the spherical joint at the base, the universal joint at the platform): both
#: have six freedoms and actuate a force along the same line through their two anchors, so their
#: mobility, actuation and singularities are the same (their joint-angle limits sit at the other
#: end).
EQUIVALENT_LIMBS = {"SPS": ("UPS", "idle spin"), "SPU": ("UPS", "inverted")}


@dataclass(frozen=True)
class Group:
    """Limbs of one type in one arrangement: ``count`` limbs, actuated or passive, with the
    joint-axis choices ``axes`` ({option: value}) and the angular ``phase`` (deg) of the first."""

    limb: str
    count: int
    actuated: bool
    arrangement: str
    axes: tuple[tuple[str, str], ...] = ()
    phase: float = 0.0

    @property
    def constraining(self) -> bool:
        return LIMB_TYPES[self.limb].constraints > 0

    def label(self) -> str:
        ax = ",".join(f"{k}={v}" for k, v in self.axes)
        act = "actuated" if self.actuated else "passive"
        return f"{self.count} {act} {self.limb} {self.arrangement}" + (f" ({ax})" if ax else "")

    def leg_labels(self, interleaved: bool) -> list[tuple[str, ...]]:
        """Each limb as the labels of its joints, base to platform (the joint graph's edges)."""
        lt = LIMB_TYPES[self.limb]
        where = "interleaved" if interleaved else self.arrangement
        opts = dict(self.axes)
        labels = []
        for j, letter in enumerate(lt.name):
            lab = letter + ("*" if self.actuated and letter == lt.actuated_joint
                            and j == lt.name.index(lt.actuated_joint) else "")
            if j == 0:
                lab += f"@{where}"
            labels.append(lab)
        labels[0] += "|" + ",".join(f"{k}={v}" for k, v in sorted(opts.items()))
        return [tuple(labels)] * self.count


def _name(groups: tuple[Group, ...]) -> str:
    act = [g for g in groups if g.actuated]
    pas = [g for g in groups if not g.actuated]
    s = "&".join(f"{g.count}-{g.limb}" for g in act)
    for g in pas:
        s += "/" + (g.limb if g.count == 1 else f"{g.count}-{g.limb}")
    return s


def _key(groups) -> tuple:
    """The canonical form of the joint graph of parallel limbs: the sorted multiset of limb
    label paths (two structures of limbs from base to platform have isomorphic labelled joint
    graphs exactly when these multisets agree)."""
    inter = len([g for g in groups if g.actuated]) > 1
    return tuple(sorted(lab for g in groups for lab in g.leg_labels(inter and g.actuated)))


@dataclass(frozen=True)
class _Candidate:
    groups: tuple[Group, ...]

    @property
    def name(self) -> str:
        return _name(self.groups)

    @property
    def n_legs(self) -> int:
        return sum(g.count for g in self.groups)

    @property
    def n_actuated(self) -> int:
        return sum(g.count for g in self.groups if g.actuated)

    def template(self):
        """The motion template its constraining groups select (the rule of docs/structures.md),
        or None when there is none or more than one."""
        names = set()
        for g in self.groups:
            if g.constraining:
                t = LIMB_TYPES[g.limb].templates.get(g.arrangement)
                if t is None:
                    return None
                names.add(t)
        if not names:
            return TEMPLATES["free"]
        return TEMPLATES[names.pop()] if len(names) == 1 else None


def _axis_choices(lt, all_axes: bool):
    """The joint-axis choices of a limb type: the first value of each option (every combination
    with ``all_axes``), then its ``variants``."""
    keys = list(lt.axes)
    values = [lt.axes[k] if all_axes else lt.axes[k][:1] for k in keys]
    seen = set()
    for combo in itertools.product(*values):
        seen.add(tuple(zip(keys, combo)))
        yield tuple(zip(keys, combo))
    for v in lt.variants:
        v = tuple(sorted(v, key=lambda kv: keys.index(kv[0]) if kv[0] in keys else len(keys)))
        if v not in seen:
            seen.add(v)
            yield v


def candidates(types, legs=None, all_axes: bool = False) -> list[_Candidate]:
    """Every candidate of the vocabulary restricted to the limb types ``types`` (and to total
    limb counts in ``legs``), in enumeration order, duplicates included."""
    out = []
    ok = (lambda n: True) if legs is None else (lambda n: n in legs)
    actuable = [t for t in types if LIMB_TYPES[t].actuated_joint is not None]
    rings = []
    for t in actuable:
        lt = LIMB_TYPES[t]
        for arr in lt.arrangements:
            for n in ARRANGEMENTS[arr].counts:
                for axes in _axis_choices(lt, all_axes):
                    rings.append(Group(t, n, True, arr, axes))
    # n identical actuated limbs
    out += [_Candidate((g,)) for g in rings if ok(g.count)]
    # actuated limbs plus one passive constraining limb at the centre
    for c in types:
        lc = LIMB_TYPES[c]
        if lc.central is None:
            continue
        centre = Group(c, 1, False, "central", tuple(lc.central.items()))
        out += [_Candidate((g, centre)) for g in rings if ok(g.count + 1)]
    # two kinds of actuated limbs, interleaved: k of one at phase 0, k of the other at 180/k;
    # constraining kinds first, so that the kept one of two mirror orders has them at phase 0
    pairs = sorted(itertools.permutations(actuable, 2),
                   key=lambda p: -(LIMB_TYPES[p[0]].constraints > 0) + (LIMB_TYPES[p[1]].constraints > 0))
    for t1, t2 in pairs:
        for k in (2, 3):
            if not ok(2 * k):
                continue
            arrs = []
            for t in (t1, t2):
                lt = LIMB_TYPES[t]
                fit = [a for a in lt.arrangements if k in ARRANGEMENTS[a].counts] or \
                      (["regular"] if "regular" in lt.arrangements else [])
                arrs.append(fit[0] if fit else None)
            if None in arrs:
                continue
            for ax1 in _axis_choices(LIMB_TYPES[t1], all_axes):
                for ax2 in _axis_choices(LIMB_TYPES[t2], all_axes):
                    out.append(_Candidate((Group(t1, k, True, arrs[0], ax1, 0.0),
                                           Group(t2, k, True, arrs[1], ax2, 180.0 / k))))
    return out


# -- descriptions ---------------------------------------------------------------------------------
def _deg(x: float) -> str:
    return f"{x:g} deg"


#: The joint-axis value of a universal joint whose axis passes through the centre of rotation, the
#: platform centre at the home pose (0, 0, height): at the base, the direction from the base anchor
#: to it; at the platform, from the platform anchor to the platform centre (-radial).
CENTRE = "centre"


def _through_centre(entry: dict, g: Group, base: dict, second: bool) -> list[dict]:
    """The legs of a ring group whose axis options say ``centre``, one entry per limb: a base axis
    ``centre`` is the direction from that limb's base anchor to (0, 0, height) (written per limb:
    -cos, -sin of its anchor angle and height / base radius), a platform axis ``centre`` is
    ``-radial`` (towards the platform centre). Only a regular ring has anchor angles known here."""
    if g.arrangement != "regular" or base.get("pattern") != "polygon":
        raise StructureError(f"axes: {CENTRE!r} is defined for a regular ring only, not {g.arrangement!r} "
                             f"({g.label()})")
    rb = "base_radius*second_base_scale" if second else "base_radius"
    out = []
    for k in range(g.count):
        e = dict(entry)
        e["base"] = f"{entry['base']}[{k}]"
        e["platform"] = f"{entry['platform']}[{k}]"
        ang = g.phase + 360.0 * k / g.count
        for opt, val in g.axes:
            if val != CENTRE:
                continue
            if LEG_TYPES[g.limb].description_options.get(opt) == "axis_base":
                e[opt] = [f"-cos({ang:g} deg)", f"-sin({ang:g} deg)", f"height/({rb})"]
            else:
                e[opt] = "-radial"
        out.append(e)
    return out


def _anchor_sets(g: Group, twist: bool, second: bool = False):
    """Base and platform anchor sets of a ring group and its platform index list (None: in order).
    ``second``: the second group of a two-kind structure, on circles scaled by
    ``second_base_scale`` and ``second_platform_scale``."""
    n, ph = g.count, g.phase
    rb, rp = ("base_radius*second_base_scale", "platform_radius*second_platform_scale") if second else \
        ("base_radius", "platform_radius")
    if g.arrangement == "paired" and n % 2 == 0:
        m = n // 2
        base = {"pattern": "paired", "n": m, "radius": rb, "phase": _deg(ph), "separation": "base_separation"}
        plat = {"pattern": "paired", "n": m, "radius": rp, "phase": _deg(ph + 180.0 / m),
                "separation": "platform_separation"}
        return base, plat, [n - 1] + list(range(n - 1))
    if g.arrangement == "paired":  # odd n: alternately closer and farther, crossed
        sign = ["+" if i % 2 == 0 else "-" for i in range(n)]
        base = {"pattern": "circle", "radius": rb,
                "angles": [f"{ph + 360.0 * i / n:g} deg {sign[i]} base_separation/2" for i in range(n)]}
        plat = {"pattern": "circle", "radius": rp,
                "angles": [f"{ph + 360.0 * i / n:g} deg {'-' if sign[i] == '+' else '+'} platform_separation/2"
                           for i in range(n)]}
        return base, plat, None
    if g.arrangement == "irregular":
        tw = " + platform_twist" if twist else ""
        base = {"pattern": "circle", "radius": rb,
                "angles": [f"{ph + 360.0 * i / n:g} deg" + (f" + base_offset_{i + 1}" if i else "") for i in range(n)]}
        plat = {"pattern": "circle", "radius": rp,
                "angles": [f"{ph + 360.0 * i / n:g} deg{tw}" + (f" + platform_offset_{i + 1}" if i else "")
                           for i in range(n)]}
        return base, plat, None
    base = {"pattern": "polygon", "n": n, "radius": rb, "phase": _deg(ph)}
    pphase = f"{ph:g} deg + platform_twist" if twist and g.arrangement == "regular" else _deg(ph)
    plat = {"pattern": "polygon", "n": n, "radius": rp, "phase": pphase}
    return base, plat, None


#: The cone-angle key of the base-side and the platform joint of each limb type (None: a revolute
#: joint, whose axis the limb's constraints already fix); a chain limb declares its own
#: (``cone_keys``: the universal or spherical joint at its base or platform anchor).
_CONES = {"SPS": ("S_base_cone", "S_platform_cone"), "UPS": ("U_base_cone", "S_platform_cone"),
          "PUS": ("U_base_cone", "S_platform_cone"), "RUS": ("U_base_cone", "S_platform_cone"),
          "RPS": (None, "S_platform_cone"), "PRS": (None, "S_platform_cone"), "RPU": (None, "U_platform_cone"),
          "UPU": ("U_base_cone", "U_platform_cone")}


def _joint_limits(c: _Candidate) -> list:
    """The ring limbs' joint cone-angle limits (base_joint_max, platform_joint_max) and their
    interference (link_diameter): the same physical limits for every structure. The central
    passive limb is not limited (as the 5-PUS/UPU's constraining limb in the paper)."""
    ring, index = {}, 1
    for g in c.groups:
        names = [f"L{index + j}" for j in range(g.count)]
        index += g.count
        if g.arrangement != "central":
            ring[g.limb] = ring.get(g.limb, []) + names
    out = []
    for end, limit in ((0, "base_joint_max"), (1, "platform_joint_max")):
        by_key = {}
        for limb, names in ring.items():
            key = (_CONES.get(limb) or getattr(LEG_TYPES[limb], "cone_keys", None) or (None, None))[end]
            if key is not None:
                by_key.setdefault(key, []).extend(names)
        for key, names in by_key.items():
            name = ("base_joints" if end == 0 else "platform_joints") + ("" if len(by_key) == 1 else f"_{key[0]}")
            out.append({"name": name, "type": "joint_angle", "key": key, "max": limit, "legs": sorted(names, key=lambda n: int(n[1:])),
                        "doc": f"{key} <= {limit}"})
    legs = sorted((n for names in ring.values() for n in names), key=lambda n: int(n[1:]))
    if len(legs) > 1:
        out.append({"name": "interference", "type": "interference", "diameter": "link_diameter", "legs": legs,
                    "doc": "distance between the ring limbs' centre lines >= link_diameter"})
    return out


#: Shared parameters positive by nature: zero or negative is refused with the parameter's name.
POSITIVE_PARAMETERS = ("base_radius", "platform_radius", "second_base_scale", "second_platform_scale", "link_length",
                       "crank_length", "q_min", "stroke", "base_joint_max", "platform_joint_max", "reach", "tilt")


def _positive(name: str, value: str) -> dict:
    if name not in POSITIVE_PARAMETERS:
        return {}
    unit = value.split()[1:]  # "300 mm" -> ["mm"]; "1" -> []
    return {"above": f"0 {unit[0]}" if unit else 0}


def _description(c: _Candidate, template, key: str) -> dict:
    twist = not any(g.arrangement == "opposed" for g in c.groups)
    base, plat, legs = {}, {}, []
    index = 1
    telescopic, sliders = [], []
    ring_groups = [g for g in c.groups if g.arrangement != "central"]
    for i, g in enumerate(c.groups, start=1):
        lt = LIMB_TYPES[g.limb]
        entry = {"type": g.limb}
        if g.arrangement == "central":
            entry["base"] = ["0 mm", "0 mm", "0 mm"]
            entry["platform"] = ["0 mm", "0 mm", "0 mm"]
        else:
            b, p, idx = _anchor_sets(g, twist, second=len(ring_groups) > 1 and g is ring_groups[1])
            base[f"B{i}"], plat[f"A{i}"] = b, p
            entry["base"] = f"B{i}"
            entry["platform"] = f"A{i}" if idx is None else f"A{i}[{', '.join(map(str, idx))}]"
        entry.update(lt.options)
        entry.update(dict(g.axes))
        entry["actuated"] = lt.actuated_joint if g.actuated else "none"
        if CENTRE in dict(g.axes).values():
            legs += _through_centre(entry, g, b, second=len(ring_groups) > 1 and g is ring_groups[1])
        else:
            legs.append(entry)
        group_names = [f"L{index + j}" for j in range(g.count)]
        index += g.count
        if g.actuated:
            kind = LEG_TYPES[g.limb].actuator_kind  # the leg type says: slider, length or angle
            if kind == "slider":
                sliders += group_names
            elif kind == "length":
                telescopic += group_names
    constraints = []
    if telescopic:
        constraints.append({"name": "stroke_legs", "type": "leg_length", "legs": telescopic, "min": "q_min",
                            "max": "q_min + stroke", "doc": "telescopic limbs within [q_min, q_min + stroke]"})
    if sliders and len(sliders) == c.n_actuated:
        constraints.append({"name": "stroke_sliders", "type": "actuator_range", "min": "slider_min",
                            "max": "slider_min + stroke", "doc": "slider positions within [slider_min, "
                                                                 "slider_min + stroke]"})
    constraints += _joint_limits(c)
    slug = "".join(ch if ch.isalnum() else "_" for ch in c.name.lower()).strip("_")
    arr = "; ".join(g.label() for g in c.groups)
    return {
        "name": f"{slug}-{key}",
        "summary": f"{c.name} ({template.motion}): {arr}",
        "description": (f"Generated by parasynth.structures: {arr}. Task: template {template.name} "
                        f"({template.doc})."),
        "parameters": {k: {"value": v, "doc": d, **_positive(k, v)} for k, (v, d) in PARAMETERS.items()},
        "checks": list(CHECKS),
        "base": base,
        "platform": plat,
        "legs": legs,
        "task": dict(template.task),
        "length_scale": "base_radius",
        "constraints": constraints,
    }


# -- the result -----------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Structure:
    """A verified candidate structure.

    ``name`` in the field's notation (``5-PUS/UPU``, ``2-RPU&2-SPS``), ``motion`` (the verified
    motion type), ``leg_counts`` and ``actuated_counts`` ({leg type: number}), ``groups`` (the
    limb groups), ``arrangement`` (one line per group), ``template`` (the motion template of its
    task coordinates), ``axes`` (the translation axes and rotation axes of its freedoms),
    ``description`` (a dict that ``load_mechanism`` accepts once written to YAML),
    ``checked_poses`` and ``controlled_poses`` (how many random poses of the task box were
    checked, and at how many the actuators controlled every freedom), ``home_margin`` (the
    singularity margin at the home pose, default dimensions), ``checked_margin`` (the least
    margin over the checked poses), ``equivalents`` ((name, reason) of the kinematically
    equivalent structures reported as this one, :data:`EQUIVALENT_LIMBS`)."""

    name: str
    key: str
    motion: str
    leg_counts: dict
    actuated_counts: dict
    groups: tuple
    arrangement: str
    template: str
    axes: dict
    description: dict = field(repr=False)
    checked_poses: int = 0
    controlled_poses: int = 0
    home_margin: float = math.nan
    checked_margin: float = math.nan
    equivalents: tuple = ()
    _cls: list = field(default_factory=list, repr=False)

    def __getstate__(self):
        """Pickled without the built model class (made anew from ``description`` when asked
        for, :meth:`mechanism_class`): a class made at run time does not pickle."""
        return {**self.__dict__, "_cls": []}

    def __setstate__(self, state):
        self.__dict__.update(state)

    @property
    def verified(self) -> bool:
        """Controlled at its home pose and at every checked pose with a singularity margin of at
        least :data:`SINGULARITY_FLOOR` (at the default dimensions)."""
        return bool(self.home_margin >= SINGULARITY_FLOOR and self.checked_margin >= SINGULARITY_FLOOR
                    and self.controlled_poses == self.checked_poses)

    @property
    def label(self) -> str:
        """The name, with the kinematically equivalent structures reported with it:
        ``5-UPS/UPU (also 5-SPS/UPU: idle spin)``."""
        if not self.equivalents:
            return self.name
        return f"{self.name} (also {', '.join(f'{n}: {why}' for n, why in self.equivalents)})"

    @property
    def limbs(self) -> str:
        return " + ".join(f"{g.count}x{g.limb}" for g in self.groups)

    @property
    def actuation(self) -> str:
        return ", ".join(f"{g.count} {g.limb} {'at ' + LIMB_TYPES[g.limb].actuated_joint if g.actuated else 'passive'}"
                         for g in self.groups)

    def mechanism_class(self) -> type:
        """The described model class (built once per structure)."""
        if not self._cls:
            self._cls.append(described_class(self.description, source=self.name))
        return self._cls[0]

    def mechanism(self, **params):
        """A mechanism of this structure with the shared parameters ``params`` in SI (m, rad)."""
        cls = self.mechanism_class()
        fields = set(cls.Params.__dataclass_fields__)
        unknown = sorted(set(params) - fields)
        if unknown:
            raise StructureError(f"unknown parameter(s) {unknown} for structure {self.name!r}; valid: "
                             f"{', '.join(sorted(fields))}")
        return cls(cls.Params(**params))

    def yaml(self) -> str:
        """The description as YAML text."""
        import yaml  # lazy: PyYAML is not loaded by `import parasynth`

        return yaml.safe_dump(self.description, sort_keys=False, allow_unicode=True, width=110)

    @property
    def filename(self) -> str:
        return f"{self.description['name']}.yaml"

    def write(self, directory) -> Path:
        """Write the description to ``directory/<description name>.yaml``; returns the path."""
        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        p = d / self.filename
        p.write_text(self.yaml(), encoding="utf-8")
        return p


class StructureList(list):
    """The structures found (a list), with ``motion``, ``enumerated`` (candidates generated),
    ``dropped`` ({reason: count}, reasons of :data:`DROP_REASONS`) and ``dropped_names``
    ({reason: [candidate names]}), ``no_task_rule`` ({"name [arrangement]": why it has no task
    rule}) and ``no_home`` (the same for the candidates whose limbs assemble nowhere near the
    nominal home); :meth:`dropped_lines` lists them."""

    def __init__(self, items, motion, enumerated, dropped, dropped_names, show_dropped: bool = False,
                 no_task_rule=None, no_home=None):
        super().__init__(items)
        self.show_dropped = show_dropped
        self.no_task_rule = dict(no_task_rule or {})
        self.no_home = dict(no_home or {})
        self.motion = motion
        self.enumerated = enumerated
        self.dropped = dropped
        self.dropped_names = dropped_names

    def dropped_lines(self, include_duplicates: bool = False) -> list[str]:
        """One line per reason: ``under-actuated (3): 4-UPS/RPS, ...`` with the reason's
        meaning; duplicates (isomorphic re-enumerations) only with ``include_duplicates``."""
        out = []
        for reason, names in self.dropped_names.items():
            if not names or (reason == "duplicate" and not include_duplicates):
                continue
            counted = Counter(names)
            listed = ", ".join(n if k == 1 else f"{n} x{k}" for n, k in counted.items())
            out.append(f"{reason} ({len(names)}; {DROP_REASONS[reason]}): {listed}")
            whys = {"no task rule": self.no_task_rule, "no home": self.no_home}.get(reason, {})
            out += [f"  {name}: {why}" for name, why in whys.items()]  # why, candidate by candidate
        return out

    def summary(self) -> str:
        """The structures kept, each with its verdict at the default dimensions ("verified" or
        "NOT VERIFIED" with its margins against :data:`SINGULARITY_FLOOR`), the dropped counts
        and, with ``show_dropped``, the dropped candidates by reason."""
        lines = [f"{self.motion}: {self.enumerated} candidate(s) enumerated, {len(self)} kept"]
        for s in self:
            lines.append(f"  {s.label} [{s.arrangement}]: {verdict_text(s)}")
        dropped = {k: v for k, v in self.dropped.items() if v}
        lines.append("dropped: " + (", ".join(f"{k} {v}" for k, v in dropped.items()) if dropped else "none"))
        if self.show_dropped:
            lines += ["  " + x for x in self.dropped_lines()]
        return "\n".join(lines)


def verdict_text(s) -> str:
    """"verified: ..." for a structure controlled at home and at every checked pose with margin
    at least :data:`SINGULARITY_FLOOR`; "NOT VERIFIED: ..." with the margins otherwise."""
    axes = f"T {', '.join(s.axes['translations']) or '-'}; R {', '.join(s.axes['rotations']) or '-'}"
    margins = (f"singularity margin {s.home_margin:.3g} at home, least {s.checked_margin:.3g} at the checked poses "
               f"(floor {SINGULARITY_FLOOR:g})")
    what = (f"{s.motion} ({axes}) at {s.checked_poses} random pose(s) of the task box, actuators control it at "
            f"{s.controlled_poses}; {margins}")
    return ("verified: " if s.verified else "NOT VERIFIED: ") + what


def _check(c: _Candidate, motion: str, desc: dict, n_poses: int, seed: int):
    """(reason or None, details, class): build the description and check its mobility.

    The motion is verified as follows: at the home pose the screw-theory type
    (``Mobility.type``) is ``motion``; at every checked random pose of the task box the
    freedoms number as many as the task coordinates and the description's mobility checks find
    the coordinates independent and following the limbs (``DescribedMobility.consistent``), so
    the task coordinates (lengths: translations, angles: rotations) are the finite motion. Away
    from home the instantaneous type may be counted differently (the 5-PUS/UPU's constraint
    becomes a screw of non-zero pitch, read as 2T3R); it is kept in the details."""
    try:
        cls = described_class(desc, source=c.name)
        mech = cls(cls.Params())
        home = mech.mobility(warn=False)
    except ValueError as e:
        return "not assemblable", {"error": str(e)}, None
    lo, hi = (np.array(v) for v in zip(*[mech.default_ranges()[k] for k in mech.task_coordinates]))
    rng = np.random.default_rng(seed)
    X = mech.home + 0.25 * (hi - lo) * rng.uniform(-1.0, 1.0, (4 * n_poses, len(lo)))
    X = X[mech.inverse_kinematics(X).reachable][:n_poses]
    details = {"home_type": home.type, "types": {}, "checked": len(X), "controlled": 0}
    if home.type != motion:
        return "wrong motion", details, None
    if not len(X):
        return "unreachable", details, None
    types, controlled, consistent = Counter(), 0, True
    for x in X:
        m = mech.mobility(x, warn=False)
        types[m.type] += 1
        consistent &= bool(m.consistent) and m.dof == mech.n_task
        controlled += int(m.controlled and not m.singular_at_pose)
    details.update(types=dict(types), controlled=controlled,
                   margin=float(np.min(mech.singularity_margin(X, engine="numpy"))))
    if not consistent:
        return "wrong motion", details, None
    if controlled == 0:
        return "singular everywhere", details, None
    return None, details, cls


def _verify(c: _Candidate, motion: str, desc: dict, n_poses: int, seed: int):
    """(reason or None, details, description, class, home margin) of a candidate: its checks
    (:func:`_check`), then, if it passes them, its home pose (:func:`_controlled_home`: the
    description, class and margin there; description and class None when it is singular at
    every home tried)."""
    reason, det, cls = _check(c, motion, desc, n_poses, seed)
    if reason is not None:
        return reason, det, None, None, None
    desc, cls, home_margin = _controlled_home(c, desc, cls)
    return None, det, desc, cls, home_margin


#: Candidates below which their checks (or motion rules) run in this process: forking the
#: checking processes costs ~50 ms, a candidate's checks ~20-60 ms.
PARALLEL_CHECKS = 8

#: Whether the checks can be forked: Linux (elsewhere a forked process may not run the
#: libraries loaded in its parent; the checks then run in the calling process).
_CAN_FORK = sys.platform.startswith("linux") and "fork" in mp.get_all_start_methods()

#: (function, items, result to send, within numpy_reference) of the checking processes,
#: inherited by fork (see _spread).
_WORK: tuple = ()
_FORKING = threading.Lock()  # one call forks at a time: its processes inherit its _WORK


def _work_item(i: int):
    fn, items, send, reference = _WORK
    with numpy_reference() if reference else contextlib.nullcontext():  # as in the parent
        return send(fn(items[i]))


def _ignore_interrupt() -> None:  # a checking process: Ctrl-C is the parent's to handle
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _check_processes(processes, n_items: int) -> int:
    if processes is None:
        processes = _engine.n_threads()
    if n_items < PARALLEL_CHECKS or processes < 2 or not _CAN_FORK:
        return 1
    return min(int(processes), n_items)


def _spread(fn, items: list, processes, send=lambda r: r) -> list:
    """``[fn(item) for item in items]``, in this process or, from :data:`PARALLEL_CHECKS` items
    on, spread over ``processes`` forked processes (default the engine's thread count,
    :func:`parasynth.engine.n_threads`: the cores, or a study worker's share of them),
    each result passed through ``send`` there (what cannot be sent between processes left
    out). The first item is done here before the fork: it loads and builds once what every
    item uses (modules, parsed limb descriptions, kernels from the cache), which the forked
    processes then inherit instead of each doing it again. Every item is computed alone
    (seeded on its own), so the answers do not depend on the split."""
    n = _check_processes(processes, len(items))
    if n < 2:
        return [fn(x) for x in items]
    first = fn(items[0])
    global _WORK
    with _FORKING:  # the pool's processes are forked here, each with this call's work
        _WORK = (fn, items, send, check_engine("compiled") == "numpy")  # inside numpy_reference()?
        try:
            with warnings.catch_warnings():
                # Python 3.12+ warns of fork with other threads alive: the engine's kept threads
                # sleep on locks of their own, and a forked process starts a crew of its own
                warnings.filterwarnings("ignore", message=r".*use of fork\(\) may lead to deadlocks",
                                        category=DeprecationWarning)
                pool = mp.get_context("fork").Pool(n, initializer=_ignore_interrupt)
        finally:
            _WORK = ()
    with pool:
        rest = pool.map(_work_item, range(1, len(items)), chunksize=1)
    return [first] + rest


def _verified(jobs: list, processes) -> list:
    """:func:`_verify` of each job ``(candidate, motion, description, n_poses, seed)``, in order
    (:func:`_spread`); the class of a structure checked in another process is built here again
    from its description."""
    out = _spread(lambda j: _verify(*j), jobs, processes, send=lambda r: r[:3] + (None,) + r[4:])
    return [(r, det, desc, cls if cls is not None or desc is None else described_class(desc, source=c.name), m)
            for (c, *_), (r, det, desc, cls, m) in zip(jobs, out)]


def _home_margin(cls) -> float:
    """The singularity margin of ``cls`` at its default dimensions and home pose (NumPy)."""
    mech = cls(cls.Params())
    return float(np.asarray(mech.singularity_margin(np.atleast_2d(mech.home), engine="numpy")).ravel()[0])


def _with_home_tilt(desc: dict, tilt_deg: float) -> dict:
    """``desc`` with the default ``home_tilt`` set to ``tilt_deg``."""
    params = dict(desc["parameters"])
    params["home_tilt"] = {**params["home_tilt"], "value": f"{tilt_deg:g} deg"}
    return {**desc, "parameters": params}


def _controlled_home(c: _Candidate, desc: dict, cls):
    """(description, class, home margin) with a home pose where the structure is controlled:
    the level platform if its margin is at least :data:`SINGULARITY_FLOOR`, else (unless a ring
    is regular with four or more limbs) the first tilt of :data:`HOME_TILTS` that is (the
    description's default ``home_tilt``); (None, None, best margin) when none is."""
    m = _home_margin(cls)
    if m >= SINGULARITY_FLOOR:
        return desc, cls, m
    best = m
    # a regular ring of four or more limbs singular with the platform level is singular by
    # symmetry along its whole centre line: no tilt is tried (its paired and irregular rings are
    # the structure's layouts)
    symmetric = any(g.arrangement == "regular" and g.count >= 4 for g in c.groups)
    if not symmetric and "home_tilt" in repr(desc["task"]):
        for tilt in HOME_TILTS:
            d2 = _with_home_tilt(desc, tilt)
            try:
                cls2 = described_class(d2, source=c.name)
                m2 = _home_margin(cls2)
            except ValueError:
                continue
            if m2 >= SINGULARITY_FLOOR:
                return d2, cls2, m2
            best = max(best, m2)
    return None, None, best



def parse_axes(axes) -> dict | None:
    """``axes`` as {"translations": frozenset, "rotations": frozenset} of axis names (lower
    case, single spaces), or None. Given as a mapping with the keys ``translations`` and/or
    ``rotations``, each a list of axis names (``x``, ``z``, ``moving x``, ...) or a comma-separated
    string; a key left out is not required. An empty mapping is refused (it would require
    nothing, i.e. allow everything): leave ``axes`` out for any axes."""
    if axes is None:
        return None
    if not isinstance(axes, dict) or not axes or set(axes) - {"translations", "rotations"}:
        raise StructureError(f"axes must be a mapping with the keys translations and/or rotations, each a list of "
                             f"axis names (e.g. {{'translations': ['x', 'z'], 'rotations': ['y', 'moving x']}}), "
                             f"got {axes!r}")
    out = {}
    for k, v in axes.items():
        items = v.split(",") if isinstance(v, str) else v
        if not isinstance(items, (list, tuple)) or not all(isinstance(a, str) and a.strip() for a in items):
            raise StructureError(f"axes.{k} must be a list of axis names such as 'x' or 'moving x', got {v!r}")
        names = [" ".join(a.lower().split()) for a in items]
        if len(set(names)) != len(names):
            raise StructureError(f"axes.{k}: an axis is named twice in {v!r}")
        out[k] = frozenset(names)
    return out


def _axes_match(template, want) -> bool:
    return all(frozenset(" ".join(a.lower().split()) for a in template.axes.get(k, ())) == v for k, v in want.items())


#: Largest ``n_poses`` of :func:`structures` (reachable random poses checked per candidate).
MAX_POSES = 1024
#: Largest number of mobility evaluations one call of :func:`structures` may plan (candidates
#: checked times ``n_poses``); each costs about 15 ms, so this is a few minutes of work.
MAX_POSE_CHECKS = 16_384
#: Largest allowed number of limbs in ``legs`` (the resource limit of an anchor pattern).
MAX_STRUCTURE_LEGS = MAX_LEGS


def _describe(value) -> str:
    r = repr(value)
    return r if len(r) <= 60 else r[:57] + "..."


def _leg_types(leg_types) -> list[str]:
    """The limb types to draw from, each once, in the registry's order (so that neither the
    result nor its validity depends on the order or repetition of ``leg_types``)."""
    if leg_types is None:
        return list(LIMB_TYPES)
    original = leg_types
    if isinstance(leg_types, str):
        leg_types = [t for t in leg_types.replace(",", " ").split() if t]
    elif isinstance(leg_types, (set, frozenset)):
        leg_types = sorted(leg_types, key=str)
    if not isinstance(leg_types, (list, tuple)):
        raise StructureError(f"leg_types must be a list of limb type names of {', '.join(LIMB_TYPES)} (or one "
                             f"string of them separated by commas), got {_describe(leg_types)}")
    if not leg_types:
        raise StructureError(f"leg_types must name at least one limb type of {', '.join(LIMB_TYPES)}, got "
                             f"{_describe(original)}")
    given, twice = set(), []
    for j, t in enumerate(leg_types):
        if not isinstance(t, str):
            raise StructureError(f"leg_types[{j}] must be a limb type name of {', '.join(LIMB_TYPES)}, got "
                                 f"{_describe(t)}")
        try:
            name = limb_type(t.strip()).name
        except StructureError as e:
            raise StructureError(f"leg_types: {e}") from None
        if name in given and name not in twice:
            twice.append(name)
        given.add(name)
    if twice:
        warnings.warn(f"leg_types: {', '.join(twice)} given more than once, counted once", StructureWarning,
                      stacklevel=3)
    return [t for t in LIMB_TYPES if t in given]


def _legs(legs) -> list[int] | None:
    """The allowed total numbers of limbs, sorted, each once (None: any)."""
    if legs is None:
        return None
    allowed = f"integers in [2, {MAX_STRUCTURE_LEGS}], e.g. [5, 6]"
    if is_real_number(legs):
        legs = [legs]
    if isinstance(legs, np.ndarray) and legs.ndim == 1:
        legs = legs.tolist()
    if not isinstance(legs, (list, tuple, set, frozenset)) or not legs:
        raise StructureError(f"legs must be numbers of limbs ({allowed}), got {_describe(legs)}")
    out = set()
    for n in legs:
        if not is_real_number(n) or not math.isfinite(float(n)) or not float(n).is_integer() or n < 2:
            raise StructureError(f"legs must be numbers of limbs ({allowed}), got {_describe(n)} in "
                                 f"{_describe(legs)}")
        if n > MAX_STRUCTURE_LEGS:
            raise StructureError(f"legs must be at most {MAX_STRUCTURE_LEGS} (the documented maximum), got "
                                 f"{_describe(n)}")
        out.add(int(n))
    return sorted(out)


def structures(motion, *, leg_types=None, legs=None, axes=None, all_axes: bool = False, n_poses: int = 4,
               seed: int = 0, show_dropped: bool = False, processes: int | None = None) -> StructureList:
    """The candidate structures of the vocabulary for ``motion`` (``"3T3R"``, ``"3T2R"``,
    ``"2T2R"``, ...), each verified numerically.

    ``leg_types``: limb types to draw from (a list of names, or one string separated by commas;
    default the whole vocabulary, ``parasynth.structures.LIMB_TYPES``; a type given twice counts
    once, and the order does not matter: candidates are always enumerated in the registry's
    order); ``legs``: allowed total numbers of limbs (e.g. ``[5, 6]``, integers in [2,
    :data:`MAX_STRUCTURE_LEGS`]; default any); ``axes``: the axes the freedoms must have, e.g.
    ``{"translations": ["x", "z"], "rotations": ["y", "moving x"]}`` (the 2-RPU&2-SPS's;
    :func:`parse_axes`; the axes of a structure are those of its motion template,
    ``Structure.axes``); ``all_axes`` (a bool): every joint-axis choice of the vocabulary
    instead of the first of each; ``n_poses``: reachable random poses of the task box checked
    per candidate (1 to :data:`MAX_POSES`; the candidates to check times ``n_poses`` at most
    :data:`MAX_POSE_CHECKS`, about 15 ms each); ``seed``: their seed (0 to 2**32 - 1);
    ``show_dropped`` (a bool): :meth:`StructureList.summary` lists every dropped candidate by
    name under its reason (under- and over-actuated, singular at home, equivalent, ...; the
    names are in ``dropped_names`` either way). A kept structure is controlled at its home pose
    with a singularity margin of at least :data:`SINGULARITY_FLOOR` at the default dimensions
    (the level platform, else the first of ``HOME_TILTS`` that is, as its default
    ``home_tilt``); kinematically equivalent structures are reported as one
    (``Structure.equivalents``, ``Structure.label``). ``processes``: how many processes check
    the candidates (forked, :data:`PARALLEL_CHECKS` candidates or more; default the engine's
    thread count, i.e. the cores or a study worker's share of them; 1: this process alone); the
    answer is the same for any number.
    Returns a :class:`StructureList` of :class:`Structure` with the counts of the dropped
    candidates by reason. :class:`StructureError` (a ``ValueError``) names the argument at
    fault."""
    nt, nr = parse_motion(motion)
    motion = f"{nt}T{nr}R"
    types = _leg_types(leg_types)
    legs = _legs(legs)
    try:
        n_poses = check_count("n_poses", n_poses, 1, MAX_POSES)
        seed = check_count("seed", seed, 0, MAX_SEED, what="an integer")
    except InputError as e:
        raise StructureError(str(e)) from None
    if not isinstance(all_axes, (bool, np.bool_)):
        raise StructureError(f"all_axes must be True or False, got {_describe(all_axes)}")
    if not isinstance(show_dropped, (bool, np.bool_)):
        raise StructureError(f"show_dropped must be True or False, got {_describe(show_dropped)}")
    if processes is not None:
        try:
            processes = check_count("processes", processes, 1, 1024)
        except InputError as e:
            raise StructureError(f"{e}; or None for the engine's thread count") from None
    all_axes = bool(all_axes)
    dof = nt + nr
    most = max(6 - LIMB_TYPES[t].constraints for t in types)
    if dof > most:  # every structure holds a limb of these types, and moves within that limb's freedoms
        raise StructureError(f"motion {motion}: the limb types {', '.join(types)} leave at most {most} freedoms each (6 "
                             f"less their constraint wrenches), so no structure of them has {dof}; allowed: a motion of "
                             f"at most {most} freedoms, or limb types with more")
    want_axes = parse_axes(axes)
    if want_axes is not None:
        for k, n in (("translations", nt), ("rotations", nr)):
            if k in want_axes and len(want_axes[k]) != n:
                raise StructureError(f"axes.{k}: {motion} has {n} {k}, {len(want_axes[k])} axes given "
                                     f"({', '.join(sorted(want_axes[k])) or 'none'})")
    dropped = {r: 0 for r in DROP_REASONS}
    dropped_names = {r: [] for r in DROP_REASONS}
    seen = set()
    cands = candidates(types, legs, all_axes)
    if legs is not None:
        possible = sorted({c.n_legs for c in candidates(types, None, all_axes)})
        none = [n for n in legs if n not in possible]
        if none:
            warnings.warn(f"legs: no candidate of the limb types {', '.join(types)} has {', '.join(map(str, none))} "
                          f"limbs (possible: {', '.join(map(str, possible)) or 'none'}); "
                          f"{'those counts add nothing' if len(none) < len(legs) else 'nothing is enumerated'}",
                          StructureWarning, stacklevel=2)

    # the same arguments, engine and code give the same structures: kept on disk between
    # processes (parasynth.common.cache; PARASYNTH_CACHE_DIR=off disables it)
    cache_key = None
    if _own_vocabulary(types):
        cache_key = (motion, tuple(types), None if legs is None else tuple(legs), all_axes,
                     None if want_axes is None else tuple(sorted((k, tuple(sorted(v))) for k, v in want_axes.items())),
                     n_poses, seed, check_engine("compiled"))
    kept = None if cache_key is None else _cache.load("structures", cache_key, StructureList)
    if kept is not None:
        kept.show_dropped = bool(show_dropped)
        return kept
    no_rule, no_home = {}, {}

    def drop(reason, c):
        dropped[reason] += 1
        dropped_names[reason].append(c.name)

    def too_many(n_check, at_least=""):
        if n_check * n_poses > MAX_POSE_CHECKS:
            raise StructureError(f"n_poses: {n_poses} poses for each of the {at_least}{n_check} candidates to check "
                                 f"are {n_check * n_poses} mobility evaluations (about "
                                 f"{n_check * n_poses * 0.015 / 60:.0f} min), more than the documented maximum "
                                 f"{MAX_POSE_CHECKS}; give a smaller n_poses or fewer leg_types")

    def keep(c, key, template):
        if template is not None and want_axes is not None and template.motion == motion \
                and not _axes_match(template, want_axes):
            drop("other axes", c)
        elif c.n_actuated < dof:
            drop("under-actuated", c)
        elif c.n_actuated > dof:
            drop("over-actuated", c)
        else:
            to_check.append((c, key, template))

    # the cheap rules first, so that the work of the checks is known before any is done; the
    # motions computed from the limbs' closure equations (structures/motion.py) come second, once
    # the candidates with a template alone are known not to exceed the budget of checks
    to_check = []
    pending = []
    order = {id(c): i for i, c in enumerate(cands)}
    for c in cands:
        key = _key(c.groups)
        if key in seen:
            drop("duplicate", c)
            continue
        seen.add(key)
        template = c.template()
        if template is None and c.n_actuated == dof:
            if _fewest_freedoms(c.groups) < dof:  # no closure solve needed: a limb's freedoms bound the motion's
                drop("wrong motion", c)
                continue
            pending.append((c, key))  # only a candidate with as many actuators as freedoms gets a rule
            continue
        keep(c, key, template)
    if pending:
        too_many(len(to_check), "at least ")
    rules = _spread(lambda c: candidate_rule(c.groups, lambda t: _description(c, t, "rule")),
                    [c for c, _ in pending], processes)
    for (c, key), (template, why, reason) in zip(pending, rules):
        remember_rule(c.groups, (template, why, reason))  # a rule found in another process, for later calls
        if template is None:
            drop(reason, c)
            (no_rule if reason == "no task rule" else no_home)[f"{c.name} [{'; '.join(g.label() for g in c.groups)}]"] = why
        elif template.motion != motion:
            drop("wrong motion", c)
        else:
            keep(c, key, template)
    to_check.sort(key=lambda t: order[id(t[0])])  # enumeration order, as the candidates came
    too_many(len(to_check))
    jobs = []
    for c, key, template in to_check:
        arrs = "-".join(dict.fromkeys(g.arrangement for g in c.groups if g.actuated))
        short = f"{arrs}-{hashlib.sha1(repr(key).encode()).hexdigest()[:6]}"
        jobs.append((c, motion, _description(c, template, short), n_poses, seed))
    found = []
    for (c, key, template), (reason, det, desc, cls, home_margin) in zip(to_check, _verified(jobs, processes)):
        if reason is not None:
            drop(reason, c)
            continue
        if desc is None:
            drop("singular at home", c)
            continue
        s = Structure(
            name=c.name, key=desc["name"], motion=motion,
            leg_counts=dict(Counter(g.limb for g in c.groups for _ in range(g.count))),
            actuated_counts=dict(Counter(g.limb for g in c.groups if g.actuated for _ in range(g.count))),
            groups=c.groups, arrangement="; ".join(g.label() for g in c.groups), template=template.name,
            axes=dict(template.axes), description=desc, checked_poses=det["checked"],
            controlled_poses=det["controlled"], home_margin=home_margin, checked_margin=det["margin"])
        s._cls.append(cls)
        found.append(s)
    found = _fold_equivalents(found, drop)
    out = StructureList(found, motion, len(cands), dropped, dropped_names, show_dropped=bool(show_dropped),
                        no_task_rule=no_rule, no_home=no_home)
    if cache_key is not None:
        _cache.save("structures", cache_key, out)
    return out


#: The vocabulary as parasynth defines it (at import): an enumeration from it alone is kept on
#: disk (parasynth.common.cache, keyed by the package's code). A limb type registered or
#: replaced since (``register_limb``, a leg class of a plugin), or tables changed, are code the
#: cache's key does not see: such an enumeration is computed every time.
_OWN = ({k: (v, LEG_TYPES.get(k)) for k, v in LIMB_TYPES.items()},
        (ARRANGEMENTS, dict(ARRANGEMENTS)), (TEMPLATES, dict(TEMPLATES)), (PARAMETERS, dict(PARAMETERS)),
        HOME_TILTS, CHECKS, (EQUIVALENT_LIMBS, dict(EQUIVALENT_LIMBS)))


def _own_vocabulary(types) -> bool:
    """Whether the limb types ``types`` and the tables an enumeration reads are parasynth's own,
    as at import (the same objects)."""
    limbs, *tables, tilts, checks, equivalent = _OWN
    for t in types:
        own = limbs.get(t)
        if own is None or LIMB_TYPES.get(t) is not own[0] or LEG_TYPES.get(t) is not own[1]:
            return False
    current = (ARRANGEMENTS, TEMPLATES, PARAMETERS)
    if any(d is not snap[0] or d.keys() != snap[1].keys() or any(d[k] is not v for k, v in snap[1].items())
           for d, snap in zip(current, tables)):
        return False
    return HOME_TILTS is tilts and CHECKS is checks and EQUIVALENT_LIMBS == equivalent[1]


def _signature(s: Structure, mapping: dict) -> tuple:
    """The limb groups of ``s`` with limb types renamed by ``mapping`` and joint axes left out."""
    return tuple((mapping.get(g.limb, g.limb), g.count, g.actuated, g.arrangement, g.phase) for g in s.groups)


def _fold_equivalents(found: list, drop) -> list:
    """Report kinematically equivalent structures as one (:data:`EQUIVALENT_LIMBS`): a structure
    with an SPS or SPU group is folded into the kept structure with a UPS group in its place (the
    same arrangement), which lists it in ``equivalents`` with the reason (``idle spin``,
    ``inverted``); without such a UPS structure (UPS not among the limb types), into the first
    of its equivalents (an SPU structure into the SPS one: ``inverted, idle spin``, the reasons
    of both against the UPS). A folded structure is counted as dropped, reason ``equivalent``."""
    rename = {a: b for a, (b, _) in EQUIVALENT_LIMBS.items()}
    why = {a: r for a, (_, r) in EQUIVALENT_LIMBS.items()}

    def renamed(s):
        return any(g.limb in rename for g in s.groups)

    def reasons(s):
        return [why[g.limb] for g in s.groups if g.limb in rename]

    by_sig = {}
    for i, s in enumerate(found):  # the representative: a structure without SPS or SPU, else the first
        sig = _signature(s, rename)
        j = by_sig.get(sig)
        if j is None or (renamed(found[j]) and not renamed(s)):
            by_sig[sig] = i
    extra: dict = {}
    folded = set()
    for i, s in enumerate(found):
        j = by_sig[_signature(s, rename)]
        if j == i or not renamed(s):
            continue
        reason = ", ".join(dict.fromkeys(reasons(s) + reasons(found[j])))
        if (s.name, reason) not in extra.get(j, []):
            extra.setdefault(j, []).append((s.name, reason))
        folded.add(i)
        drop("equivalent", s)
    out = []
    for i, s in enumerate(found):
        if i in folded:
            continue
        if i in extra:
            s = dataclasses.replace(s, equivalents=tuple(extra[i]), _cls=list(s._cls))
        out.append(s)
    return out
