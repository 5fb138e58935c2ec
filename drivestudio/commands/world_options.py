"""The world options of one verb's parser, derived from each world's typed configuration (core/settings.py).

A world's Plugin names, per verb, the settings of its configuration that the verb shows (`verb_settings`, dotted
paths such as `camera.width`); each becomes a flag with the setting's help, unit, range and default, read back into
a configuration by `config`; every other setting is given as `--set NAME=VALUE`. A flag two worlds share (--seed)
is added once and belongs to both. Every flag has default None, so that `given` can tell which flags of a world the
user set and a configuration keeps its own default for the others. A world may add options of its own that are not
settings (a generation plan's lists) with `add`.
"""
from __future__ import annotations

import argparse
from typing import Any

from core.settings import Entry, assign, entries, read, with_values
from drivestudio.errors import UsageError


def _help(e: Entry, defaults: dict[str, Any]) -> str:
    s = e.setting
    unit = f" [{s.unit}]" if s.unit else ""
    limits = f", {s.low:g}-{s.high:g}" if s.low is not None and s.high is not None and e.kind in (int, float) and \
        s.high < 10**6 else ""
    shown = {w: d for w, d in defaults.items() if d is not None and d is not False}
    if s.several:
        limits += f"; one of {', '.join(s.choices)}, or several comma-separated (each seed draws one)"
    if e.kind is bool or not shown:
        return f"{s.help}{unit}{limits}"
    if len(set(map(str, shown.values()))) == 1:
        return f"{s.help}{unit}{limits} (default {next(iter(shown.values()))})"
    return f"{s.help}{unit}{limits} (default " + ", ".join(f"{w} {d}" for w, d in shown.items()) + ")"


class WorldOptions:
    def __init__(self, parser: argparse.ArgumentParser, verb: str):
        self.parser, self.verb = parser, verb
        self._dest: dict[str, str] = {}                # flag -> dest, of every world option added
        self._owned: dict[str, dict[str, str]] = {}    # world -> flag -> dest
        self._paths: dict[str, dict[str, str]] = {}    # world -> setting path -> flag
        self._entries: dict[str, Entry] = {}           # flag -> the first world's entry (the flag's type)
        self.hidden = False                            # options added now are read but not listed in --help

    def group(self, title: str):
        return self.parser.add_argument_group(title)

    def add(self, world: str, group, *flags: str, **kw) -> None:
        """An option of `world` that is not a setting of its configuration."""
        flag = flags[0]
        if flag not in self._dest:
            if self.hidden:
                kw["help"] = argparse.SUPPRESS
            self._dest[flag] = group.add_argument(*flags, default=None, **kw).dest
        self._owned.setdefault(world, {})[flag] = self._dest[flag]

    def add_settings(self, world: str, config_type: type, paths: tuple[str, ...], group,
                     defaults: dict[str, dict[str, Any]]) -> None:
        """The flags of `paths`, settings of `config_type`; `defaults`: flag -> {world: default} for the help."""
        table = entries(config_type)
        for path in paths:
            e = table[path]
            if e.flag not in self._dest:
                metavar = e.flag[2:].upper().replace("-", "_")
                kw: dict[str, Any] = {"action": "store_true"} if e.kind is bool else \
                    {"type": _reader(e), "metavar": f"{metavar}[,{metavar}...]" if e.setting.several else metavar}
                if e.setting.choices and not e.setting.several:   # a mix of several is checked by the setting
                    kw["choices"] = e.setting.choices
                shown = argparse.SUPPRESS if self.hidden else _help(e, defaults[e.flag])
                self._dest[e.flag] = group.add_argument(e.flag, default=None, help=shown, **kw).dest
                self._entries[e.flag] = e
            self._owned.setdefault(world, {})[e.flag] = self._dest[e.flag]
            self._paths.setdefault(world, {})[path] = e.flag

    def values(self, world: str, args) -> dict[str, Any]:
        """{destination: value} of the options of `world` that are not settings (None: not given)."""
        settings = set(self._paths.get(world, {}).values())
        return {dest: getattr(args, dest, None) for flag, dest in self._owned.get(world, {}).items()
                if flag not in settings}

    def owns(self, world: str, flag: str) -> bool:
        return flag in self._owned.get(world, {})

    def given(self, world: str, args) -> list[str]:
        """The flags of `world` that `args` sets."""
        return [f for f, dest in self._owned.get(world, {}).items() if getattr(args, dest, None) not in (None, False)]

    def config(self, world: str, base: Any, args) -> Any:
        """`base` (the world's configuration) with the settings the user gave on the command line; each value is
        read again with the world's own setting (a flag two worlds share is typed by the first)."""
        table = entries(type(base))
        values = {}
        for path, flag in self._paths.get(world, {}).items():
            v = getattr(args, self._dest[flag], None)
            if v is None or v is False:
                continue
            e = table[path]
            values[path] = v if e.kind is bool else read(e, str(v), flag) if e.setting.parse is None or \
                isinstance(v, str) else v
        return assign(with_values(base, values), getattr(args, "set", None) or ())


def _reader(e: Entry):
    """argparse's `type=`: the setting's own reading, its refusal as argparse's one line."""
    if e.setting.parse is not None:
        return str

    def parse(text: str):
        try:
            return read(e, text, e.flag)
        except ValueError as err:
            raise argparse.ArgumentTypeError(str(err).removeprefix(f"{e.flag}: ").removeprefix(f"{e.flag} ")) \
                from None
    parse.__name__ = {int: "integer", float: "number"}.get(e.kind, "value")
    return parse


def refuse_other_worlds(options: WorldOptions, plugin, others, args) -> None:
    """Options that only another world has are refused in one line."""
    for other in others:
        if other.name != plugin.name:
            given = [f for f in options.given(other.name, args) if not options.owns(plugin.name, f)]
            if given:
                raise UsageError(f"{', '.join(given)} belong{'s' if len(given) == 1 else ''} to the {other.name} "
                                 f"world, not to --world {plugin.name}")
