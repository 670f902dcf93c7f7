"""Registry of the built-in mechanism models."""

from __future__ import annotations

import dataclasses
from typing import Callable

from ..mechanism import Mechanism

__all__ = ["list_mechanisms", "load_mechanism", "register"]

_REGISTRY: dict[str, tuple[Callable[[], type], str]] = {}


def register(name: str, loader: Callable[[], type], summary: str) -> None:
    """Register a model class (loaded lazily by ``loader``) under ``name``."""
    _REGISTRY[name] = (loader, summary)


def _rpu_sps():
    from .rpu_sps_2t2r import RPU2SPS2

    return RPU2SPS2


def _pus_upu():
    from .pus_upu_5dof import PUSUPU5

    return PUSUPU5


def _ups_rps():
    from .ups_rps_grinding import UPSRPSGrinding

    return UPSRPSGrinding


register("4ups_1rps", _ups_rps, "4-UPS/1-RPS parallel grinding robot (Wang et al., Symmetry 2022)")
register("2rpu_2sps", _rpu_sps, "2-RPU&2-SPS 2T2R manipulator (An et al., 2018)")
register("5pus_upu", _pus_upu, "5-PUS/UPU 3T2R mechanism (Wang, Lyu & Liu, Appl. Sci. 2021)")


def list_mechanisms() -> list[str]:
    """Names accepted by :func:`load_mechanism`."""
    return sorted(_REGISTRY)


def mechanism_summaries() -> dict[str, str]:
    return {k: _REGISTRY[k][1] for k in list_mechanisms()}


def load_mechanism(name: str, **params) -> Mechanism:
    """Build a model by name with parameters in SI units (m, rad); defaults are the papers'.

    Raises ``ValueError`` naming the valid mechanisms for an unknown name, and the valid
    parameters for an unknown parameter.
    """
    if not isinstance(name, str) or name not in _REGISTRY:
        raise ValueError(f"unknown mechanism {name!r}; available: {', '.join(list_mechanisms())}")
    cls = _REGISTRY[name][0]()
    fields = {f.name for f in dataclasses.fields(cls.Params)}
    unknown = sorted(set(params) - fields)
    if unknown:
        raise ValueError(
            f"unknown parameter(s) {unknown} for mechanism {name!r}; valid: {', '.join(sorted(fields))}"
        )
    return cls(cls.Params(**params))
