"""Declared, typed settings of a measure, and the one validator that checks them.

Every registered measure (:mod:`parasynth.objectives`) declares its settings as
:class:`Setting` values: the kind (a type, or a quantity kind whose unit a study file gives),
the allowed range or choices, the default, and where the setting goes::

    Setting("float", default=0.0, low=0.0, high=1.0)          # a quantile
    Setting("str", default="first_order", choices=("first_order", "monte_carlo"))
    Setting("force")                                           # '50 N' in a study file
    Setting("int", low=1, high=MAX_SAMPLES, sample_field="n")  # overrides the workspace sample's n

A setting with ``sample_field`` is not passed to the measure's function: in a study it replaces
that field of the measure's :class:`~parasynth.measures.workspace.WorkspaceSample` (``samples: 1024``
for one measure, or an accuracy measure's ``sampling``, its sampling method, beside its own
``method``, the error model). A setting with ``evaluation_key`` takes the study's
``evaluation.<key>`` when the measure's settings leave it out (the pose ``constraints`` and the
``engine`` shared by the workspace measures).

:func:`check_settings` checks a measure's settings against these declarations, in the spirit
of scikit-learn's parameter constraints: one pass, one :class:`SettingError` naming the field
path and what is allowed (``objectives[1].settings.method: 'foo' is not one of first_order,
monte_carlo``). With ``resolve`` (the study loader) quantities with units are converted to SI
and the model-dependent kinds (``ranges``, ``pose``, ``pose_constraints``) are resolved by the
caller's functions; without it (a call from Python, SI values) the values are checked and
returned unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping

from ..common.units import UNIT_KINDS, QuantityError, parse_quantity
from ..model.task import Task
from ..common.validation import check_count, check_number

__all__ = ["Setting", "SettingError", "check_settings", "KINDS", "as_setting"]

#: Kinds of settings that are not quantities: Python types, and the model-dependent kinds a
#: study resolves against the mechanism (a task box, pose coordinates, pose constraint names).
TYPE_KINDS = ("int", "float", "str", "bool", "list", "dict", "ranges", "pose", "pose_constraints", "task")
#: Every kind a setting may have: the type kinds and the quantity kinds of :mod:`parasynth.common.units`.
KINDS = TYPE_KINDS + tuple(k for k in UNIT_KINDS if k != "dimensionless")
#: Kinds of the older ``{name: kind}`` declarations and the kind they stand for.
_LEGACY_KINDS = {"choice": "str", "dimensionless": "float"}


class SettingError(ValueError):
    """A measure setting that its declaration does not allow; the message starts with the path."""


@dataclass(frozen=True)
class Setting:
    """One declared setting of a measure.

    ``kind``: one of :data:`KINDS`; ``default``: the value the measure uses when the setting is
    left out (documentation: the function's own default applies); ``low``/``high``: allowed
    closed range of a number (each element of a quantity list); ``choices``: allowed values of a
    string; ``sample_field``: the :class:`~parasynth.measures.workspace.WorkspaceSample` field the setting
    overrides (then not passed to the function); ``evaluation_key``: the study's evaluation key
    that gives the value when the setting is left out; ``doc``: one line."""

    kind: str
    default: Any = None
    low: float | None = None
    high: float | None = None
    choices: tuple | None = None
    sample_field: str | None = None
    evaluation_key: str | None = None
    doc: str = ""

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"setting kind {self.kind!r} is unknown; allowed: {', '.join(KINDS)}")
        if self.choices is not None:
            object.__setattr__(self, "choices", tuple(self.choices))

    def allowed(self) -> str:
        """What the setting allows, in words: 'float in [0.0, 1.0]', 'str, one of x, y, z'."""
        if self.choices is not None:
            return f"{self.kind}, one of {', '.join(map(str, self.choices))}"
        if self.low is not None or self.high is not None:
            lo = "-inf" if self.low is None else self.low
            hi = "inf" if self.high is None else self.high
            return f"{self.kind} in [{lo}, {hi}]"
        return self.kind

    def check(self, value, where: str, resolve: Mapping[str, Callable] | None = None):
        """``value`` checked (and with ``resolve``, converted to SI); :class:`SettingError`
        naming ``where`` otherwise."""
        k = self.kind
        if value is None and resolve is None and self.default is None:
            return None  # from Python: None leaves the measure's own default
        if k == "int":
            v = _wrap(check_count, where, value, 1 if self.low is None else self.low, self.high)
            return v if resolve is not None else value
        if k == "float":
            v = _wrap(check_number, where, value, None, self.low, self.high)
            return v if resolve is not None else value
        if k == "str":
            if not isinstance(value, str):
                raise SettingError(f"{where}: must be a string" + self._one_of() + f", got {value!r}")
            if self.choices is not None and value not in self.choices:
                what = f" ({self.doc})" if self.doc else ""
                raise SettingError(f"{where}: {value!r} is not one of {', '.join(map(str, self.choices))}{what}")
            return value
        if k == "bool":
            if not isinstance(value, bool):
                raise SettingError(f"{where}: must be true or false, got {value!r}")
            return value
        if k == "list":
            if isinstance(value, (str, bytes, Mapping)) or not hasattr(value, "__len__"):
                raise SettingError(f"{where}: must be a list, got {value!r}")
            return value
        if k == "dict":
            if not isinstance(value, Mapping):
                raise SettingError(f"{where}: must be a mapping, got {value!r}")
            return value
        if k == "task":  # a parasynth.Task (a study resolves its task: section into one)
            if resolve is not None and k in resolve:
                return resolve[k](value, where)
            if not isinstance(value, Task):
                raise SettingError(f"{where}: must be a parasynth.Task, got {type(value).__name__}")
            return value
        if k in ("ranges", "pose", "pose_constraints"):
            return resolve[k](value, where) if resolve is not None and k in resolve else value
        # a quantity kind: a value with its unit in a study file (nested lists allowed), SI from Python
        if resolve is None:
            return value
        out = _quantity(value, k, where)
        self._check_range(out, where)
        return out

    def _one_of(self) -> str:
        return f" (one of {', '.join(map(str, self.choices))})" if self.choices else ""

    def _check_range(self, v, where):
        if isinstance(v, tuple):
            for j, x in enumerate(v):
                self._check_range(x, f"{where}[{j}]")
            return
        if (self.low is not None and v < self.low) or (self.high is not None and v > self.high):
            raise SettingError(f"{where}: {v!r} (SI) is outside the allowed range "
                               f"[{'-inf' if self.low is None else self.low}, "
                               f"{'inf' if self.high is None else self.high}]")


def as_setting(spec) -> Setting:
    """A :class:`Setting` from a declaration: a Setting, or a kind name (the older
    ``{name: kind}`` form, e.g. ``"bool"``, ``"length"``)."""
    if isinstance(spec, Setting):
        return spec
    if isinstance(spec, str):
        return Setting(_LEGACY_KINDS.get(spec, spec))
    raise ValueError(f"a measure setting is declared by a Setting or a kind name, got {spec!r}")


def check_settings(measure: str, specs: Mapping[str, Setting], values: Mapping, path: str = "settings",
                   resolve: Mapping[str, Callable] | None = None) -> dict:
    """``values`` (a measure's settings) checked against the declarations ``specs`` of measure
    ``measure``; converted to SI with ``resolve`` (see the module documentation). Raises
    :class:`SettingError` naming ``<path>.<setting>`` and what is allowed."""
    if not isinstance(values, Mapping):
        raise SettingError(f"{path}: give a mapping {{setting: value}}, got {values!r}")
    out = {}
    for k, v in values.items():
        spec = specs.get(k)
        if spec is None:
            raise SettingError(f"{path}.{k}: unknown setting of {measure!r}; allowed: {', '.join(specs) or '(none)'}")
        out[k] = spec.check(v, f"{path}.{k}", resolve)
    return out


def _wrap(check, where, value, *args):
    try:
        return check(where, value, *args)
    except (ValueError, TypeError) as e:
        msg = str(e)
        raise SettingError(f"{where}:{msg[len(where):]}" if msg.startswith(where + " ") else msg) from None


def _quantity(value, kind, where):
    if isinstance(value, (list, tuple)):
        return tuple(_quantity(x, kind, f"{where}[{j}]") for j, x in enumerate(value))
    try:
        return parse_quantity(value, kind, field=where)
    except QuantityError as e:
        raise SettingError(str(e)) from None
