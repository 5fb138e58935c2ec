"""Typed configurations: a setting is a dataclass field that carries its help, unit and limits.

A world's configuration (sim/highway/world.py WorldConfig, sim/sidewalk/world.py SidewalkConfig) is the one place
where each of its options has a default, a unit and a range. The command line (drivestudio/commands/world_options.py),
the Gymnasium keyword arguments and the JSON a run writes are derived from it; `check` holds a configuration to its
limits wherever it was made.

    cars: int = setting(12, "AI cars driven by SUMO", low=0, high=300)
"""
from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from core.inputs import check_keys

MAX_SEED = 2**32 - 1


class SettingError(ValueError):
    """A configuration value out of its setting's range or choices: one line, exit status 2."""


@dataclass(frozen=True)
class Setting:
    help: str
    unit: str = ""                     # "m/s", "px", "deg", ...
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()
    flag: str = ""                     # the command-line flag when it is not --field-name
    parse: Any = None                  # str -> value, for a setting whose text is not its type (a file or a number)
    several: bool = False              # the value may name several choices, comma-separated (a mix to draw from)


def setting(default: Any = dataclasses.MISSING, help: str = "", *, unit: str = "", low: float | None = None,
            high: float | None = None, choices: tuple[str, ...] = (), flag: str = "", parse: Any = None,
            several: bool = False, default_factory: Any = dataclasses.MISSING) -> Any:
    """A dataclass field that is a setting (see the module's docstring)."""
    meta = {"setting": Setting(help, unit, low, high, tuple(choices), flag, parse, several)}
    if default_factory is not dataclasses.MISSING:
        return field(default_factory=default_factory, metadata=meta)
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class Entry:
    """One setting of a configuration, by its dotted path (`camera.width`)."""

    path: str
    setting: Setting
    kind: type                         # int, float, bool, str or object (a parse function's value)
    default: Any
    optional: bool                     # None is a value (e.g. lanes: the track's own)

    @property
    def flag(self) -> str:
        return self.setting.flag or "--" + self.path.rsplit(".", 1)[-1].replace("_", "-")


def entries(cls: type) -> dict[str, Entry]:
    """Every setting of configuration class `cls`, nested configurations' too, by dotted path."""
    out: dict[str, Entry] = {}
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        hint = hints[f.name]
        default = f.default if f.default is not dataclasses.MISSING else \
            f.default_factory() if f.default_factory is not dataclasses.MISSING else None
        if dataclasses.is_dataclass(hint):
            for path, e in entries(hint).items():   # type: ignore[arg-type]
                out[f"{f.name}.{path}"] = dataclasses.replace(e, default=e.default if default is None else
                                                              get(default, path))
            continue
        s = f.metadata.get("setting")
        if s is None:
            continue
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        kind = args[0] if args else hint
        out[f.name] = Entry(f.name, s, kind if kind in (int, float, bool, str) else object, default,
                            type(None) in typing.get_args(hint))
    return out


def check_value(entry: Entry, value: Any, what: str | None = None) -> Any:
    """`value` held to its setting's kind, range and choices (SettingError, one line, naming `what` or else the
    flag)."""
    name, s = entry.flag if what is None else what, entry.setting
    if value is None:
        if entry.optional:
            return None
        raise SettingError(f"{name} must be given")
    if entry.kind is bool:
        if not isinstance(value, bool):
            raise SettingError(f"{name} must be true or false, got {value!r}")
        return value
    if entry.kind in (int, float):
        kind = "an integer" if entry.kind is int else "a number"
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                (entry.kind is int and math.isfinite(value) and not float(value).is_integer()):
            raise SettingError(f"{name} must be {kind}, got {value!r}")
        if not math.isfinite(value):
            raise SettingError(f"{name} must be a finite number, got {value!r}")
        value = entry.kind(value)
        if (s.low is not None and value < s.low) or (s.high is not None and value > s.high):
            unit = f" {s.unit}" if s.unit else ""
            raise SettingError(f"{name} must be {'an integer' if entry.kind is int else 'a number'} from "
                               f"{s.low:g} to {s.high:g}{unit}, got {value!r}")
    if entry.kind is str and not isinstance(value, str):
        raise SettingError(f"{name} must be a text, got {value!r}")
    if s.choices and s.several:
        return _several(name, s.choices, value)
    if s.choices and value not in s.choices:
        raise SettingError(f"{name}: invalid choice: {value!r} (choose from {', '.join(s.choices)})")
    return value


