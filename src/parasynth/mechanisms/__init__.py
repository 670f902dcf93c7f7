"""Registry of the mechanism models: every built-in model is a packaged description.

A mechanism is named either by a registry name (``list_mechanisms()``) or by a description
file: a path to a ``.yaml``/``.yml`` file (or any existing file), or the bare file name of a
description shipped in this package (``"5pus_upu.yaml"``, the same class as ``"5pus_upu"``).
The paper models ``5pus_upu``, ``2rpu_2sps`` and ``4ups_1rps`` are defined by their packaged
descriptions (``mechanism_class("5pus_upu")`` is the class built from ``5pus_upu.yaml``);
their paper-specific extras are in :mod:`parasynth.mechanisms.extras`. A description's class
is built once per file (and per file change), and resolves each variant choice once. See
``docs/mechanisms.md``.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Callable

from ..model.mechanism import Mechanism

__all__ = ["list_mechanisms", "load_mechanism", "instantiate", "register", "mechanism_class", "resolve_mechanism_name",
           "packaged_descriptions", "described_class", "parse_description"]

_PACKAGE_DIR = Path(__file__).resolve().parent
_DESCRIBED: dict = {}
_RESOLVED: dict = {}  # {absolute path: its resolved path}
_FIELDS: dict = {}  # {Params class: its field names}

_REGISTRY: dict[str, tuple[Callable[[], type], str]] = {}


_UNLISTED: set = set()


def register(name: str, loader: Callable[[], type], summary: str, listed: bool = True) -> None:
    """Register a model class (loaded lazily by ``loader``) under ``name``; ``listed=False``
    keeps it out of :func:`list_mechanisms` (a study's generated mechanism, e.g. the structures
    of a study over structures)."""
    _REGISTRY[name] = (loader, summary)
    if not listed:
        _UNLISTED.add(name)


def _description_language():
    """The description package, imported on first use."""
    # lazy: the description language and PyYAML load with the first mechanism, not at `import parasynth`
    from . import description

    return description


def _described_class(path: Path) -> type:
    """The class of the description file ``path`` (cached while the file is unchanged)."""
    st = path.stat()
    s = str(path)
    full = _RESOLVED.get(s)  # an absolute path's resolved form, found once (a study builds per design)
    if full is None:
        full = str(path.resolve())
        if path.is_absolute():  # a relative one depends on the working directory
            _RESOLVED[s] = full
    key = (full, st.st_mtime_ns, st.st_size)
    if key not in _DESCRIBED:
        _DESCRIBED[key] = _description_language().load_description(path)
    return _DESCRIBED[key]


def described_class(data: dict, source: str | None = None) -> type:
    """The model class of a description given as a dict (the parsed YAML); see
    :func:`parasynth.mechanisms.description.description_class`. Loads the description
    language on first use."""
    return _description_language().description_class(data, source)


def parse_description(data: dict, source: str | None = None):
    """The parsed :class:`~parasynth.mechanisms.description.Description` of a description given
    as a dict, without a model class or a build at its defaults (its geometry is built with
    ``build_geometry(env)``). Loads the description language on first use."""
    return _description_language().Description(data, source)


def _packaged(filename: str) -> Callable[[], type]:
    return lambda: _described_class(_PACKAGE_DIR / filename)


register("4ups_1rps", _packaged("4ups_1rps.yaml"),
         "4-UPS/1-RPS parallel grinding robot (Wang et al., Symmetry 2022; described in 4ups_1rps.yaml)")
register("2rpu_2sps", _packaged("2rpu_2sps.yaml"),
         "2-RPU&2-SPS 2T2R manipulator (An et al., 2018; described in 2rpu_2sps.yaml)")
register("5pus_upu", _packaged("5pus_upu.yaml"),
         "5-PUS/UPU 3T2R mechanism (Wang, Lyu & Liu, Appl. Sci. 2021; described in 5pus_upu.yaml)")
register("gough_stewart_6ups", _packaged("gough_stewart_6ups.yaml"),
         "6-UPS Gough-Stewart platform, semi-regular hexagons (described in gough_stewart_6ups.yaml)")
register("hexapod_6pus", _packaged("hexapod_6pus.yaml"),
         "6-PUS hexapod on vertical sliders, paired joints (described in hexapod_6pus.yaml)")
register("hexapod_6rus", _packaged("hexapod_6rus.yaml"),
         "6-RUS rotary hexapod, mirrored crank pairs (described in hexapod_6rus.yaml)")
register("3rps", _packaged("3rps.yaml"), "3-RPS 1T2R platform with parasitic motion (described in 3rps.yaml)")
register("3prs", _packaged("3prs.yaml"), "3-PRS 1T2R platform on vertical sliders (described in 3prs.yaml)")


def list_mechanisms() -> list[str]:
    """Names accepted by :func:`load_mechanism`."""
    return sorted(k for k in _REGISTRY if k not in _UNLISTED)


def mechanism_summaries() -> dict[str, str]:
    return {k: _REGISTRY[k][1] for k in list_mechanisms()}


def packaged_descriptions() -> list[str]:
    """File names of the mechanism descriptions shipped with parasynth."""
    return sorted(p.name for p in _PACKAGE_DIR.glob("*.yaml"))


def _description_path(name, base_dir=None) -> Path | None:
    """The description file ``name`` refers to; None when it is not a file name or path."""
    if not isinstance(name, (str, os.PathLike)):
        return None
    s = os.fspath(name)
    if not s or (isinstance(name, str) and name in _REGISTRY):
        return None
    p = Path(s).expanduser()
    candidates = []
    if base_dir is not None and not p.is_absolute():
        candidates.append(Path(base_dir) / p)
    candidates.append(p)
    if p.name == s:
        candidates.append(_PACKAGE_DIR / s)
    for c in candidates:
        if c.is_file():
            return c
    if s.endswith((".yaml", ".yml")):
        where = ", ".join(str(c.parent) for c in candidates)
        raise ValueError(f"mechanism description {s!r} not found (looked in {where}); packaged descriptions: "
                         f"{', '.join(packaged_descriptions())}")
    return None


def resolve_mechanism_name(name, base_dir=None) -> str:
    """A registry name unchanged; a description file as an absolute path (relative paths are
    tried against ``base_dir`` first, then the working directory), except a packaged
    description named by its bare file name, which stays bare. Raises ``ValueError`` as
    :func:`mechanism_class` does."""
    path = _description_path(name, base_dir)
    if path is None:
        mechanism_class(name)  # raises for an unknown name
        return name
    if path.parent.resolve() == _PACKAGE_DIR and os.fspath(name) == path.name:
        return path.name
    return str(path.resolve())


def mechanism_class(name, base_dir=None) -> type:
    """The model class for a registry name or a description file (see the module docstring).
    Raises ``ValueError`` naming the valid mechanisms for an unknown name, and
    ``DescriptionError`` (a ``ValueError``) for a malformed description."""
    if isinstance(name, str) and name in _REGISTRY:
        return _REGISTRY[name][0]()
    path = _description_path(name, base_dir)
    if path is None:
        raise ValueError(f"unknown mechanism {name!r}; available: {', '.join(list_mechanisms())}, or a mechanism "
                         f"description file (.yaml; packaged: {', '.join(packaged_descriptions())})")
    return _described_class(path)


def load_mechanism(name: str, **params) -> Mechanism:
    """Build a model by name with parameters in SI units (m, rad); defaults are the papers'.

    ``name`` is a registry name or a mechanism description file (a path, or the file name of a
    packaged description such as ``"5pus_upu.yaml"``). Raises ``ValueError`` naming the valid
    mechanisms for an unknown name, and the valid parameters for an unknown parameter.
    """
    return instantiate(mechanism_class(name), name, **params)


def instantiate(cls: type, name: str, **params) -> Mechanism:
    """``load_mechanism(name, **params)`` for the model class ``cls`` of ``name`` found before
    (:func:`mechanism_class`): a study builds every design from the class it resolved once."""
    fields = _FIELDS.get(cls.Params)
    if fields is None:
        fields = _FIELDS[cls.Params] = frozenset(f.name for f in dataclasses.fields(cls.Params))
    if not fields.issuperset(params):
        unknown = sorted(set(params) - fields)
        raise ValueError(
            f"unknown parameter(s) {unknown} for mechanism {name!r}; valid: {', '.join(sorted(fields))}"
        )
    return cls(cls.Params(**params))
