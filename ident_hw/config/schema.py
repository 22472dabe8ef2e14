"""A small generic schema layer: YAML node trees → frozen dataclasses, with strict validation.

A config section is a frozen dataclass. Its annotated fields say the expected types; a field's
``metadata`` (built with :func:`spec`) may add a validator, a unit note and a degree alias::

    @dataclass(frozen=True)
    class Geometry:
        l1: float = field(metadata=spec(positive, unit="m"))
        gamma: tuple[float, float, float] = field(metadata=spec(angle=True))

A field marked ``angle=True`` (value in rad) may instead be written as ``<name>_deg`` in degrees;
one marked ``key=False`` is no key of the file: the loader gives it (``build(..., given=...)``).
Cross-field rules are not the sections': :func:`build` takes them as ``checks``, one function per
section class, ``check(section, written)`` (``written``: the keys the file gives, ``_deg`` ones by
their field's name), raising :class:`FieldError` naming the offending key (path relative to the
section); each runs as soon as its section is built, so its error points at the section's node.

Every error is one :class:`ConfigError` naming the file, the line, the key path
(``robot.geometry.l1``) and what was expected. Unknown keys are errors (with a "did you mean");
a key an earlier version had is one too, saying what became of it (the section class's
``RETIRED_KEYS``: key -> message).
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import os
import re
import types
import typing
from pathlib import Path
from typing import Any, Callable, Literal, Mapping, Union

import yaml

import drivers.errors

_TAG_NULL = "tag:yaml.org,2002:null"
_TAG_BOOL = "tag:yaml.org,2002:bool"
_TAG_INT = "tag:yaml.org,2002:int"
_TAG_FLOAT = "tag:yaml.org,2002:float"
_TAG_STR = "tag:yaml.org,2002:str"


class ConfigError(drivers.errors.ConfigError):
    """A config file is invalid: names the file, line, key path and what was expected.

    A :class:`drivers.errors.ConfigError` (the drive layer's, raised for an invalid axis setting),
    so that one ``except`` catches a bad value wherever it is found."""

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 key: str | None = None) -> None:
        self.file, self.line, self.key, self.reason = file, line, key, message
        where = file or "<config>"
        if line is not None:
            where += f", line {line}"
        super().__init__(f"{where}: {key}: {message}" if key else f"{where}: {message}")


class FieldError(ValueError):
    """Raised by a section's check (or a validator): ``key`` is a dotted path inside the section."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(message)
        self.key, self.message = key, message


def spec(check: Callable[[Any], None] | None = None, *, unit: str = "", angle: bool = False,
         doc: str = "", path: bool = False, key: bool = True) -> dict:
    """Field metadata: an optional validator ``check(value)`` raising ValueError("expected ..."),
    the SI unit (for messages and docs), whether ``<name>_deg`` is accepted (value in rad),
    whether the value is a file path relative to the config file that writes it (``path``: read
    as that file's folder joined with it, so a base config's path holds in the configs extending it;
    ``${NAME}`` in it is the environment variable NAME, :func:`expand_variables`),
    and whether the field is a key of the file at all (``key=False``: set by the loader)."""
    return {"check": check, "unit": unit, "angle": angle, "doc": doc, "path": path, "key": key}


#: a section's cross-field check: ``(section, keys written in the file) -> None``, raising FieldError
Check = Callable[[Any, frozenset], None]


# ----------------------------------------------------------------------------- validators
def positive(value) -> None:
    for v in _flat(value):
        if not v > 0:
            raise ValueError(f"expected a positive value, got {v}")


def non_negative(value) -> None:
    for v in _flat(value):
        if not v >= 0:
            raise ValueError(f"expected a value >= 0, got {v}")


def in_range(lo: float, hi: float) -> Callable[[Any], None]:
    def check(value) -> None:
        for v in _flat(value):
            if not lo <= v <= hi:
                raise ValueError(f"expected a value in [{lo}, {hi}], got {v}")
    return check


def ordered_pair(value) -> None:
    """A ``(min, max)`` pair with ``min < max``."""
    if not value[0] < value[1]:
        raise ValueError(f"expected [min, max] with min < max, got {list(value)}")


def _flat(value):
    return value if isinstance(value, (tuple, list)) else (value,)


# ----------------------------------------------------------------------------- building
def build(cls: type, node: yaml.Node, checks: Mapping[type, Check] | None = None,
          given: Mapping[str, Any] | None = None):
    """Build dataclass ``cls`` from a composed YAML node, validating every key and running the
    cross-field ``checks`` of each section built; ``given``: the values of ``cls``'s fields that
    are no keys of the file (``spec(key=False)``)."""
    return _Builder(checks or {}).dataclass(cls, node, "", given or {})


def location(node: yaml.Node) -> tuple[str, int]:
    """(file name, 1-based line) of a composed node."""
    return node.start_mark.name, node.start_mark.line + 1


def error_at(node: yaml.Node, key: str, message: str) -> ConfigError:
    file, line = location(node)
    return ConfigError(message, file=file, line=line, key=key)


def mapping_items(node: yaml.Node, path: str) -> dict[str, tuple[yaml.Node, yaml.Node]]:
    """Keys of a mapping node → (key node, value node); duplicates and non-string keys are errors."""
    if not isinstance(node, yaml.MappingNode):
        raise error_at(node, path or "<top>", f"expected a mapping (key: value), got {_describe(node)}")
    items: dict[str, tuple[yaml.Node, yaml.Node]] = {}
    for key_node, value_node in node.value:
        if not (isinstance(key_node, yaml.ScalarNode) and key_node.tag == _TAG_STR):
            raise error_at(key_node, path or "<top>", f"expected a text key, got {_describe(key_node)}")
        if key_node.value in items:
            raise error_at(key_node, _join(path, key_node.value), "duplicate key")
        items[key_node.value] = (key_node, value_node)
    return items


def _join(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def _describe(node: yaml.Node) -> str:
    if isinstance(node, yaml.MappingNode):
        return "a mapping"
    if isinstance(node, yaml.SequenceNode):
        return f"a list of {len(node.value)}"
    if node.tag == _TAG_NULL:
        return "nothing (null)"
    return repr(node.value)


def _type_name(tp) -> str:
    origin = typing.get_origin(tp)
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(tp))
    if origin in (Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(tp))
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_type_name(args[0])}"
        return f"a list of {len(args)} {_type_name(args[0])}" if len(set(args)) == 1 else "a list"
    if origin is dict:
        return f"a mapping of {_type_name(typing.get_args(tp)[1])}"
    if dataclasses.is_dataclass(tp):
        return "a mapping"
    if tp is type(None):
        return "null"
    return {float: "a number", int: "an integer", str: "a text", bool: "true/false"}.get(tp, str(tp))


