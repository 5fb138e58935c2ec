"""A run's settings on the command line, derived from its typed configuration (core/settings.py): the few settings
most runs set are flags, every other one is `--set NAME=VALUE` (its --help lists them with their defaults), and the
run's config.json, given back with `--config FILE`, runs it again.

A flag has default None, so that a setting keeps the configuration's default, or the --config file's value, unless
it is given. The order of precedence: the defaults (or a preset such as --quick), the --config file, the flags given,
then every --set; each value is read and held to its setting, and a refusal is one line (exit status 2) before any
work.
"""
from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from core.inputs import check_keys, read_json
from core.settings import Entry, assign, check, entries, from_json, read, with_values
from drivestudio.errors import UsageError


def default_text(value: Any) -> str:
    """A default as `--set` reads it back."""
    return "none" if value is None else str(value).lower() if isinstance(value, bool) else str(value)


def defaults_text(config_type: type, shown: Iterable[str] = ()) -> str:
    """`NAME=DEFAULT UNIT, ...`: the settings of `config_type` that are not in `shown`, with their defaults."""
    hidden = set(shown)
    return ", ".join(f"{path}={default_text(e.default)}{e.setting.unit and ' ' + e.setting.unit}"
                     for path, e in entries(config_type).items() if path not in hidden)


def flag_help(e: Entry, config: bool = False) -> str:
    """A setting's help as its flag shows it: the text, the unit, the range, the default (or that it must be given,
    here or, with `config`, by the --config file)."""
    s = e.setting
    unit = f" [{s.unit}]" if s.unit else ""
    limits = f", {s.low:g}-{s.high:g}" if s.low is not None and s.high is not None and s.high < 10**6 else ""
    default = "" if e.kind is bool or e.optional else f" (default {e.default})" if e.default is not None else \
        " (required, or from --config)" if config else " (required)"
    return f"{s.help}{unit}{limits}{default}"


def add_flags(group, config_type: type, names: Iterable[str], config: bool = False) -> None:
    """A flag for each setting of `names` (`--batch-size` for batch_size), its help derived from the setting;
    `config`: the verb takes --config too."""
    table = entries(config_type)
    for name in names:
        e = table[name]
        kw: dict[str, Any] = {"choices": e.setting.choices} if e.setting.choices else \
            {"metavar": e.flag[2:].upper().replace("-", "_")}
        group.add_argument(e.flag, dest=name, default=None, help=flag_help(e, config), **kw)


def add_set(group, config_type: type, shown: Iterable[str], what: str, listing: str | None = None) -> None:
    """--set NAME=VALUE, repeatable: any setting of `config_type`; the help lists those without a flag (`shown`)
    with their defaults, or says `listing`."""
    group.add_argument("--set", action="append", metavar="NAME=VALUE",
                       help=f"a setting of {what}, repeatable; the others, with their defaults: "
                            f"{listing or defaults_text(config_type, shown)}")


def add_config(group, what: str) -> None:
    """--config FILE: `what` ("the study") as its config.json says."""
    group.add_argument("--config", metavar="CONFIG.json",
                       help=f"run {what} again as its config.json says (its folder holds it); the options given here "
                            "override it")


def read_config(path: str, keys: Iterable[str] | None = None) -> dict:
    """The JSON object of a run's config.json; with `keys`, any other key is refused in one line."""
    data = read_json(path, "run configuration")
    if not isinstance(data, dict):
        raise UsageError(f"{path}: a run configuration is a JSON object")
    if keys is not None:
        check_keys(data, tuple(keys), str(path), UsageError)
    return data


def resolve(base: Any, args, flags: Iterable[str], saved: dict | None = None) -> Any:
    """`base` with the --config file's settings (`saved` where the file holds more than settings), then the flags
    of `flags` that were given, then every --set; each value read and held to its setting."""
    config = base
    if saved is None and getattr(args, "config", None):
        saved = read_config(args.config)
    if saved is not None:
        config = from_json(config, saved, str(args.config))
    table = entries(type(config))
    given = {name: read(table[name], text) for name in flags if (text := getattr(args, name)) is not None}
    return check(assign(with_values(config, given), getattr(args, "set", None) or ()))
