"""The vocabulary of structural synthesis: limb types, their arrangements, the shared
parametrisation and the motion templates that give a structure its task coordinates.

A :class:`LimbType` says which leg model of :mod:`parasynth.model.legs` a limb is, which joint is
actuated, whether it may be a passive constraining limb, how many constraint wrenches it
imposes, where it may be placed (its *arrangements*: anchor patterns and joint axes) and, for a
constraining limb, which motion template a placement yields. :data:`LIMB_TYPES` is the registry:
:func:`register_limb` adds a type, and every enumeration after that uses it
(docs/structures.md).

This module is data: it imports nothing of parasynth but :mod:`parasynth.model.legs`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..model import chains as _chains  # noqa: F401  (the chain limbs' leg types)
from ..model.legs import LEG_TYPES

__all__ = ["Arrangement", "LimbType", "Template", "LIMB_TYPES", "ARRANGEMENTS", "TEMPLATES", "PARAMETERS",
           "CHECKS", "HOME_TILTS", "OFFSET_DEFAULTS", "register_limb", "limb_type", "parse_motion", "StructureError", "StructureWarning"]


class StructureError(ValueError):
    """An argument of structural synthesis that is not allowed (a motion, a limb type, limb
    counts, axes, a setting); the message starts with the argument's name."""


class StructureWarning(UserWarning):
    """An argument of structural synthesis that is taken but partly has no effect (a limb type
    given twice, a number of limbs no candidate can have); the message starts with its name."""


@dataclass(frozen=True)
class Arrangement:
    """Where the limbs of a group sit. ``role``: ``"ring"`` (a group of actuated limbs on the
    base and platform circles) or ``"central"`` (one passive limb from the base origin to the
    platform centre); ``counts``: the group sizes it allows."""

    name: str
    role: str
    counts: tuple[int, ...]
    doc: str


#: The anchor patterns. A ring group at phase ``phi`` (0 unless it is the second group of an
#: interleaved structure, then 180/k deg) is placed as follows.
ARRANGEMENTS = {
    "regular": Arrangement("regular", "ring", (3, 4, 5, 6),
                           "base: regular polygon of n on base_radius at phi; platform: regular polygon of n on "
                           "platform_radius at phi + platform_twist"),
    "paired": Arrangement("paired", "ring", (3, 4, 5, 6),
                          "n = 4, 6: base: n/2 pairs on base_radius centred at phi + 360 k/(n/2), base_separation "
                          "apart; platform: n/2 pairs on platform_radius turned by 180/(n/2) deg, "
                          "platform_separation apart; each base joint goes to the nearest joint of the "
                          "neighbouring platform pair (semi-regular hexagons for n = 6). n = 3, 5 (no even "
                          "split): limb i (0 to n-1) at phi + 360 i/n + s_i base_separation/2 on the base and "
                          "phi + 360 i/n - s_i platform_separation/2 on the platform, s_i = +1 for even i, -1 for "
                          "odd i: neighbouring limbs alternately closer and farther apart, crossed between base "
                          "and platform"),
    "irregular": Arrangement("irregular", "ring", (2, 3, 4, 5, 6),
                             "limb i (1 to n) at phi + 360 (i-1)/n + base_offset_i on base_radius and at phi + "
                             "360 (i-1)/n + platform_twist + platform_offset_i on platform_radius (no twist in a "
                             "structure with an opposed pair); base_offset_1 = platform_offset_1 = 0 (the phase "
                             "and the twist turn the whole ring): the spacing of the limbs is a design variable, "
                             "and the regular ring is its point with every offset 0"),
    "opposed": Arrangement("opposed", "ring", (2,),
                           "two limbs facing each other across the centre: base at phi and phi + 180 deg on "
                           "base_radius, platform at the same angles on platform_radius (no twist)"),
    "central": Arrangement("central", "central", (1,),
                           "one passive limb from the base origin to the platform centre"),
}


