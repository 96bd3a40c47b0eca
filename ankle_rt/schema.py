"""The declarative schema machinery configs are checked with: fields, sections, lists, and
:func:`validate`, which returns a checked copy or raises :class:`ConfigError` naming the key.

A number must be finite (YAML's ``.nan`` and ``.inf`` are numbers to Python, and a NaN compares false
against every bound, so a bound alone would let it through) and within the field's bounds. The
configuration schema (:mod:`ankle_rt.config_schema`) gives every numeric key both bounds; a test walks it.
This module imports nothing from the project, so the schema, the profiles and the loader can all use it
without an import circle.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Mapping

KeyPath = tuple[str, ...]


class ConfigError(ValueError):
    """A configuration value is missing, unknown, of the wrong type or out of range."""

    def __init__(self, message: str, source: str | None = None, key: str | None = None):
        self.message = message   # without the "source: key: " prefix, for callers that re-key the error
        self.source = source
        self.key = key
        where = ": ".join(part for part in (source, key) if part)
        super().__init__(f"{where}: {message}" if where else message)


@dataclass(frozen=True)
class Field:
    """One leaf of the schema.

    ``kind`` is the expected Python type (``float`` accepts ints). A field without ``default`` is
    required. ``check`` may raise ValueError for constraints that bounds cannot express.
    """

    kind: type | tuple[type, ...]
    doc: str = ""
    default: Any = ...
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    choices: tuple[Any, ...] | None = None
    check: Callable[[Any], None] | None = None


@dataclass(frozen=True)
class Section:
    """A mapping with a fixed set of keys. ``open=True`` accepts any extra keys unchecked (their
    owner validates them later, e.g. an effect's parameters or a backend's transport settings).
    ``optional=True`` lets the whole section be omitted; its fields' defaults then apply."""

    fields: Mapping[str, "Field | Section | ListOf"]
    doc: str = ""
    optional: bool = False
    open: bool = False


@dataclass(frozen=True)
class ListOf:
    """A list whose items all follow one schema."""

    item: "Field | Section"
    doc: str = ""
    default: Any = field(default_factory=list)
    length: int | None = None


def positive(doc: str, **kw: Any) -> Field:
    """A float > 0 (give ``high=`` for its plausible upper bound)."""
    return Field(float, doc, low=0.0, low_open=True, **kw)


def non_negative(doc: str, **kw: Any) -> Field:
    """A float >= 0 (give ``high=`` for its plausible upper bound)."""
    return Field(float, doc, low=0.0, **kw)


def numeric_fields(spec: "Field | Section | ListOf", path: KeyPath = ()) -> Iterator[tuple[str, Field]]:
    """Every numeric leaf (int or float, not bool) of a schema as (dotted key, field), for checks
    that each one is bounded."""
    if isinstance(spec, Section):
        for name, sub in spec.fields.items():
            yield from numeric_fields(sub, path + (name,))
    elif isinstance(spec, ListOf):
        yield from numeric_fields(spec.item, path + ("*",))
    else:
        kinds = spec.kind if isinstance(spec.kind, tuple) else (spec.kind,)
        if int in kinds or float in kinds:
            yield ".".join(path), spec


def _type_name(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    names = {float: "a number", int: "an integer", bool: "true/false", str: "a string",
             list: "a list", dict: "a mapping"}
    return " or ".join(names.get(k, k.__name__) for k in kinds)


def _coerce_leaf(value: Any, spec: Field, where: str, source: str) -> Any:
    kinds = spec.kind if isinstance(spec.kind, tuple) else (spec.kind,)
    ok = False
    if isinstance(value, bool):
        ok = bool in kinds
    elif isinstance(value, int) and (int in kinds or float in kinds):
        ok = True
        if float in kinds and int not in kinds:
            try:
                value = float(value)
            except OverflowError:
                raise ConfigError("number out of range", source, where) from None
    else:
        ok = isinstance(value, kinds)
    if not ok and isinstance(value, bool) and spec.choices is not None:   # e.g. torque_feedback: off
        raise ConfigError(f"expected one of {list(spec.choices)}, got {value!r} (YAML reads an unquoted on/off/"
                          f"yes/no as true/false: quote it, e.g. \"{spec.choices[-1]}\")", source, where)
    if not ok:
        raise ConfigError(f"expected {_type_name(spec.kind)}, got {value!r}", source, where)
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"expected a finite number, got {value!r}", source, where)
    if spec.choices is not None and value not in spec.choices:
        raise ConfigError(f"expected one of {list(spec.choices)}, got {value!r}", source, where)
    bounded = value is not None     # an optional number left unset (its kind admits None) has no bound to hold
    if bounded and spec.low is not None and (value <= spec.low if spec.low_open else value < spec.low):
        op = ">" if spec.low_open else ">="
        raise ConfigError(f"must be {op} {spec.low:g}, got {value!r}", source, where)
    if bounded and spec.high is not None and value > spec.high:
        raise ConfigError(f"must be <= {spec.high:g}, got {value!r}", source, where)
    if spec.check is not None:
        try:
            spec.check(value)
        except ValueError as exc:
            raise ConfigError(str(exc), source, where) from None
    return value


def validate(data: Any, schema: Section, origin: Callable[[KeyPath], str], path: KeyPath = ()) -> dict:
    """Return a validated copy of ``data`` with software defaults filled in.

    ``origin(path)`` names the file a key came from, for error messages.
    """
    where = ".".join(path) or "<top level>"
    if not isinstance(data, dict):
        raise ConfigError(f"expected a mapping, got {data!r}", origin(path), where)
    out: dict[str, Any] = {}
    unknown = [k for k in data if k not in schema.fields]
    if unknown and not schema.open:
        key = ".".join(path + (str(unknown[0]),))
        raise ConfigError(f"unknown key (expected one of: {', '.join(schema.fields)})",
                          origin(path + (str(unknown[0]),)), key)
    for name in unknown:
        out[name] = data[name]
    for name, spec in schema.fields.items():
        sub = path + (name,)
        key = ".".join(sub)
        if name not in data:
            if isinstance(spec, Section):
                if spec.optional:
                    out[name] = validate({}, spec, origin, sub)
                    continue
                raise ConfigError(f"missing section ({spec.doc or 'required'})", origin(path), key)
            default = spec.default
            if default is ...:
                raise ConfigError(f"missing key: expected {_type_name(spec.kind)}"
                                  f"{' (' + spec.doc + ')' if spec.doc else ''}", origin(path), key)
            out[name] = copy.deepcopy(default)
            continue
        value = data[name]
        if isinstance(spec, Section):
            out[name] = validate(value, spec, origin, sub)
        elif isinstance(spec, ListOf):
            if not isinstance(value, list):
                raise ConfigError(f"expected a list, got {value!r}", origin(sub), key)
            if spec.length is not None and len(value) != spec.length:
                raise ConfigError(f"expected a list of {spec.length} items, got {len(value)}", origin(sub), key)
            items = []
            for i, item in enumerate(value):
                item_path = sub + (str(i),)
                if isinstance(spec.item, Section):
                    items.append(validate(item, spec.item, origin, item_path))
                else:
                    items.append(_coerce_leaf(item, spec.item, ".".join(item_path), origin(sub)))
            out[name] = items
        else:
            out[name] = _coerce_leaf(value, spec, key, origin(sub))
    return out
