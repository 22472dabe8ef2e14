"""The one way records are saved and loaded: JSON derived from frozen dataclasses.

A record's JSON object has one key per field, named as the field, in the order of the fields;
each value is written by what it is (a record as its object, a tuple or list as a list, a mapping
as an object, a NumPy array as nested lists, a NumPy scalar as its number) and read back by the
field's annotation (:func:`from_json`: ``float``, ``int``, ``str``, ``bool``, ``X | None``,
``tuple[X, ...]``, ``Mapping[str, X]``, ``numpy.ndarray``, records, and a union of records
whose :func:`choose` says which one a document is). Nothing else spells a key: renaming a field
renames its key, which :data:`FORMAT` then counts.

A field's metadata (:func:`stored`) may leave its key out of the document: when its value is
None (``omit=NONE``), empty (``omit=EMPTY``), or when a function of the whole record says so
(``omit=lambda record: ...``); or not store it at all (``store=False``: a figure derived from
the others, or one that only the process that made it holds). A key the document lacks reads as
the field's default.

Every file of a results or study folder starts with its format version, key ``format``, before
its record's keys (:func:`write_file`, :func:`read_file`): a file without one is of format 0,
written before the version was, whose keys are those of format 1. A record whose older documents
differ from its fields converts them in a static method ``upgrade_json(doc) -> doc``, applied
before it is read; a file of a newer format than this code's is refused, with its path.

Why not cattrs or msgspec: the keys of ``parameters.json`` stay those it has (the main job's
file is byte-identical but for its version), keys are left out by rules that look at the whole
record, NumPy arrays are values, and Python's own ``json`` writes the numbers (msgspec writes a
NaN as null and an infinity otherwise than ``json`` reads back); both libraries would need a hook
per record for these, which is what this module is, without a dependency.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import types
import typing
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar, Union

import numpy as np

#: the format of the files written now; 0: the files of before the version was written
FORMAT = 1

T = TypeVar("T")


def NONE(value: Any) -> bool:
    """An ``omit`` rule: leave the key out when the value is None."""
    return value is None


def EMPTY(value: Any) -> bool:
    """An ``omit`` rule: leave the key out when the value is None or empty (``()``, ``{}``, ``""``, 0)."""
    return not value


@dataclasses.dataclass(frozen=True)
class _Rule:
    """How one field is stored: ``omit`` (of the value: :func:`NONE`, :func:`EMPTY`; or, with
    ``of_record``, of the whole record) and whether it is stored at all."""

    omit: Callable[[Any], bool] | None = None
    of_record: bool = False
    store: bool = True


def stored(omit: Callable[[Any], bool] | None = None, *, record: Callable[[Any], bool] | None = None,
           store: bool = True) -> dict[str, Any]:
    """Field metadata saying how the field is stored: ``omit``: a rule on its value (:func:`NONE`,
    :func:`EMPTY`) under which its key is left out; ``record``: a rule on the whole record instead
    (``lambda row: row.truth is None``); ``store=False``: never stored (read back as its default)."""
    if omit is not None and record is not None:
        raise ValueError("stored(): give omit or record, not both")
    return {"storage": _Rule(omit=record or omit, of_record=record is not None, store=store)}


def _rule(f: dataclasses.Field) -> _Rule:
    return f.metadata.get("storage") or _Rule()


# ----------------------------------------------------------------------------- writing
def to_json(value: Any) -> Any:
    """``value`` as JSON data (dicts, lists, numbers, text, None): a record as the object of its
    stored fields, keys equal to their names (see the module docstring)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        doc: dict[str, Any] = {}
        for f in dataclasses.fields(value):
            rule = _rule(f)
            item = getattr(value, f.name)
            if not rule.store or (rule.omit is not None and rule.omit(value if rule.of_record else item)):
                continue
            doc[f.name] = to_json(item)
        return doc
    if isinstance(value, Mapping):
        return {str(k): to_json(v) for k, v in value.items()}
    if isinstance(value, (tuple, list)):
        return [to_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"cannot store a {type(value).__name__} as JSON")


# ----------------------------------------------------------------------------- reading
@dataclasses.dataclass(frozen=True)
class Chooser:
    """For a union of records annotated ``Annotated[A | B, choose(f)]``: ``f(doc)`` is the record
    class the document ``doc`` is. ``f`` is left out of the repr, which autodoc shows in the
    union's annotations (a module's private chooser is no name to link to)."""

    pick: Callable[[Mapping[str, Any]], type] = dataclasses.field(repr=False)


def choose(pick: Callable[[Mapping[str, Any]], type]) -> Chooser:
    """The annotation marker of a union of records (:class:`Chooser`)."""
    return Chooser(pick)


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls, include_extras=True)