@dataclass(frozen=True)
class Template:
    """A motion template: the task section (coordinates, dependent names, position,
    orientation, validity, home, ranges; expressions of the shared parameters) that a
    constraining placement allows, its motion type and the axes of its freedoms."""

    name: str
    motion: str
    task: dict
    axes: dict
    doc: str


_ANG = "angle"
_LEN = "length"
_BOX_XY = ["-reach", "reach"]
_BOX_Z = ["height - reach", "height + reach"]
_TILT = ["-tilt", "tilt"]
_HOME_TILT = "home_tilt"

TEMPLATES = {
    "free": Template(
        "free", "3T3R",
        {"coordinates": {"x": _LEN, "y": _LEN, "z": _LEN, "alpha": _ANG, "beta": _ANG, "gamma": _ANG},
         "position": ["x", "y", "z"],
         "orientation": {"convention": "xyz", "angles": ["alpha", "beta", "gamma"]},
         "home": {"x": "0 mm", "y": "0 mm", "z": "height", "alpha": "0 deg", "beta": _HOME_TILT, "gamma": "0 deg"},
         "ranges": {"x": _BOX_XY, "y": _BOX_XY, "z": _BOX_Z, "alpha": _TILT, "beta": _TILT, "gamma": _TILT}},
        {"translations": ("x", "y", "z"), "rotations": ("x", "moving y", "moving z")},
        "no limb constrains the platform: the platform centre and x-y-z angles, R = Rx Ry Rz"),
    "upu_central": Template(
        "upu_central", "3T2R",
        {"coordinates": {"x": _LEN, "y": _LEN, "z": _LEN, "alpha": _ANG, "beta": _ANG},
         "define": {"q1": "atan2(x, z)"},
         "position": ["x", "y", "z"],
         "orientation": {"convention": "yxy", "angles": ["q1", "alpha", "beta - q1"]},
         "valid": ["x**2 + z**2 > 1e-12"],
         "home": {"x": "0 mm", "y": "0 mm", "z": "height", "alpha": "0 deg", "beta": _HOME_TILT},
         "ranges": {"x": _BOX_XY, "y": _BOX_XY, "z": _BOX_Z, "alpha": _TILT, "beta": _TILT}},
        {"translations": ("x", "y", "z"), "rotations": ("y", "the limb's cross axis")},
        "a central U-P-U limb with its base and platform universal-joint axes along y (the 5-PUS/UPU's "
        "constraining limb) forbids the rotation about the normal of the two cross axes: "
        "R = Ry(q1) Rx(alpha) Ry(beta - q1), q1 = atan2(x, z) the limb's angle about y"),
    "rps_central": Template(
        "rps_central", "2T3R",
        {"coordinates": {"x": _LEN, "z": _LEN, "alpha": _ANG, "beta": _ANG, "gamma": _ANG},
         "position": ["x", "0 mm", "z"],
         "orientation": {"convention": "xyz", "angles": ["alpha", "beta", "gamma"]},
         "home": {"x": "0 mm", "z": "height", "alpha": "0 deg", "beta": _HOME_TILT, "gamma": "0 deg"},
         "ranges": {"x": _BOX_XY, "z": _BOX_Z, "alpha": _TILT, "beta": _TILT, "gamma": _TILT}},
        {"translations": ("x", "z"), "rotations": ("x", "moving y", "moving z")},
        "a central R-P-S limb with its revolute axis along y keeps the platform centre in the plane y = 0 "
        "(a force along y through the sphere): position (x, 0, z), x-y-z angles"),
    "rpu_opposed": Template(
        "rpu_opposed", "2T2R",
        {"coordinates": {"x": _LEN, "z": _LEN, "theta": _ANG, "psi": _ANG},
         "position": ["x", "0 mm", "z"],
         "orientation": {"rotations": [{"axis": "y", "angle": "theta"}, {"axis": "x", "angle": "psi"}]},
         "home": {"x": "0 mm", "z": "height", "theta": _HOME_TILT, "psi": "0 deg"},
         "ranges": {"x": _BOX_XY, "z": _BOX_Z, "theta": _TILT, "psi": _TILT}},
        {"translations": ("x", "z"), "rotations": ("y", "moving x")},
        "two R-P-U limbs facing each other on the x axis, revolute axes along y (tangential) and platform "
        "universal axes along x (radial), as in the 2-RPU&2-SPS: a force along y and a couple normal to y and "
        "the platform's x: position (x, 0, z), R = Ry(theta) Rx(psi)"),
    "xy_ring": Template(
        "xy_ring", "3T2R",
        {"coordinates": {"x": _LEN, "y": _LEN, "z": _LEN, "alpha": _ANG, "beta": _ANG},
         "position": ["x", "y", "z"],
         "orientation": {"rotations": [{"axis": "x", "angle": "alpha"}, {"axis": "y", "angle": "beta"}]},
         "home": {"x": "0 mm", "y": "0 mm", "z": "height", "alpha": "0 deg", "beta": _HOME_TILT},
         "ranges": {"x": _BOX_XY, "y": _BOX_XY, "z": _BOX_Z, "alpha": _TILT, "beta": _TILT}},
        {"translations": ("x", "y", "z"), "rotations": ("x", "moving y")},
        "a ring of R-P-U-R or P-R-U-R limbs (Masouleh, Gosselin et al.) with their base-side revolute axes along x "
        "and their platform-side ones along the platform's y: each limb imposes the couple about x x (R y), so "
        "R = Rx(alpha) Ry(beta)"),
}