class _Builder:
    def __init__(self, checks: Mapping[type, Check]) -> None:
        self.checks = checks

    def dataclass(self, cls, node, path, preset=None):
        items = mapping_items(node, path)
        hints = typing.get_type_hints(cls)
        inits = [f for f in dataclasses.fields(cls) if f.init and (f.metadata or {}).get("key", True)]
        known = {f.name for f in inits} | {f"{f.name}_deg" for f in inits if (f.metadata or {}).get("angle")}
        unknown = [k for k in items if k not in known]
        if unknown:
            k = unknown[0]
            retired = getattr(cls, "RETIRED_KEYS", {})
            if k in retired:                    # a key of an earlier version: say what became of it
                raise error_at(items[k][0], _join(path, k), f"no longer a key: {retired[k]}")
            close = difflib.get_close_matches(k, sorted(known), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else f"; expected one of {sorted(known)}"
            raise error_at(items[k][0], _join(path, k), f"unknown key{hint}")
        kwargs = dict(preset or {})
        for f in inits:
            meta = f.metadata or {}
            key = f.name
            deg_key = f"{key}_deg" if meta.get("angle") else None
            given = [k for k in (key, deg_key) if k and k in items]
            if len(given) == 2:
                raise error_at(items[deg_key][0], _join(path, deg_key),
                               f"give either {key!r} (rad) or {deg_key!r} (deg), not both")
            if not given:
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                    alt = f" (or {deg_key!r} in degrees)" if deg_key else ""
                    unit = f" in {meta['unit']}" if meta.get("unit") else ""
                    raise error_at(node, _join(path, key),
                                   f"missing key: expected {_type_name(hints[key])}{unit}{alt}")
                continue
            used = given[0]
            value_node = items[used][1]
            value = self.value(hints[key], value_node, _join(path, used))
            if used == deg_key:
                value = _deg_to_rad(value)
            if meta.get("path") and value is not None:
                value = os.path.normpath(Path(location(value_node)[0]).parent / expand_variables(value, value_node,
                                                                                                  _join(path, used)))
            check = meta.get("check")
            if check is not None and value is not None:
                try:
                    check(value)
                except ValueError as exc:
                    unit = f" ({meta['unit']})" if meta.get("unit") else ""
                    raise error_at(value_node, _join(path, used), f"{exc}{unit}") from None
            kwargs[key] = value
        written = frozenset(f.name for f in inits if f.name in items or f"{f.name}_deg" in items)
        try:
            obj = cls(**kwargs)
            check = self.checks.get(cls)
            if check is not None:
                check(obj, written)
        except FieldError as exc:
            target = _find(node, exc.key)
            raise error_at(target, _join(path, exc.key), exc.message) from None
        except (ValueError, TypeError) as exc:
            raise error_at(node, path or "<top>", str(exc)) from None
        return obj

    def value(self, tp, node, path):
        origin = typing.get_origin(tp)
        if origin in (Union, types.UnionType):
            args = typing.get_args(tp)
            if type(None) in args and _is_null(node):
                return None
            inner = [a for a in args if a is not type(None)]
            if len(inner) == 1:
                return self.value(inner[0], node, path)
            for a in inner:  # first type that fits
                try:
                    return self.value(a, node, path)
                except ConfigError:
                    continue
            raise error_at(node, path, f"expected {_type_name(tp)}, got {_describe(node)}")
        if origin is Literal:
            choices = typing.get_args(tp)
            value = self.scalar(node, path, type(choices[0]), tp)
            if value not in choices:
                close = difflib.get_close_matches(str(value), [str(c) for c in choices], n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise error_at(node, path, f"expected {_type_name(tp)}, got {value!r}{hint}")
            return value
        if origin is tuple:
            args = typing.get_args(tp)
            if not isinstance(node, yaml.SequenceNode):
                raise error_at(node, path, f"expected {_type_name(tp)}, got {_describe(node)}")
            if len(args) == 2 and args[1] is Ellipsis:
                args = (args[0],) * len(node.value)
            elif len(node.value) != len(args):
                raise error_at(node, path, f"expected {_type_name(tp)}, got {_describe(node)}")
            return tuple(self.value(a, n, _join(path, i)) for i, (a, n) in enumerate(zip(args, node.value)))
        if origin is dict:
            key_tp, value_tp = typing.get_args(tp)
            items = mapping_items(node, path)
            return {k: self.value(value_tp, v, _join(path, k)) for k, (_, v) in items.items()}
        if dataclasses.is_dataclass(tp):
            return self.dataclass(tp, node, path)
        if tp in (float, int, str, bool):
            return self.scalar(node, path, tp, tp)
        raise TypeError(f"schema: unsupported field type {tp!r} at {path}")

    def scalar(self, node, path, tp, declared):
        if not isinstance(node, yaml.ScalarNode) or node.tag == _TAG_NULL:
            raise error_at(node, path, f"expected {_type_name(declared)}, got {_describe(node)}")
        tag, text = node.tag, node.value
        if tp is bool and tag == _TAG_BOOL:
            return text.lower() in ("true", "yes", "on", "y")
        if tp is int and tag == _TAG_INT:
            return int(yaml.SafeLoader("").construct_yaml_int(node))
        if tp is float and tag in (_TAG_INT, _TAG_FLOAT):
            return float(yaml.SafeLoader("").construct_yaml_float(node))
        if tp is float and tag == _TAG_STR and node.style is None:
            # PyYAML (YAML 1.1) reads an unquoted ``1e-3`` as text: accept it as the number it is.
            try:
                value = float(text)
            except ValueError:
                pass
            else:
                if math.isfinite(value):
                    return value
        if tp is str and tag == _TAG_STR:
            return text
        raise error_at(node, path, f"expected {_type_name(declared)}, got {_describe(node)}")


#: ``${NAME}`` in a path: the value of the environment variable NAME
_VARIABLE = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")


def expand_variables(text: str, node: yaml.Node, path: str) -> str:
    """``text`` with every ``${NAME}`` replaced by the environment variable ``NAME`` (a dataset's
    folder, which differs from machine to machine); an unset one is a :class:`ConfigError` naming
    the key and the variable."""
    def value(match: re.Match) -> str:
        name = match.group(1)
        if name not in os.environ:
            raise error_at(node, path, f"{text}: the environment variable {name} is not set (set it to the "
                                       "folder this path starts from)")
        return os.environ[name]
    return _VARIABLE.sub(value, text)


def _is_null(node) -> bool:
    return isinstance(node, yaml.ScalarNode) and node.tag == _TAG_NULL


def _deg_to_rad(value):
    if isinstance(value, tuple):
        return tuple(math.radians(v) for v in value)
    return math.radians(value)


def _find(node: yaml.Node, dotted: str) -> yaml.Node:
    """The node at a dotted path below ``node`` (``a.b[2].c``), or the deepest one that exists."""
    for part in dotted.replace("[", ".").replace("]", "").split("."):
        if not part:
            continue
        if isinstance(node, yaml.MappingNode):
            match = [v for k, v in node.value if k.value == part or k.value == f"{part}_deg"]
            if not match:
                return node
            node = match[0]
        elif isinstance(node, yaml.SequenceNode) and part.isdigit() and int(part) < len(node.value):
            node = node.value[int(part)]
        else:
            return node
    return node