def from_json(tp: Any, doc: Any, where: str = "") -> Any:
    """The value of type ``tp`` that the JSON data ``doc`` holds (the inverse of :func:`to_json`);
    ``where``: the key path for errors (``ValueError`` naming it)."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if tp is Any:
        return doc
    if origin is typing.Annotated:
        chooser = next((a for a in args[1:] if isinstance(a, Chooser)), None)
        if chooser is not None and doc is not None:
            return from_json(chooser.pick(doc), doc, where)
        return from_json(args[0], doc, where)
    if origin in (Union, types.UnionType):
        return _from_union(tp, args, doc, where)
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        return _record(tp, doc, where)
    if origin in (tuple, list, dict, Mapping, typing.Mapping) or tp in (dict, Mapping):
        return _from_container(tp, origin, args, doc, where)
    return _from_scalar(tp, origin, args, doc, where)


def _from_union(tp: Any, args: tuple, doc: Any, where: str) -> Any:
    """``X | None`` (None, else an X), or a union of scalars (the first type the value is)."""
    if doc is None and type(None) in args:
        return None
    options = [a for a in args if a is not type(None)]
    if len(options) == 1:
        return from_json(options[0], doc, where)
    for option in options:
        if isinstance(option, type) and isinstance(doc, option) and not dataclasses.is_dataclass(option):
            return doc
    if float in options and isinstance(doc, (int, float)):
        return float(doc)
    raise ValueError(f"{where or 'document'}: {doc!r} is none of {tp}")


def _from_container(tp: Any, origin: Any, args: tuple, doc: Any, where: str) -> Any:
    """``tuple[X, ...]``, ``tuple[X, Y]``, ``list[X]``, ``Mapping[str, X]`` from a JSON list or object."""
    if origin is tuple:
        _expect(doc, list, tp, where)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(from_json(args[0], v, f"{where}[{i}]") for i, v in enumerate(doc))
        if len(args) != len(doc):
            raise ValueError(f"{where}: expected {len(args)} values, got {len(doc)}")
        return tuple(from_json(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, doc)))
    if origin is list:
        _expect(doc, list, tp, where)
        return [from_json(args[0], v, f"{where}[{i}]") for i, v in enumerate(doc)]
    _expect(doc, dict, tp, where)
    value_type = args[1] if args else Any
    return {k: from_json(value_type, v, f"{where}.{k}") for k, v in doc.items()}


def _from_scalar(tp: Any, origin: Any, args: tuple, doc: Any, where: str) -> Any:
    """A NumPy array (of floats), a ``Literal``, a number, a text or a truth value."""
    if tp is np.ndarray:
        return np.asarray(doc, dtype=float)
    if origin is typing.Literal:
        if doc not in args:
            raise ValueError(f"{where}: expected one of {args}, got {doc!r}")
        return doc
    if tp is float:
        if not isinstance(doc, (int, float)) or isinstance(doc, bool):
            raise ValueError(f"{where}: expected a number, got {doc!r}")
        return float(doc)
    if tp is int:
        if not isinstance(doc, int) or isinstance(doc, bool):
            raise ValueError(f"{where}: expected a whole number, got {doc!r}")
        return doc
    if tp in (str, bool):
        _expect(doc, tp, tp, where)
        return doc
    raise TypeError(f"{where}: cannot read a {tp} from JSON")


def _expect(doc: Any, kind: type, tp: Any, where: str) -> None:
    if not isinstance(doc, kind):
        raise ValueError(f"{where or 'document'}: expected {tp}, got {doc!r}")


def _record(cls: type[T], doc: Any, where: str) -> T:
    """The record ``cls`` of the JSON object ``doc``: each stored field from its key (its default
    where the key is absent), after the record's ``upgrade_json``; keys of no field are left out
    (a key an older format had and that the record no longer holds)."""
    _expect(doc, dict, cls, where)
    upgrade = getattr(cls, "upgrade_json", None)
    if upgrade is not None:
        doc = upgrade(dict(doc))
    hints = _hints(cls)    # type: ignore[arg-type]  # a record class: hashable
    values = {}
    for f in dataclasses.fields(cls):          # type: ignore[arg-type]
        if not f.init or not _rule(f).store:
            continue
        if f.name in doc:
            values[f.name] = from_json(hints[f.name], doc[f.name], f"{where}.{f.name}" if where else f.name)
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise ValueError(f"{where or cls.__name__}: missing key {f.name!r}")
    return cls(**values)


# ----------------------------------------------------------------------------- files
def file_document(record: Any) -> dict[str, Any]:
    """The JSON document of a file holding ``record``: its format version first, then the
    record's keys."""
    return {"format": FORMAT, **to_json(record)}


def write_file(path: str | Path, record: Any, indent: int = 2) -> None:
    """Write ``record`` to ``path`` as a JSON file (:func:`file_document`), through a temporary
    file renamed over it (a reader never sees half of it)."""
    write_atomically(path, json.dumps(file_document(record), indent=indent))


def read_file(cls: type[T], path: str | Path) -> T:
    """The record ``cls`` stored in ``path`` (:func:`write_file`): a file without ``format`` is of
    format 0; one of a newer format than :data:`FORMAT` is refused (``ValueError`` naming it), as is
    a document that is not ``cls``'s."""
    try:
        doc = json.loads(Path(path).read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not JSON: {exc}") from None
    return of_document(cls, doc, str(path))


def of_document(cls: type[T], doc: Any, where: str) -> T:
    """The record ``cls`` of a file's JSON document ``doc`` (see :func:`read_file`), ``where``: its path."""
    if not isinstance(doc, dict):
        raise ValueError(f"{where}: expected a JSON object")
    version = doc.get("format", 0)
    if not isinstance(version, int) or version > FORMAT:
        raise ValueError(f"{where}: format {version!r}, newer than this ident_hw's ({FORMAT}): update ident_hw")
    try:
        return _record(cls, {k: v for k, v in doc.items() if k != "format"}, "")
    except (ValueError, TypeError, KeyError) as exc:
        raise ValueError(f"{where}: {exc}") from exc


def write_atomically(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file renamed over it: a reader (or a run
    continued after Ctrl-C) never sees half of it."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)