@dataclass(frozen=True)
class LimbType:
    """A limb of the vocabulary.

    ``name``: the leg type of :mod:`parasynth.model.legs` (its joints, base to platform);
    ``actuated_joint``: the joint letter an actuated limb drives (None: never actuated);
    ``passive``: may be a passive constraining limb; ``constraints``: constraint wrenches it
    imposes at a generic pose (0: a six-freedom chain); ``arrangements``: the ring arrangements
    of actuated groups; ``options``: description options fixed for every placement (shared
    parameters by name); ``axes``: joint-axis options with the values allowed, the first the
    default (``radial``, ``tangent``, ``normal`` of the limb's own anchor, or x, y, z);
    ``central``: the options of its central placement (passive limbs only); ``templates``:
    {arrangement: template name} for a constraining limb; ``variants``: further joint-axis
    choices (tuples of (option, value) pairs) enumerated besides the first of each option, with
    or without ``all_axes`` (a choice whose axes are tied to each other, as ``centre`` at both
    universal joints of the spherical UPU)."""

    name: str
    actuated_joint: str | None
    passive: bool
    constraints: int
    arrangements: tuple[str, ...]
    options: dict = field(default_factory=dict)
    axes: dict = field(default_factory=dict)
    central: dict | None = None
    templates: dict = field(default_factory=dict)
    doc: str = ""
    variants: tuple = ()

    @property
    def joints(self) -> str:
        return self.name


#: Default offsets (deg strings) of limbs 2..6 of an irregular ring from the regular polygon, base and
#: platform: the base regular, the platform not similar to it (a platform polygon similar to the
#: base polygon leaves the 5-x/UPU singular with the platform level, as the regular pentagon).
OFFSET_DEFAULTS = (("0 deg", "0 deg", "0 deg", "0 deg", "0 deg"),
                   ("-15 deg", "-5 deg", "-20 deg", "-10 deg", "-25 deg"))
#: Home tilts (deg) tried, in order, for a structure singular at its level home pose.
HOME_TILTS = (10.0, 20.0)

