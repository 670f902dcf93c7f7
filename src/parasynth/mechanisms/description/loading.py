"""Turning a description (a mapping or a YAML file) into a mechanism class."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

from ...common.yamlio import YamlError, load_yaml
from .errors import DescriptionError
from .schema import Description, _make_params_class
from .mechanism import DescribedMechanism
from .variants import all_selections, describe_selection, selection_key

def _taken(name: str) -> bool:
    """Names an output cannot take: attributes of every described mechanism."""
    return hasattr(DescribedMechanism, name) or name in ("params", "home", "legs", "actuators", "length_scale",
                                                          "description", "variants", "source", "summary", "paper")


def _output_method(name: str, doc: str):
    def method(self, X):
        spec = self.description.outputs.get(name)
        if spec is None:
            raise ValueError(f"{self.name}: the output {name!r} is not defined for "
                             f"{describe_selection(self.description.variants, self.description.selection)}")
        return self._output(spec, X)

    method.__name__ = method.__qualname__ = name
    method.__doc__ = (doc or f"The output {name!r} of the description") + (
        " at poses X (N, n_task) or (n_task,), SI.")
    return method


def description_class(data: dict, source: str | None = None) -> type:
    """A :class:`DescribedMechanism` subclass for a description given as a dict (the parsed
    YAML). ``source`` names it in error messages. Raises :class:`DescriptionError` (a
    ``ValueError``) naming the key path of the first problem; the description is also built
    once with its default parameters for every combination of its variants (up to
    ``variants.MAX_CHECKED_COMBINATIONS``), so that geometric problems surface here.

    The class caches the description resolved for each variant selection: instances of the
    same selection share one parsed description, so building a mechanism per design is cheap."""
    where = source or (data.get("name") if isinstance(data, dict) else None) or "description"
    try:
        desc = Description(data, source, outputs_taken=_taken)
    except DescriptionError as e:
        raise DescriptionError(f"{where}: {e}") from None
    variants = desc.variants
    cache = {selection_key(variants, desc.selection): desc}

    def resolve(selection: dict) -> Description:
        full = {**desc.selection, **selection}
        key = selection_key(variants, full)
        d = cache.get(key)
        if d is None:
            try:
                d = Description(data, source, full, outputs_taken=_taken)
            except DescriptionError as e:
                raise DescriptionError(f"{where}: variants ({describe_selection(variants, full)}): {e}") from None
            cache[key] = d
        return d

    variants_by_name = {v.name: v for v in variants}
    combos = all_selections(variants)
    resolved = [resolve(sel) for sel in combos]
    safe = re.sub(r"\W", "_", desc.name)
    cls_name = f"Described_{safe}_{desc.digest}"
    try:
        params_cls = _make_params_class(desc, cls_name, resolve)
        ns = {
            "name": desc.name,
            "summary": desc.summary,
            "paper": desc.summary,
            "source": source,
            "description": desc,
            "variants": variants_by_name,
            "Params": params_cls,
            "task_coordinates": desc.task.names,
            "angular_coordinates": frozenset(c for c, k in desc.task.coords if k == "angle"),
            "_description_for": classmethod(lambda cls, selection: resolve(selection)),
            "__doc__": f"{desc.summary}\n\n{desc.text}".strip(),
            "__module__": __package__,  # parasynth.mechanisms.description
        }
        docs = {}
        for d in resolved:
            for name, spec in d.outputs.items():
                docs.setdefault(name, spec.doc)
        for name, doc in docs.items():
            ns[name] = _output_method(name, doc)
        cls = type(cls_name, (DescribedMechanism,), ns)
        for sel in combos:  # build once with the defaults: geometry, home pose, constraints
            try:
                cls(params_cls(**sel))
            except DescriptionError as e:
                if not variants or sel == desc.selection:
                    raise
                msg = str(e)
                raise DescriptionError(f"variants ({describe_selection(variants, sel)}): {msg}") from None
    except DescriptionError as e:
        msg = str(e)
        raise DescriptionError(msg if msg.startswith(f"{where}:") else f"{where}: {msg}") from None
    except ValueError as e:
        raise DescriptionError(f"{where}: {e}") from None
    return cls


def load_description(path) -> type:
    """Read a YAML description file and return its mechanism class (see :func:`description_class`).

    The file is read with the project's safe YAML reader (:mod:`parasynth.common.yamlio`): duplicate
    keys, alias bombs, excessive nesting, binary and non-UTF-8 files are refused with a
    one-line :class:`DescriptionError` naming the file."""
    p = Path(path)
    try:
        data = load_yaml(p, name=p.name, what="mechanism description")
    except YamlError as e:
        raise DescriptionError(str(e)) from None
    return description_class(data, source=p.name)


def from_description(source, **params) -> DescribedMechanism:
    """Build a described mechanism from a dict or a YAML file path with parameters in SI."""
    cls = description_class(source) if isinstance(source, dict) else load_description(source)
    fields = {f.name for f in dataclasses.fields(cls.Params)}
    unknown = sorted(set(params) - fields)
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown} for mechanism {cls.name!r}; valid: {', '.join(sorted(fields))}")
    return cls(cls.Params(**params))
