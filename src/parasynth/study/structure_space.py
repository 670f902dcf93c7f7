"""A study over structures: the ``structure:`` section resolved to one mechanism and one
categorical design variable.

A study that gives ``structure:`` (a motion, the allowed limb types, limb counts, arrangements,
axes) instead of ``mechanism:`` searches the structure and the dimensions together. The
candidates are enumerated and checked by :func:`parasynth.structures` once, when the study is
resolved; they all declare the same parameters (the shared parametrisation,
:data:`parasynth.structures.PARAMETERS`), so they are written as **one mechanism
description** whose variant ``structure`` selects a candidate (its anchors, limbs, task and
constraints overlaid on the first). That description is registered in the mechanism registry
under a name derived from its content (:func:`resolve_structures`), so every part of a study
that builds a mechanism -- the evaluator, ``check_study``, the final re-evaluation, the report's
sketches -- builds ``load_mechanism(study.mechanism, structure=..., base_radius=...)`` as for
any other study, and the structure is a categorical design variable beside the dimensions:

* the variable ``structure`` (choices: the structures' labels, the field's names such as
  ``5-PUS/UPU``, with the arrangement added where two structures share a name) is added first
  unless the study lists it (to keep a subset of the choices);
* a dimension that some structures do not use (``link_length`` of a structure without links of
  fixed length, ``platform_twist`` of paired rings, ...) gets the condition ``when: {structure:
  [the structures using it]}``, so it is absent from their designs (:func:`conditions`).

How the evaluations are spread over the structures (successive halving) is
:mod:`parasynth.study.schedule`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
from dataclasses import dataclass

from .. import structures as synthesis
from ..common.validation import numpy_reference
from ..engine import compiling_early
from ..mechanisms import described_class, register
from .errors import StudyError
from .optimizers.base import optimizer_class
from .space import DesignSpace, Variable

__all__ = ["STRUCTURE", "STRUCTURE_FLOOR_LABEL", "StructureSetup", "resolve_structures", "conditions", "labels_of",
           "structure_variables", "check_structure_optimizer", "check_halving", "STRUCTURE_ALGORITHMS", "box_centre"]

#: Optuna samplers of a study over structures: those whose proposals depend only on the trials
#: they are shown (each structure's sampler sees that structure's trials, see
#: :mod:`parasynth.study.schedule`); NSGA-II/III keep generations and CMA-ES its state in the study.
STRUCTURE_ALGORITHMS = ("tpe", "random")

#: The name of the structure design variable (and of the description's variant).
STRUCTURE = "structure"
#: The column of the constraint every study over structures gets unless it gives one on
#: ``home_singularity_margin``: the design's singularity margin at its home pose at least the
#: study's ``evaluation.singularity_floor`` (default ``SINGULARITY_FLOOR``), so that structures are
#: compared on designs that pass the same floor.
STRUCTURE_FLOOR_LABEL = "home_floor"


@dataclass(frozen=True)
class StructureSetup:
    """The structures of a study: ``labels`` (choice names, in enumeration order),
    ``structures`` ({label: :class:`~parasynth.structures.Structure`}), ``reference`` (the
    reference structure's label or None), ``uses`` ({label: shared parameters its description
    uses}), ``enumerated`` and ``dropped`` (the enumeration's counts), ``mechanism`` (the
    registry name of the combined description)."""

    motion: str
    labels: tuple
    structures: dict
    reference: str | None
    uses: dict
    enumerated: int
    dropped: dict
    mechanism: str

    def label_of(self, s) -> str:
        return next(k for k, v in self.structures.items() if v is s)


def labels_of(found) -> list[str]:
    """A unique label per structure: its name, with its arrangements added where two structures
    share a name (``6-PUS (regular)``, ``6-PUS (paired)``)."""
    names = [s.name for s in found]
    out = []
    for s in found:
        if names.count(s.name) == 1:
            out.append(s.name)
        else:
            arr = "/".join(dict.fromkeys(g.arrangement for g in s.groups if g.arrangement != "central"))
            out.append(f"{s.name} ({arr})")
    if len(set(out)) != len(out):  # the same name and arrangement, other joint axes: name the axes that differ
        axes = [tuple((g.limb, k, v) for g in s.groups for k, v in g.axes) for s in found]
        fixed = {lab: set.intersection(*[set(a) for a, o in zip(axes, out) if o == lab]) for lab in set(out)}
        out = [f"{lab} [{', '.join(f'{t} {k}={v}' for t, k, v in a if (t, k, v) not in fixed[lab])}]"
               if out.count(lab) > 1 else lab for lab, a in zip(out, axes)]
    if len(set(out)) != len(out):  # still the same: the description's key
        out = [f"{lab} [{s.key.rsplit('-', 1)[-1]}]" if out.count(lab) > 1 else lab for lab, s in zip(out, found)]
    return out


_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def _uses(desc: dict) -> frozenset:
    """The shared parameters a structure's description refers to (outside its parameter list)."""
    text = json.dumps({k: v for k, v in desc.items() if k not in ("parameters", "name", "summary", "description")})
    return frozenset(w for w in _WORD.findall(text) if w in synthesis.PARAMETERS)