#: The shared parametrisation: every structure's description declares these parameters, so a
#: study can compare structures with the same base, platform, links and strokes.
PARAMETERS = {
    "base_radius": ("300 mm", "radius of the base anchor circle (joints, slider lines, crank axes)"),
    "platform_radius": ("150 mm", "radius of the platform anchor circle"),
    "platform_twist": ("25 deg", "turn of a regular platform polygon against the base polygon"),
    "base_separation": ("20 deg", "angle between the two joints of a base pair (paired arrangement)"),
    "platform_separation": ("20 deg", "angle between the two joints of a platform pair (paired arrangement)"),
    "second_base_scale": ("1", "base radius of the second limb group of a two-kind structure, as a multiple of "
                               "base_radius (the 2-RPU&2-SPS's SPS limbs sit farther out than its RPU limbs)"),
    "second_platform_scale": ("1", "platform radius of the second limb group of a two-kind structure, as a multiple "
                                   "of platform_radius"),
    **{f"base_offset_{i}": (v, f"angle of limb {i}'s base anchor from its place in the regular polygon "
                               f"(irregular arrangement)") for i, v in zip(range(2, 7), OFFSET_DEFAULTS[0])},
    **{f"platform_offset_{i}": (v, f"angle of limb {i}'s platform anchor from its place in the regular polygon "
                                   f"(irregular arrangement)") for i, v in zip(range(2, 7), OFFSET_DEFAULTS[1])},
    "height": ("400 mm", "height of the platform centre above the base at home"),
    "home_tilt": ("0 deg", "rotation of the platform about y at the home pose (the template's rotation about y); a "
                           "structure singular with a level platform gets the first of HOME_TILTS at which its "
                           "actuators control it as its default"),
    "link_length": ("350 mm", "fixed link length of PUS, PRS and RUS limbs"),
    "crank_length": ("120 mm", "crank length of RUS limbs"),
    "q_min": ("250 mm", "shortest telescopic limb (SPS, UPS, RPU, RPS, UPU)"),
    "slider_min": ("-100 mm", "lower end of the slider stroke (PUS, PRS)"),
    "stroke": ("400 mm", "actuator stroke, the same for every telescopic limb (q_min to q_min + stroke) and "
                         "slider (slider_min to slider_min + stroke)"),
    "base_joint_max": ("40 deg", "cone-angle limit of the base-side spherical or universal joint of the ring limbs "
                                 "(from the limb's direction at home)"),
    "platform_joint_max": ("25 deg", "cone-angle limit of the platform joint (spherical or universal) of the ring "
                                     "limbs"),
    "link_diameter": ("8 mm", "diameter of the ring limbs for interference (distance between their centre lines)"),
    "reach": ("100 mm", "half-width of the task box in translation"),
    "tilt": ("20 deg", "half-width of the task box in rotation"),
}
CHECKS = ("stroke > 0",)

LIMB_TYPES: dict[str, LimbType] = {}


def register_limb(limb: LimbType) -> LimbType:
    """Add (or replace) a limb type of the vocabulary. Its name must be a leg type of
    :data:`parasynth.model.legs.LEG_TYPES`, its arrangements and templates known."""
    if limb.name not in LEG_TYPES:
        raise ValueError(f"limb type {limb.name!r}: not a leg type of parasynth.model.legs; leg types: "
                         f"{', '.join(sorted(LEG_TYPES))}")
    if limb.actuated_joint is not None and limb.actuated_joint not in limb.name:
        raise ValueError(f"limb type {limb.name!r}: actuated_joint {limb.actuated_joint!r} is not one of its "
                         f"joints {', '.join(limb.name)}")
    for a in limb.arrangements:
        if a not in ARRANGEMENTS or ARRANGEMENTS[a].role != "ring":
            raise ValueError(f"limb type {limb.name!r}: unknown ring arrangement {a!r}; ring arrangements: "
                             f"{', '.join(k for k, v in ARRANGEMENTS.items() if v.role == 'ring')}")
    for a, t in limb.templates.items():
        if t not in TEMPLATES:
            raise ValueError(f"limb type {limb.name!r}: unknown template {t!r} for {a!r}; templates: "
                             f"{', '.join(TEMPLATES)}")
    if limb.central is not None and not limb.passive:
        raise ValueError(f"limb type {limb.name!r}: a central placement needs a passive-capable limb")
    LIMB_TYPES[limb.name] = limb
    return limb


