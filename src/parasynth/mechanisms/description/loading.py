"""Turning a description (a mapping or a YAML file) into a mechanism class."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import yaml

from .errors import DescriptionError
from .schema import Description, _make_params_class
from .mechanism import DescribedMechanism

def description_class(data: dict, source: str | None = None) -> type:
    """A :class:`DescribedMechanism` subclass for a description given as a dict (the parsed
    YAML). ``source`` names it in error messages. Raises :class:`DescriptionError` (a
    ``ValueError``) naming the key path of the first problem; the description is also built
    once with its default parameters, so that geometric problems surface here."""
    where = source or (data.get("name") if isinstance(data, dict) else None) or "description"
    try:
        desc = Description(data, source)
    except DescriptionError as e:
        raise DescriptionError(f"{where}: {e}") from None
    safe = re.sub(r"\W", "_", desc.name)
    cls_name = f"Described_{safe}_{desc.digest}"
    try:
        params_cls = _make_params_class(desc, cls_name)
        ns = {
            "name": desc.name,
            "summary": desc.summary,
            "paper": desc.summary,
            "source": source,
            "description": desc,
            "Params": params_cls,
            "task_coordinates": desc.task.names,
            "angular_coordinates": frozenset(c for c, k in desc.task.coords if k == "angle"),
            "__doc__": f"{desc.summary}\n\n{desc.text}".strip(),
            "__module__": __package__,  # parasynth.mechanisms.description
        }
        cls = type(cls_name, (DescribedMechanism,), ns)
        cls()  # build once with the defaults: geometry, home pose, constraints
    except DescriptionError as e:
        msg = str(e)
        raise DescriptionError(msg if msg.startswith(f"{where}:") else f"{where}: {msg}") from None
    except ValueError as e:
        raise DescriptionError(f"{where}: {e}") from None
    return cls


def load_description(path) -> type:
    """Read a YAML description file and return its mechanism class (see :func:`description_class`)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise DescriptionError(f"{p}: cannot read the description ({e.strerror})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise DescriptionError(f"{p.name}: not valid YAML: {e}") from None
    return description_class(data, source=p.name)


def from_description(source, **params) -> DescribedMechanism:
    """Build a described mechanism from a dict or a YAML file path with parameters in SI."""
    cls = description_class(source) if isinstance(source, dict) else load_description(source)
    fields = {f.name for f in dataclasses.fields(cls.Params)}
    unknown = sorted(set(params) - fields)
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown} for mechanism {cls.name!r}; valid: {', '.join(sorted(fields))}")
    return cls(cls.Params(**params))