def _combined(motion: str, labels, found) -> dict:
    """One description of every structure: the first as the base, each as a choice of the
    variant ``structure`` overlaying its anchors, limbs, task, length scale and constraints."""
    first = found[0].description
    sets = {sec: sorted({k for s in found for k in s.description[sec]}) for sec in ("base", "platform")}
    task_keys = sorted({k for s in found for k in s.description["task"]})
    choices = {}
    for lab, s in zip(labels, found):
        d = s.description
        over = {sec: {k: d[sec].get(k) for k in sets[sec]} for sec in ("base", "platform")}
        over["task"] = {k: d["task"].get(k) for k in task_keys}
        over.update(legs=d["legs"], constraints=d["constraints"], length_scale=d["length_scale"],
                    description=f"{lab}: {s.arrangement}. {d['description']}")
        choices[lab] = over
    base = {k: v for k, v in first.items() if k not in ("name", "summary")}
    return {"name": f"structures_{motion.lower()}", "summary": f"{len(found)} structures of {motion} "
            f"(parasynth.structures): {', '.join(labels)}", **base,
            "variants": {STRUCTURE: {"default": labels[0], "doc": "the structure (parasynth.structures)",
                                     "choices": choices}}}


_CACHE: dict = {}


def resolve_structures(sec) -> StructureSetup:
    """The structures of a study's ``structure:`` section (a
    :class:`~parasynth.study.spec.StructureSpec`), their combined description registered in the
    mechanism registry; :class:`StudyError` naming the key at fault. Cached per section."""
    key = json.dumps(sec.model_dump(), sort_keys=True)
    if key in _CACHE:
        return _CACHE[key]
    # an empty leg_types, axes, arrangements or include is refused: it never means "all"
    axes = dict(sec.axes) if sec.axes is not None else None
    for k in ("arrangements", "include"):
        if getattr(sec, k) is not None and not getattr(sec, k):
            raise StudyError(f"structure.{k}: an empty list would keep no structure; name at least one, or leave "
                             f"the key out for all")
    try:
        # on the NumPy reference: the enumeration evaluates a few poses per candidate, and a
        # compile here (pose and constraint-rank kernels, ~8 s CPU on an empty cache, the latter
        # used by nothing else of a study) would stand alone before the run's own side-by-side
        # compile (docs/performance.md, "Cold start of the structure studies")
        # its candidates checked on the cores (forked processes) unless compiling helpers
        # started ahead of the run hold them (engine.compiling_early)
        with numpy_reference():
            found = synthesis.structures(sec.motion, leg_types=sec.leg_types, legs=sec.legs, axes=axes,
                                         all_axes=sec.all_axes, processes=1 if compiling_early() else None)
    except ValueError as e:
        msg = str(e)
        if msg.startswith(("leg_types", "legs", "axes", "all_axes")):  # the message names its field
            raise StudyError(f"structure.{msg}") from None
        field = "leg_types" if "limb type" in msg else "motion"
        raise StudyError(f"structure.{field}: {msg}") from None
    kept = list(found)
    if sec.arrangements is not None:
        known = [a for a, v in synthesis.ARRANGEMENTS.items() if v.role == "ring"]
        for j, a in enumerate(sec.arrangements):
            if a not in known:
                raise StudyError(f"structure.arrangements[{j}]: unknown arrangement {a!r}; ring arrangements: "
                                 f"{', '.join(known)}")
        kept = [s for s in kept if all(g.arrangement in sec.arrangements for g in s.groups
                                       if g.arrangement != "central")]
    labels = labels_of(kept)
    def names_of(s):  # its name and those of the equivalent structures reported with it
        return (s.name,) + tuple(n for n, _ in s.equivalents)

    if sec.include is not None:
        for j, x in enumerate(sec.include):
            if x not in labels and not any(x in names_of(s) for s in kept):
                raise StudyError(f"structure.include[{j}]: {x!r} is not among the structures found; found: "
                                 f"{', '.join(labels) or '(none)'}")
        pairs = [(lab, s) for lab, s in zip(labels, kept) if lab in sec.include or set(names_of(s)) & set(sec.include)]
        labels, kept = [p[0] for p in pairs], [p[1] for p in pairs]
    dropped = {k: v for k, v in found.dropped.items() if v}
    if len(kept) < 2:
        raise StudyError(f"structure: {len(kept)} structure(s) of {found.motion} match ({', '.join(labels) or 'none'}; "
                         f"dropped: {', '.join(f'{k} {v}' for k, v in dropped.items()) or 'none'}); a study over "
                         f"structures needs at least two (for one, write its description with `parasynth structures "
                         f"--out DIR` and give it as mechanism:)")
    by_coords: dict = {}  # the structures of each set of task coordinates, in enumeration order
    for lab, s in zip(labels, kept):
        by_coords.setdefault(tuple(s.description["task"]["coordinates"]), []).append((lab, s))
    if len(by_coords) > 1:
        def listed(found):
            labs = [lab for lab, _ in found]
            return ", ".join(labs[:3]) + (f" and {len(labs) - 3} more" if len(labs) > 3 else "")

        def axes(found):  # the structure.axes that selects the set
            ax = found[0][1].axes
            return ("axes: {" + ", ".join(f"{k}: [{', '.join(ax.get(k, ()))}]" for k in ("translations", "rotations"))
                    + "}")

        sets = "; ".join(f"{', '.join(c)} ({axes(f)}: {listed(f)})" for c, f in by_coords.items())
        raise StudyError(f"structure: the structures found move in different task coordinates: {sets}; a study "
                         f"compares structures over one task box, so keep those of one set: give structure.axes "
                         f"as above, or restrict structure.leg_types or structure.include")
    ref = sec.reference
    if ref is not None and ref not in labels:
        # a name shared by several structures (their arrangements) is the first of them in
        # enumeration order; a label names one
        byname = [lab for lab, s in zip(labels, kept) if ref in names_of(s)]
        if not byname:
            raise StudyError(f"structure.reference: {ref!r} is not any of the structures found; found: "
                             f"{', '.join(labels)}")
        ref = byname[0]
    desc = _combined(found.motion, labels, kept)
    digest = hashlib.sha1(json.dumps(desc, sort_keys=True).encode()).hexdigest()[:10]
    name = f"structures-{found.motion}-{digest}"
    try:
        cls = described_class(desc, source=f"structure ({found.motion})")
    except ValueError as e:
        raise StudyError(f"structure: the combined description of the structures is not valid: {e}") from None
    register(name, lambda: cls, desc["summary"], listed=False)
    setup = StructureSetup(found.motion, tuple(labels), dict(zip(labels, kept)), ref,
                           {lab: _uses(s.description) for lab, s in zip(labels, kept)}, found.enumerated, dropped, name)
    _CACHE[key] = setup
    return setup