def limb_type(name: str) -> LimbType:
    """The registered limb type ``name``; :class:`StructureError` naming the vocabulary otherwise."""
    if not isinstance(name, str) or name not in LIMB_TYPES:
        raise StructureError(f"unknown limb type {name!r}; the vocabulary: {', '.join(LIMB_TYPES)}")
    return LIMB_TYPES[name]


def parse_motion(motion) -> tuple[int, int]:
    """``"3T2R"`` -> (3, 2); :class:`StructureError` naming the form otherwise."""
    s = motion.strip().upper() if isinstance(motion, str) else None
    if s is None or len(s) != 4 or s[1] != "T" or s[3] != "R" or s[0] not in "0123" or s[2] not in "0123" \
            or s in ("0T0R",):
        raise StructureError(f"motion must be written like '3T2R' (translations 0-3 'T', rotations 0-3 'R', at least "
                         f"one freedom), got {motion!r}")
    return int(s[0]), int(s[2])


_SLIDER = {"slider_axis": "z", "link_length": "link_length", "branch": -1}

for _limb in (
    LimbType("SPS", "P", False, 0, ("regular", "paired", "irregular"),
             doc="spherical, actuated prismatic, spherical: six freedoms (and a spin of the limb)"),
    LimbType("UPS", "P", False, 0, ("regular", "paired", "irregular"), axes={"u_axis": ("tangent", "radial")},
             doc="universal (axis fixed to the base), actuated prismatic, spherical: six freedoms"),
    LimbType("PUS", "P", False, 0, ("regular", "paired", "irregular"), options=dict(_SLIDER),
             axes={"u_axis": ("tangent", "radial")},
             doc="actuated vertical slider, universal, link of link_length, spherical: six freedoms"),
    LimbType("RUS", "R", False, 0, ("regular", "paired", "irregular"),
             options={"crank_length": "crank_length", "link_length": "link_length", "branch": 1},
             axes={"r_axis": ("tangent", "radial")},
             doc="actuated crank (revolute, axis tangential or radial), universal, link, spherical: six freedoms"),
    LimbType("RPS", "P", True, 1, ("regular",), axes={"r_axis": ("tangent",)},
             central={"r_axis": "y"}, templates={"central": "rps_central"},
             doc="revolute, prismatic, spherical: a force along the revolute axis through the sphere; in a ring "
                 "the 3-RPS's parasitic motion (no template); passive at the centre: rps_central"),
    LimbType("PRS", "P", False, 1, ("regular",), options=dict(_SLIDER), axes={"r_axis": ("tangent",)},
             doc="actuated vertical slider, revolute, link, spherical: a force along the revolute axis; in a ring "
                 "the 3-PRS's parasitic motion (no template)"),
    LimbType("RPU", "P", False, 2, ("opposed",), axes={"r_axis": ("tangent",), "u_platform_axis": ("radial",)},
             templates={"opposed": "rpu_opposed"},
             doc="revolute, actuated prismatic, universal: a force along the revolute axis and a couple; an "
                 "opposed pair gives rpu_opposed"),
    LimbType("UPU", "P", True, 1, ("regular",),
             axes={"u_axis": ("tangent", "radial", "z"), "u_platform_axis": ("tangent", "radial", "z")},
             central={"u_axis": "y", "u_platform_axis": "y"}, templates={"central": "upu_central"},
             variants=((("u_axis", "centre"), ("u_platform_axis", "centre")),),
             doc="universal, prismatic, universal (cross axes parallel): one constraint wrench; passive at the "
                 "centre (axes along y): upu_central; an actuated ring's motion is computed from its closure "
                 "(tangent axes: Tsai's translational 3-UPU, 3T0R; z axes: 3T1R; radial with z: 1T2R; centre at "
                 "both ends, the variant always enumerated: the base joint's first axis and the platform joint's "
                 "last axis through the platform centre at home, the spherical 3-UPU of Karouia and Herve, 0T3R, "
                 "its constraint a force through that centre normal to the plane of the centre and the limb)"),
):
    register_limb(_limb)

