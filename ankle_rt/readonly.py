"""Read-only copies of configuration data: what controller plugins are given.

A plugin is built from the validated config but must not change what the daemon, the safety layer or
another part of the run reads (a plugin that wrote ``amplifier.current_limit_peak`` could otherwise
raise the current clamp). :func:`read_only` returns a deep copy in which every mapping refuses
writes (TypeError naming the key) and every list is a tuple: a write fails loudly, and even a write
forced past the guard changes only the plugin's own copy.
"""

from __future__ import annotations

from typing import Any, NoReturn


class ReadOnlyDict(dict):
    """A dict that refuses every change (TypeError). Still a dict, so readers that check
    ``isinstance(x, dict)`` or take ``**mapping`` keep working. ``source``: the config's name."""

    source: str = "<memory>"

    def _refuse(self, *args: Any, **kwargs: Any) -> NoReturn:
        key = f" (key {args[0]!r})" if args and isinstance(args[0], str) else ""
        raise TypeError(f"the configuration is read-only for controllers{key}: a controller may not change it")

    __setitem__ = __delitem__ = __ior__ = _refuse
    update = pop = popitem = clear = setdefault = _refuse


def read_only(value: Any) -> Any:
    """A deep read-only copy of ``value``: mappings become ReadOnlyDict, lists and tuples tuples
    (their items copied the same way); other values are returned as they are (immutable scalars)."""
    if isinstance(value, dict):
        out = ReadOnlyDict({k: read_only(v) for k, v in value.items()})
        source = getattr(value, "source", None)
        if source is not None:
            out.source = source
        return out
    if isinstance(value, (list, tuple)):
        return tuple(read_only(v) for v in value)
    return value
