"""Configuration loading and validation.

A configuration is one YAML file, optionally pulling in others with ``include:`` (paths relative to
the including file; later files and the including file override earlier ones, key by key). Every key
is checked against a declarative schema (:mod:`ankle_rt.config_schema`, built from
:mod:`ankle_rt.schema`): a typo, a missing key, a wrong type, a non-finite number or an out-of-range
value stops loading with a :class:`ConfigError` that names the file, the dotted key and what was
expected. Physical parameters never get silent defaults; only software options do.

Files are read as regular files only (a FIFO or ``/dev/zero`` named by ``include:`` fails at once),
at most :data:`MAX_CONFIG_BYTES` each and :data:`MAX_CONFIG_FILES` in all, as UTF-8 text; nesting is
bounded by :data:`MAX_CONFIG_DEPTH`. YAML aliases and anchors are refused (an alias bomb would expand
a small file past any size limit), as are duplicate keys (YAML keeps the last silently) and files of
more than :data:`MAX_CONFIG_NODES` nodes, all before anything is built from the document. Every such
problem is a ConfigError naming the file (and the key and line where there is one).
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any, Callable, Mapping

import yaml

from ankle_rt.config_schema import SCHEMA, check_consistency, resolve_correction_clamps
from ankle_rt.schema import (  # noqa: F401  (re-exported: the schema vocabulary's historical home)
    ConfigError, Field, KeyPath, ListOf, Section, non_negative, numeric_fields, positive, validate,
)
from ankle_rt.textfile import TextFileError, read_text

MAX_CONFIG_BYTES = 1 << 20
"""Largest config file read (1 MiB; the shipped ones are a few kB)."""
MAX_CONFIG_DEPTH = 16
"""Deepest nesting of mappings and lists accepted (the schema needs 4)."""
MAX_CONFIG_FILES = 32
"""Most files one config may pull in through ``include:`` (nested includes counted)."""
MAX_CONFIG_NODES = 100_000
"""Most YAML nodes (keys, values, list items) in one config file (the shipped ones have a few hundred)."""


_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)   # libyaml when present: the same documents, faster


def _read_yaml(path: Path) -> dict:
    """One config file as a mapping: a regular file of at most MAX_CONFIG_BYTES, UTF-8, valid YAML."""
    try:
        text = read_text(path, MAX_CONFIG_BYTES)
    except TextFileError as exc:
        raise ConfigError(f"cannot use as a config file: {exc}", str(path)) from None
    return parse_yaml(text, str(path))


def parse_yaml(text: str, source: str) -> dict:
    """A config document's text as a mapping (``{}`` when empty); ConfigError naming ``source`` when
    it is not valid YAML or not a mapping."""
    try:
        _check_nodes(yaml.compose(text, Loader=_LOADER), source)
        data = yaml.load(text, Loader=_LOADER)
    except yaml.YAMLError as exc:
        raise ConfigError(f"not valid YAML: {exc}", source) from None
    except RecursionError:
        raise ConfigError("not valid YAML: nested too deeply", source) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError("expected a mapping at the top level", source)
    if _depth(data) > MAX_CONFIG_DEPTH:
        raise ConfigError(f"nested deeper than {MAX_CONFIG_DEPTH} levels", source)
    return data


def _check_nodes(root: yaml.Node | None, source: str) -> None:
    """Refuse, before anything is built from it, a document with a YAML alias (``*name``: an alias
    bomb expands a few hundred bytes into gigabytes), a mapping with a duplicate key (YAML keeps the
    last one silently) or more than MAX_CONFIG_NODES nodes. ConfigError naming the key and line."""
    seen: set[int] = set()
    stack = [] if root is None else [root]
    while stack:
        node = stack.pop()
        if id(node) in seen:     # the composer shares an anchored node wherever it is aliased
            raise ConfigError(f"the value on line {node.start_mark.line + 1} is used again through a YAML "
                              "alias (*name, <<): aliases are not accepted in a config; write the values out", source)
        seen.add(id(node))
        if len(seen) > MAX_CONFIG_NODES:
            raise ConfigError(f"more than {MAX_CONFIG_NODES} YAML nodes", source)
        if isinstance(node, yaml.MappingNode):
            keys: dict[str, int] = {}
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode):
                    line = key.start_mark.line + 1
                    if key.value in keys:
                        raise ConfigError(f"line {line}: duplicate key {key.value!r} (first on line "
                                          f"{keys[key.value]}); YAML would keep only the last", source)
                    keys[key.value] = line
                stack.extend((key, value))
        elif isinstance(node, yaml.SequenceNode):
            stack.extend(node.value)


def _depth(data: object) -> int:
    """How deeply lists and mappings nest in ``data`` (iteratively: no recursion limit to hit)."""
    deepest, stack, seen = 0, [(data, 1)], set()
    while stack:
        item, level = stack.pop()
        if isinstance(item, (dict, list)) and id(item) not in seen:   # YAML aliases share objects
            seen.add(id(item))
            deepest = max(deepest, level)
            if level <= MAX_CONFIG_DEPTH:
                stack.extend((v, level + 1) for v in (item.values() if isinstance(item, dict) else item))
    return deepest


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


def read_with_includes(path: Path, origins: dict[KeyPath, str], stack: tuple[Path, ...] = (),
                       files: list[Path] | None = None) -> dict:
    """Read ``path`` and the files it includes into one mapping, recording where each key came from
    (``files`` collects every file read, to bound their number)."""
    path = path.resolve()
    files = [] if files is None else files
    if len(files) >= MAX_CONFIG_FILES:
        raise ConfigError(f"more than {MAX_CONFIG_FILES} config files through include", str(stack[-1]), "include")
    files.append(path)
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
        merge(merged, read_with_includes(inc_path, origins, stack + (path,), files), origins, str(inc_path.resolve()))
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

    return config_from_data(data, origin, str(path))


def config_data(cfg: Mapping[str, Any]) -> dict:
    """A validated config as data :func:`config_from_data` validates again to the same config (keys
    left without a value dropped, as if absent): a copy to change a key of and re-check."""
    return {key: config_data(value) if isinstance(value, Mapping) else copy.deepcopy(value)
            for key, value in cfg.items() if value is not None}


def config_from_data(data: dict, origin: Callable[[KeyPath], str], source: str) -> Config:
    """Merged config data validated key by key and across keys: the Config a run uses (``origin``:
    the file each key came from, for errors; ``source``: the config's name)."""
    cfg = Config(validate(data, SCHEMA, origin))
    resolve_correction_clamps(cfg)
    check_consistency(cfg, origin)
    _check_gain_margin(cfg, origin)
    cfg.source = source
    return cfg


def _check_gain_margin(cfg: Config, origin: Callable[[KeyPath], str]) -> None:
    """The impedance controller (with or without the joint-torque loop) and the motor-side PD (the
    gain set ``controller.pd_gains`` picks; choosing the other is a config change, checked again):
    the configured gain set must keep the required gain margin over the plant range, and the joint-torque
    loop (impedance, gait phase) must not turn the gauges' noise into more current than the oscillation
    detector allows (ConfigError naming the gain that limits it)."""
    from ankle_rt.gain_margin import gain_set_refusal, noise_refusal

    ctl = cfg["controller"]
    if ctl["type"] == "pd":
        section = ctl["pd_gains"] + "_gains"
        bad = gain_set_refusal(cfg, ctl[section])
    elif ctl["type"] == "impedance":
        section, bad = None, gain_set_refusal(cfg, {})
    elif ctl["type"] == "gait_phase":   # the phases' margins: when the controller is built; the loop's noise here
        section, bad = "torque_loop", noise_refusal(cfg, {})
    else:
        return
    if bad is not None:
        name, reason = bad
        section = section or ("torque_loop" if name in ctl["torque_loop"] else "impedance")
        raise ConfigError(reason, origin(("controller", section, name)), f"controller.{section}.{name}")