#: The chain limbs (:mod:`parasynth.model.chains`: joint strings solved numerically): their anchor
#: directions and the height of their home configuration from the shared parameters.
_CHAIN = {"radial": "radial", "tangent": "tangent", "home_height": "height"}
for _limb in (
    LimbType("RPUR", "P", False, 1, ("regular", "paired", "irregular"), options=dict(_CHAIN),
             templates={a: "xy_ring" for a in ("regular", "paired", "irregular")},
             doc="revolute (x), actuated prismatic, universal (x, then the platform's y), revolute (the platform's "
                 "y), solved numerically: one constraint couple; a ring of five gives the 5-RPUR's xy_ring"),
    LimbType("PRUR", "P", False, 1, ("regular", "paired", "irregular"), options=dict(_CHAIN),
             templates={a: "xy_ring" for a in ("regular", "paired", "irregular")},
             doc="actuated vertical slider, revolute (x), universal (x, then the platform's y), revolute (the "
                 "platform's y), solved by its closed form (PR-UR): one constraint couple; a ring of five gives the 5-PRUR's "
                 "xy_ring"),
    LimbType("SPU", "P", False, 0, ("regular", "paired", "irregular"), options=dict(_CHAIN),
             doc="spherical, actuated prismatic, universal at the platform, solved by its closed form (SP-U): six freedoms (the "
                 "inversion of the UPS)"),
    LimbType("RRPS", "P", False, 0, ("regular", "paired", "irregular"), options=dict(_CHAIN),
             doc="two revolutes (tangent, then normal to it and the limb, offset along the limb), actuated prismatic, "
                 "spherical, solved by its closed form (RRP-S): six freedoms"),
    LimbType("RRUR", "R", False, 1, ("regular", "paired", "irregular"), options=dict(_CHAIN),
             templates={a: "xy_ring" for a in ("regular", "paired", "irregular")},
             doc="actuated revolute (x), revolute (x) at an elbow off the limb's line, universal (x, then the "
                 "platform's y), revolute (the platform's y), solved by its closed form (RR-UR): one constraint couple about "
                 "x x (R y), as the RPUR (Masouleh, Gosselin et al.); a ring of five gives the 5-RRUR's xy_ring"),
    LimbType("RUU", "R", False, 1, ("regular", "paired", "irregular"), options=dict(_CHAIN),
             doc="actuated crank (revolute, tangent), universal at the crank's end (tangent, then the intermediate "
                 "axis normal to it and the limb), universal at the platform (the intermediate axis, then tangent), "
                 "solved numerically: one constraint couple normal to the tangent and the intermediate axis; a ring "
                 "of three is the translational 3-RUU (Kong and Gosselin 2007), its motion computed from the limbs' "
                 "closure"),
    LimbType("URPU", "P", False, 0, ("regular", "paired", "irregular"), options=dict(_CHAIN),
             doc="universal (tangent, then normal to it and the limb), revolute parallel to the universal joint's "
                 "second axis four fifths of the limb up, actuated prismatic, universal (radial, then normal to it and the limb), solved "
                 "numerically: six freedoms, the limb of the 6-URPU"),
    LimbType("PRRS", "P", False, 0, ("regular", "paired", "irregular"), options=dict(_CHAIN),
             doc="actuated vertical slider, two revolutes (tangent, then normal to it and the limb, offset along the "
                 "limb), link, spherical, solved numerically: six freedoms, the limb of the 6-PRRS"),
):
    register_limb(_limb)
