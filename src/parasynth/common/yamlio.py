"""One safe YAML reader for study files and mechanism descriptions.

On top of ``yaml.SafeLoader`` (no Python objects are built) it refuses, with the file and line
named:

* duplicate keys in a mapping (YAML says keys are unique; PyYAML would keep the last);
* more than :data:`MAX_ALIASES` aliases (``*name``) in a document, or a document whose
  aliases expand to more than :data:`MAX_NODES` values: an "alias bomb" of a few lines
  expands to billions of entries in anything that walks the data;
* nesting deeper than :data:`MAX_DEPTH` (which would otherwise end in a RecursionError);
* files larger than :data:`MAX_BYTES`, files that are not UTF-8 text (binary files, other
  encodings), directories and unreadable paths.

Numbers in exponent form are numbers as YAML 1.2 writes them: PyYAML follows YAML 1.1, where
a float needs a dot and a signed exponent (``2.0e+6``), so ``2e6``, ``2.0e6``, ``1e-3`` and
``.5e3`` would be read as strings. This reader takes them as floats (:data:`EXPONENT_FLOAT`);
what YAML 1.1 already read as a number is unchanged.

Errors are :class:`YamlError` (a ``ValueError``) with a one-line message.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import yaml

__all__ = ["YamlError", "load_yaml", "read_text", "MAX_ALIASES", "MAX_NODES", "MAX_DEPTH", "MAX_BYTES",
           "EXPONENT_FLOAT"]

#: Aliases allowed in one document.
MAX_ALIASES = 100
#: Values (scalars, lists, mappings) of a document with its aliases expanded.
MAX_NODES = 200_000
#: Deepest nesting of mappings and lists.
MAX_DEPTH = 50
#: Largest file read (bytes).
MAX_BYTES = 4 * 1024 * 1024


#: Plain scalars read as floats beside YAML 1.1's: a decimal number with an exponent whose sign
#: and dot are optional (YAML 1.2's core schema, with 1.1's digit separators ``_``): ``2e6``,
#: ``2.0e6``, ``-3e-2``, ``.5e3``, ``1_000e2``.
EXPONENT_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")


class YamlError(ValueError):
    """A YAML file or text that cannot be read safely; the message names the source."""


def _where(mark) -> str:
    return f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "?"


class _Loader(yaml.SafeLoader):
    """SafeLoader with duplicate-key, alias-count and depth limits."""

    def __init__(self, stream, source: str):
        super().__init__(stream)
        self._source = source
        self._aliases = 0
        self._depth = 0

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                ev = self.peek_event()
                raise YamlError(f"{self._source}: more than {MAX_ALIASES} aliases (*name) at {_where(ev.start_mark)}; "
                                f"write the values out")
            return super().compose_node(parent, index)
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                ev = self.peek_event()
                raise YamlError(f"{self._source}: nested deeper than {MAX_DEPTH} levels at {_where(ev.start_mark)}")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def get_single_data(self):
        node = self.get_single_node()
        if node is None:
            return None
        if self._aliases:
            try:
                n = _expanded_size(node, {})
            except YamlError as e:
                raise YamlError(f"{self._source}: {e}") from None
            if n > MAX_NODES:
                raise YamlError(f"{self._source}: its aliases expand to {n} values; the maximum is {MAX_NODES}")
        return self.construct_document(node)

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen = {}
            for key_node, _ in node.value:  # the mapping's own keys; merged (<<) ones may be overridden
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                try:
                    key = self.construct_object(key_node, deep=True)
                    hash(key)
                except (TypeError, yaml.constructor.ConstructorError):
                    continue  # the base class reports unhashable keys
                if key in seen:
                    raise YamlError(f"{self._source}: duplicate key {key!r} at {_where(key_node.start_mark)} "
                                    f"(first at {_where(seen[key])}); each key may appear once")
                seen[key] = key_node.start_mark
        return super().construct_mapping(node, deep=deep)


# The loader's own copy of the implicit resolvers (PyYAML's add_implicit_resolver would append
# to lists SafeLoader shares), with the exponent floats after YAML 1.1's own.
_Loader.yaml_implicit_resolvers = {ch: list(rs) for ch, rs in yaml.SafeLoader.yaml_implicit_resolvers.items()}
for _ch in "-+0123456789.":
    _Loader.yaml_implicit_resolvers.setdefault(_ch, []).append(("tag:yaml.org,2002:float", EXPONENT_FLOAT))


def _expanded_size(node, memo) -> int:
    """Values in ``node`` with aliases expanded (shared nodes counted at each use)."""
    key = id(node)
    if key in memo:
        if memo[key] < 0:
            raise YamlError(f"an alias refers to a list or mapping that contains it, at {_where(node.start_mark)}")
        return memo[key]
    memo[key] = -1  # in progress: meeting it again is a cycle
    if isinstance(node, yaml.SequenceNode):
        n = 1 + sum(_expanded_size(c, memo) for c in node.value)
    elif isinstance(node, yaml.MappingNode):
        n = 1 + sum(_expanded_size(k, memo) + _expanded_size(v, memo) for k, v in node.value)
    else:
        n = 1
    n = min(n, 10 * MAX_NODES)
    memo[key] = n
    return n


def read_text(path, what: str = "file") -> str:
    """The UTF-8 text of ``path`` (a BOM is allowed), with one-line errors for a missing path,
    a directory, an unreadable, binary, oversized or non-UTF-8 file."""
    p = Path(path)
    if not p.exists():
        raise YamlError(f"{what} {str(p)!r} does not exist")
    if p.is_dir():
        raise YamlError(f"{what} {str(p)!r} is a directory, not a file")
    try:
        size = p.stat().st_size
        if size > MAX_BYTES:
            raise YamlError(f"{what} {str(p)!r} is {size} bytes; the maximum is {MAX_BYTES}")
        data = p.read_bytes()
    except OSError as e:
        raise YamlError(f"{what} {str(p)!r} cannot be read: {e.strerror or e}") from None
    if len(data) > MAX_BYTES:  # a file that grew, or a special file
        raise YamlError(f"{what} {str(p)!r} is larger than {MAX_BYTES} bytes")
    if b"\x00" in data:
        raise YamlError(f"{what} {str(p)!r} is a binary file, not YAML text")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise YamlError(f"{what} {str(p)!r} is not UTF-8 text (byte {e.start}: {data[e.start:e.start + 1]!r}); "
                        f"save it as UTF-8") from None


def load_yaml(source, *, is_text: bool = False, name: str | None = None, what: str = "file"):
    """Parse one YAML document from a path (or from text with ``is_text=True``) safely.

    ``name`` is the source named in messages (default the path, or "text")."""
    if is_text:
        text = source
        label = name or "text"
        if isinstance(text, bytes):
            try:
                text = text.decode("utf-8-sig")
            except UnicodeDecodeError:
                raise YamlError(f"{label}: not UTF-8 text") from None
        if not isinstance(text, str):
            raise YamlError(f"{label}: expected YAML text, got {type(text).__name__}")
        if len(text) > MAX_BYTES:
            raise YamlError(f"{label}: {len(text)} characters; the maximum is {MAX_BYTES}")
        if "\x00" in text:
            raise YamlError(f"{label}: contains NUL characters; not YAML text")
    else:
        label = name or os.fspath(source)
        text = read_text(source, what)
    loader = _Loader(text, label)
    try:
        return loader.get_single_data()
    except YamlError:
        raise
    except yaml.YAMLError as e:
        msg = " ".join(str(e).replace('in "<unicode string>", ', "").split())
        raise YamlError(f"{label}: not valid YAML: {msg}") from None
    except RecursionError:  # a construct deeper than the composer check (should not happen)
        raise YamlError(f"{label}: nested too deeply") from None
    finally:
        loader.dispose()
