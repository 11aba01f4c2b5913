"""A sweep's configuration as text and as a store records it: :func:`load_config` reads a
TOML file, :func:`config_to_toml` writes one, :func:`config_template` writes every key at
its default, and :func:`with_new_defaults` / :func:`config_differences` compare a store's
recorded configuration with a sweep's.
"""

from __future__ import annotations

import textwrap
import tomllib
from pathlib import Path

from lfjax.model.options import ModelOptions
from lfjax.sweep.config import (KEYS, SCHEMA, SweepConfig, config_fields, config_from_dict,
                                config_sections)
from lfjax.sweep.config_keys import (CONFIG_FORMAT, UNIT_SUFFIXES, SweepConfigError, shown,
                                     toml_value)

def load_config(path) -> SweepConfig:
    """Read and validate a sweep TOML file (relative layout paths are relative to it)."""
    path = Path(path)
    if path.is_dir():
        raise SweepConfigError([f"{str(path)!r} is a folder, not a TOML config file (lfjax "
                                f"sweep --template CONFIG.toml writes one)"], str(path))
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise SweepConfigError([f"config file {str(path)!r} does not exist"], str(path)) from None
    except (OSError, UnicodeDecodeError) as err:
        raise SweepConfigError([f"cannot read the config file: {err}"], str(path)) from None
    except tomllib.TOMLDecodeError as err:
        raise SweepConfigError([f"not valid TOML: {err}"], str(path)) from None
    if not data:
        # an empty file would otherwise start the default sweep (1,000 eyes, hours)
        raise SweepConfigError(["the config file sets nothing: write at least one section "
                                "(lfjax sweep --template CONFIG.toml writes every key with "
                                "its default)"], str(path))
    return config_from_dict(data, base_dir=path.parent, source=str(path))


def config_to_toml(config: SweepConfig) -> str:
    """TOML text that :func:`load_config` reads back into ``config``."""
    sections = config_sections(config_fields(config))
    lines = []
    for section, body in sections.items():
        lines.append(f"[{section}]")
        for key, value in body.items():
            lines.append(f"{key} = {toml_value(value)}")
        lines.append("")
    return "\n".join(lines)


def config_template() -> str:
    """A commented TOML config with every key at its default (keys whose default is "not
    set" are commented out with an example value); :func:`load_config` reads it as
    ``SweepConfig()``. ``lfjax sweep --template CONFIG.toml`` writes it. Above each key: its
    help and allowed values (:data:`~lfjax.sweep.config.KEYS`)."""
    units = ", ".join(f"{suffix} {name}" for suffix, name in UNIT_SUFFIXES.items())
    lines = [f"# lfjax sweep configuration ({CONFIG_FORMAT}): every key with its default.",
             *textwrap.wrap(f"Units are in the key names: {units}. Run: lfjax sweep "
                            f"THIS.toml --dry-run", 88, initial_indent="# ",
                            subsequent_indent="# "), ""]
    for section, keys in SCHEMA.items():
        lines.append(f"[{section}]")
        for key in keys.values():
            if key.default is not None:
                text, prefix = toml_value(key.default), ""
            elif key.none_word is not None:
                text, prefix = toml_value(key.none_word), ""
            else:
                text, prefix = toml_value(key.example), "# "
            about = key.help + (f"; {key.rules()}" if key.rules() else "")
            lines += textwrap.wrap(about, 88, initial_indent="# ", subsequent_indent="#   ",
                                   break_on_hyphens=False)
            lines.append(f"{prefix}{key.name} = {text}")
        lines.append("")
    lines.append("[model]  # lfjax.ModelOptions fields")
    for key, value in ModelOptions().as_dict().items():
        if value is not None:
            lines.append(f"{key} = {toml_value(value)}")
        else:
            lines.append(f"# {key} = (not set)")
    return "\n".join(lines) + "\n"


def with_new_defaults(stored: dict) -> dict:
    """A stored :meth:`~lfjax.sweep.config.SweepConfig.as_dict` record with every key it
    lacks at its default.

    A store written before a key existed was computed as that key's default computes (a new
    key's default changes nothing), so it resumes under a config leaving the key there; set
    to anything else, the key then differs from the record."""
    out = dict(stored)
    for key in KEYS:
        if key.field not in out:
            out[key.field] = shown(key.default)
    return out


def config_differences(stored: dict, current: dict, prefix: str = "") -> list[str]:
    """Human-readable differences between two
    :meth:`~lfjax.sweep.config.SweepConfig.as_dict` records."""
    out = []
    for key in sorted(set(stored) | set(current)):
        a, b = stored.get(key, "<absent>"), current.get(key, "<absent>")
        if isinstance(a, dict) and isinstance(b, dict):
            out += config_differences(a, b, f"{prefix}{key}.")
        elif a != b:
            out.append(f"{prefix}{key}: store has {a!r}, config has {b!r}")
    return out


__all__ = [
    "config_differences",
    "config_template",
    "config_to_toml",
    "load_config",
    "with_new_defaults",
]