def conditions(setup: StructureSetup, name: str, choices) -> tuple:
    """The ``when`` condition of the shared parameter ``name`` as a design variable: the
    structures (of ``choices``) whose description uses it; () when every one does."""
    users = tuple(lab for lab in choices if name in setup.uses[lab])
    if len(users) == len(tuple(choices)):
        return ()
    if not users:
        raise StudyError(f"variables: {name!r} is used by none of the structures {', '.join(choices)}; leave it out")
    return ((STRUCTURE, users),)


def structure_variables(setup: StructureSetup, variables) -> list:
    """The design variables of a study over structures: the categorical ``structure`` first
    (unless the study lists it), each shared dimension conditional on the structures using it
    (:func:`conditions`; a condition the study gives is kept)."""
    variables = list(variables)
    own = next((v for v in variables if v.name == STRUCTURE), None)
    if own is None:
        own = Variable(STRUCTURE, "categorical", None, choices=setup.labels)
        variables.insert(0, own)
    elif own.type != "categorical":
        raise StudyError(f"variables: {STRUCTURE!r} is the structure; give it as type: categorical with choices among "
                         f"{', '.join(setup.labels)}")
    out = []
    for v in variables:
        if v is not own and not v.when and v.name in synthesis.PARAMETERS:
            when = conditions(setup, v.name, own.choices)
            if when:
                v = dataclasses.replace(v, when=when)
        out.append(v)
    return out


