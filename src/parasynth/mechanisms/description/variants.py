"""The ``variants:`` section: named structural choices of a description.

A variant is a choice the numbers of ``parameters:`` cannot express: a different platform
layout, another set of anchor points, a different task parametrisation. Each variant has a
name (it becomes a field of the mechanism's ``Params``, so ``load_mechanism(..., name=choice)``,
``--param name=choice`` and categorical study variables select it), a ``default`` choice and
``choices``, each a *partial description* overlaid on the base one::

    variants:
      platform:
        default: rectangular
        doc: improved (rectangular) or first (pentagonal) scheme
        choices:
          rectangular: {}
          pentagonal:
            platform:
              S: {pattern: circle, radius: pentagon_radius, angles: slider_angles}

Choices are strings, or the two booleans ``true`` and ``false`` (a switch such as
``coupled``). The overlay rules (see ``docs/mechanisms.md``):

* mapping sections (``base``, ``platform``, ``task``, ``outputs``) are overlaid entry by entry:
  an entry of the overlay (an anchor set, a task key such as ``coordinates`` or ``home``, an
  output) replaces the base entry of the same name as a whole; ``null`` removes it;
* the other sections (``legs``, ``constraints``, ``checks``, ``length_scale``, ``description``)
  are replaced as a whole;
* ``name``, ``summary``, ``parameters`` and ``variants`` cannot be overlaid: every choice shares
  the same parameters (the ``Params`` class is one);
* variants are applied in the order they are declared, so a later variant's entry wins over
  an earlier one's (e.g. ``platform: pentagonal`` replaces the sphere set that
  ``hinge_layout`` chose).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from .errors import DescriptionError
from .parameters import _check_identifier, _check_keys

__all__ = ["Variant", "parse_variants", "apply_variants", "selection_key"]

#: Sections overlaid entry by entry; the other overlayable sections are replaced whole.
MERGED_SECTIONS = ("base", "platform", "task", "outputs")
REPLACED_SECTIONS = ("description", "checks", "legs", "constraints", "length_scale")
OVERLAYABLE = MERGED_SECTIONS + REPLACED_SECTIONS
#: Most variant combinations validated when a description is loaded (each one is parsed).
MAX_CHECKED_COMBINATIONS = 64


def _fmt(v) -> str:
    return ("true" if v else "false") if isinstance(v, bool) else repr(v)


@dataclass(frozen=True)
class Variant:
    """One named choice: ``choices`` maps each allowed value to its overlay (a mapping)."""

    name: str
    default: object
    choices: dict
    doc: str = ""

    @property
    def is_switch(self) -> bool:
        return all(isinstance(c, bool) for c in self.choices)

    @property
    def allowed(self) -> str:
        return ", ".join(_fmt(c) for c in self.choices)

    def coerce(self, value, where: str):
        """The choice ``value`` (a string, or a bool for a switch); ``ValueError`` naming the
        allowed choices otherwise."""
        if self.is_switch:
            if isinstance(value, (bool, np.bool_)):
                return bool(value)
            raise ValueError(f"{where} must be true or false, got {value!r}")
        if isinstance(value, str) and value in self.choices:
            return value
        raise ValueError(f"{where} must be one of {self.allowed}, got {value!r}")


def parse_variants(raw, reserved: set) -> list[Variant]:
    """The ``variants:`` section (``reserved``: names already taken by parameters)."""
    if raw is None:
        return []
    if not isinstance(raw, dict):
        raise DescriptionError("variants: give a mapping {name: {default: ..., choices: {choice: overlay}}}")
    out = []
    for name, spec in raw.items():
        path = f"variants.{name}"
        _check_identifier(name, path, "variant")
        if name in reserved:
            raise DescriptionError(f"{path}: {name!r} is also a parameter; use distinct names")
        if not isinstance(spec, dict):
            raise DescriptionError(f"{path}: give {{default: ..., choices: {{choice: overlay, ...}}}}, got {spec!r}")
        _check_keys(spec, {"default", "choices", "doc"}, path, "a variant")
        choices = spec.get("choices")
        if not isinstance(choices, dict) or len(choices) < 2:
            raise DescriptionError(f"{path}.choices: give at least two named choices, each a partial description "
                                   f"(use {{}} for the base description unchanged)")
        kinds = {type(c) for c in choices}
        if kinds == {bool}:
            if set(choices) != {True, False}:
                raise DescriptionError(f"{path}.choices: a switch has the two choices true and false")
        elif kinds != {str}:
            raise DescriptionError(f"{path}.choices: choice names are all strings, or the two booleans true and "
                                   f"false; got {', '.join(map(repr, choices))}")
        parsed = {}
        for c, overlay in choices.items():
            cp = f"{path}.choices.{_fmt(c) if isinstance(c, bool) else c}"
            if overlay is None:
                overlay = {}
            if not isinstance(overlay, dict):
                raise DescriptionError(f"{cp}: give a partial description (a mapping of sections), got {overlay!r}")
            bad = [k for k in overlay if k not in OVERLAYABLE]
            if bad:
                fixed = [k for k in bad if k in ("name", "summary", "parameters", "variants")]
                why = (" (every choice shares the description's name, summary and parameters: declare all "
                       "parameters at the top level)") if fixed else ""
                raise DescriptionError(f"{cp}: {', '.join(map(repr, bad))} cannot be overlaid by a variant{why}; "
                                       f"allowed: {', '.join(OVERLAYABLE)}")
            for k in MERGED_SECTIONS:
                if k in overlay and overlay[k] is not None and not isinstance(overlay[k], dict):
                    raise DescriptionError(f"{cp}.{k}: give a mapping of entries to replace, got {overlay[k]!r}")
            parsed[c] = overlay
        if "default" not in spec:
            raise DescriptionError(f"{path}.default: required key is missing; one of "
                                   f"{', '.join(_fmt(c) for c in choices)}")
        v = Variant(name, None, parsed, str(spec.get("doc", "") or ""))
        try:
            default = v.coerce(spec["default"], f"{path}.default")
        except ValueError as e:
            raise DescriptionError(str(e)) from None
        out.append(Variant(name, default, v.choices, v.doc))
    return out


def selection_key(variants, selection: dict) -> tuple:
    """Hashable key of a (complete) selection, in declaration order."""
    return tuple(selection[v.name] for v in variants)


def apply_variants(data: dict, variants, selection: dict) -> dict:
    """The description ``data`` (without ``variants``) with the chosen overlays applied."""
    out = {k: v for k, v in data.items() if k != "variants"}
    for v in variants:
        overlay = v.choices[selection[v.name]]
        for section, value in overlay.items():
            if section in MERGED_SECTIONS:
                base = out.get(section)
                merged = dict(base) if isinstance(base, dict) else {}
                for key, entry in (value or {}).items():
                    if entry is None:
                        merged.pop(key, None)
                    else:
                        merged[key] = entry
                out[section] = merged
            elif value is None:
                out.pop(section, None)
            else:
                out[section] = value
    return out


def all_selections(variants) -> list[dict]:
    """Every combination of choices (default first), at most ``MAX_CHECKED_COMBINATIONS``."""
    if not variants:
        return [{}]
    default = {v.name: v.default for v in variants}
    combos = [default]
    for values in itertools.product(*[list(v.choices) for v in variants]):
        sel = dict(zip((v.name for v in variants), values))
        if sel != default:
            combos.append(sel)
        if len(combos) >= MAX_CHECKED_COMBINATIONS:
            break
    return combos


def describe_selection(variants, selection: dict) -> str:
    return ", ".join(f"{v.name}={_fmt(selection[v.name])}" for v in variants)
