"""Configuration loading and validation.

A configuration is one YAML file, optionally pulling in others with ``include:`` (paths relative to
the including file; later files and the including file override earlier ones, key by key). Every key
is checked against a declarative schema: a typo, a missing key, a wrong type or an out-of-range value
stops loading with a :class:`ConfigError` that names the file, the dotted key and what was expected.
Physical parameters never get silent defaults; only software options do.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import yaml

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
    return Field(float, doc, low=0.0, low_open=True, **kw)


def non_negative(doc: str, **kw: Any) -> Field:
    return Field(float, doc, low=0.0, **kw)


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
            value = float(value)
    else:
        ok = isinstance(value, kinds)
    if not ok:
        raise ConfigError(f"expected {_type_name(spec.kind)}, got {value!r}", source, where)
    if spec.choices is not None and value not in spec.choices:
        raise ConfigError(f"expected one of {list(spec.choices)}, got {value!r}", source, where)
    if spec.low is not None and (value <= spec.low if spec.low_open else value < spec.low):
        op = ">" if spec.low_open else ">="
        raise ConfigError(f"must be {op} {spec.low:g}, got {value!r}", source, where)
    if spec.high is not None and value > spec.high:
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


def _read_yaml(path: Path) -> dict:
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read config file: {exc.strerror}", str(path)) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"not valid YAML: {exc}", str(path)) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError("expected a mapping at the top level", str(path))
    return data


def merge(into: dict, new: dict, origins: dict[KeyPath, str] | None = None, source: str = "",
          path: KeyPath = ()) -> None:
    """Merge ``new`` into ``into`` key by key, recursively (new values are copied); record in
    ``origins`` which ``source`` each replaced key came from, when given."""
    for key, value in new.items():
        sub = path + (key,)
        if isinstance(value, dict) and isinstance(into.get(key), dict):
            merge(into[key], value, origins, source, sub)
        else:
            into[key] = copy.deepcopy(value)
            if origins is not None:
                origins[sub] = source


def read_with_includes(path: Path, origins: dict[KeyPath, str], stack: tuple[Path, ...] = ()) -> dict:
    """Read ``path`` and the files it includes into one mapping, recording where each key came from."""
    path = path.resolve()
    if path in stack:
        chain = " -> ".join(p.name for p in stack + (path,))
        raise ConfigError(f"include cycle: {chain}", str(stack[-1]), "include")
    raw = _read_yaml(path)
    includes = raw.pop("include", [])
    if isinstance(includes, str):
        includes = [includes]
    if not isinstance(includes, list) or not all(isinstance(i, str) for i in includes):
        raise ConfigError("expected a file name or a list of file names", str(path), "include")
    merged: dict = {}
    for inc in includes:
        inc_path = (path.parent / inc)
        if not inc_path.exists():
            raise ConfigError(f"included file {inc!r} not found (looked in {path.parent})", str(path), "include")
        merge(merged, read_with_includes(inc_path, origins, stack + (path,)), origins, str(inc_path.resolve()))
    merge(merged, raw, origins, str(path))
    return merged


class Config(dict):
    """A validated configuration: a plain nested dict plus where it was loaded from."""

    source: str = "<memory>"

    def deep_copy(self) -> "Config":
        """A copy that may be edited freely, naming the same source file in its errors."""
        out = Config(copy.deepcopy(dict(self)))
        out.source = self.source
        return out


def load_config(path: str | Path, overrides: dict | None = None) -> Config:
    """Load, merge includes, apply ``overrides`` (a nested mapping) and validate a config file."""
    from ankle_rt.config_schema import SCHEMA

    path = Path(path)
    origins: dict[KeyPath, str] = {}
    data = read_with_includes(path, origins)
    if overrides:
        merge(data, overrides, origins, "<command line>")

    def origin(key_path: KeyPath) -> str:
        for n in range(len(key_path), 0, -1):
            if key_path[:n] in origins:
                return origins[key_path[:n]]
        return str(path.resolve())

    cfg = Config(validate(data, SCHEMA, origin))
    cfg.source = str(path)
    return cfg