def check_structure_optimizer(opt) -> None:
    """A study over structures runs on an optimiser that can (Optuna, successive halving over
    the structures, with a sampler of :data:`STRUCTURE_ALGORITHMS`; or a sweep); :class:`StudyError`
    naming the optimiser otherwise (:meth:`~parasynth.study.optimizers.BaseOptimizer.check_structures`)."""
    optimizer_class(opt.kind).check_structures(opt)


def check_halving(sec, opt, choices, budget: int) -> None:
    """The successive-halving settings of a ``structure:`` section given explicitly
    (``screening``, ``eta``, ``keep``) must act: :class:`StudyError` naming the key when a sweep
    would ignore them (a sweep evaluates its listed designs, no rungs), when the budget per
    structure (``budget``: optimizer.n_trials, or its default) would clip the screening, when
    there is only one rung (screening equal to the budget: ``eta`` and ``keep`` unused), or
    when ``keep`` keeps every one of the structures (``choices``) after every rung. Defaults
    left out are not checked (the default screening is clipped to a smaller budget, as
    documented)."""
    given = [k for k in ("screening", "eta", "keep") if k in sec.model_fields_set and getattr(sec, k) is not None]
    if not given:
        return
    if not optimizer_class(opt.kind).halving:
        raise StudyError(f"structure.{given[0]}: successive halving spreads the trials of an Optuna study; a "
                         f"{opt.kind} evaluates its listed designs and would ignore it -- leave it out")
    if "screening" in given and sec.screening > budget:
        raise StudyError(f"structure.screening: {sec.screening} designs per structure in the first rung exceed the "
                         f"budget of {budget} designs per structure (optimizer.n_trials); give screening <= {budget} "
                         f"or raise optimizer.n_trials")
    if min(sec.screening, budget) >= budget:
        for k in ("eta", "keep"):
            if k in given:
                raise StudyError(f"structure.{k}: the screening ({min(sec.screening, budget)} designs) is already the "
                                 f"whole budget per structure (optimizer.n_trials {budget}): there is one rung and "
                                 f"{k} is not used -- leave it out, or give a smaller structure.screening")
    if "keep" in given and sec.keep >= len(choices):
        raise StudyError(f"structure.keep: {sec.keep} structures continuing after each rung keep every one of the "
                         f"{len(choices)} structures (no halving); give keep < {len(choices)} or leave it out")


def box_centre(study) -> dict:
    """The centre of a study's design space, {variable: value}: the one entry point for it. The
    middle of every variable's range (:func:`parasynth.study.space.centre_value`: on its scale,
    integers rounded, the middle listed value, the first choice), and for a study over
    structures its reference structure (else the first) with the dimensions that structure uses."""
    space = getattr(study, "space", None) or DesignSpace(study.variables)
    setup = getattr(study, "structures", None)
    if setup is None or setup.reference is None:
        return space.centre()
    return space.centre({STRUCTURE: setup.reference})