def _several(name: str, choices: tuple[str, ...], value: str) -> str:
    """A value naming one or more of `choices`, comma-separated, as `a,b` (spaces dropped); each name checked."""
    picked = [v.strip() for v in value.split(",")]
    for v in picked:
        if v not in choices:
            raise SettingError(f"{name}: invalid choice: {v!r} (choose one or more of {', '.join(choices)}, "
                               "comma-separated)")
    return ",".join(picked)


def read(entry: Entry, text: str, what: str = "") -> Any:
    """The value of a setting given as text (the command line, `--set NAME=VALUE`, a query string): a number, a
    choice, true or false, or `none` where None is a value."""
    name = what or entry.flag
    if entry.setting.parse is not None:
        return entry.setting.parse(text)
    if entry.optional and text.strip().lower() == "none":
        return None
    if entry.kind is bool:
        word = text.strip().lower()
        if word not in TRUE + FALSE:
            raise SettingError(f"{name} must be true or false, got {text!r}")
        return word in TRUE
    if entry.kind in (int, float):
        try:
            value = entry.kind(text)
        except ValueError:
            raise SettingError(f"{name} must be {'an integer' if entry.kind is int else 'a number'}, "
                               f"got {text!r}") from None
        return check_value(entry, value, name)
    return check_value(entry, text, name)


TRUE, FALSE = ("true", "yes", "on", "1"), ("false", "no", "off", "0")


def assign(config: Any, pairs: Iterable[str], where: str = "--set") -> Any:
    """`config` with settings given as `NAME=VALUE` texts (dotted names, as `entries` lists them), each read and
    held to its setting; a malformed pair or an unknown name is refused in one line naming `where`."""
    table = entries(type(config))
    values = {}
    for pair in pairs:
        name, eq, text = pair.partition("=")
        name = name.strip()
        if not eq or not name:
            raise SettingError(f"{where} takes NAME=VALUE, got {pair!r}")
        if name not in table:
            raise SettingError(f"{where} {name}: no such setting (settings: {', '.join(table)})")
        values[name] = read(table[name], text.strip(), f"{where} {name}")
    return with_values(config, values)


def check(config: Any) -> Any:
    """`config` held to every setting's limits; returns it."""
    for path, e in entries(type(config)).items():
        if e.setting.parse is None:
            check_value(e, get(config, path))
    return config


def get(config: Any, path: str) -> Any:
    for part in path.split("."):
        config = getattr(config, part)
    return config


def with_values(config: Any, values: dict[str, Any]) -> Any:
    """`config` with the settings of `values` (dotted paths) replaced."""
    top: dict[str, Any] = {}
    nested: dict[str, dict[str, Any]] = {}
    for path, v in values.items():
        head, _, rest = path.partition(".")
        if rest:
            nested.setdefault(head, {})[rest] = v
        else:
            top[head] = v
    for head, sub in nested.items():
        top[head] = with_values(getattr(config, head), sub)
    return dataclasses.replace(config, **top)


def as_json(config: Any) -> dict:
    """The settings of `config` as JSON-able values, by dotted path (what a run writes and --config reads)."""
    out = {}
    for path in entries(type(config)):
        v = get(config, path)
        out[path] = v if v is None or isinstance(v, (bool, int, float, str)) else str(v)
    return out


def from_json(config: Any, values: dict, where: str) -> Any:
    """`config` with the settings of a JSON object (dotted paths, as `as_json` writes them), each held to its
    setting; an unknown key or a bad value is refused in one line naming `where` and the key."""
    table = entries(type(config))
    check_keys(values, table, where, SettingError, "setting")
    out = {}
    for path, v in values.items():
        e = table[path]
        what = f"{where}: {path}"
        out[path] = e.setting.parse(str(v)) if e.setting.parse is not None and v is not None else \
            check_value(e, v, what)
    return with_values(config, out)
