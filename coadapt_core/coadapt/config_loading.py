"""Building a `CoadaptConfig`: a preset, then a YAML file's keys, then the options given
(`make_config`; keys of earlier versions through `config_aliases`), and rebuilding a recorded
one (`config_from_dict`, e.g. from a run folder's config.yaml)."""

from __future__ import annotations

import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from coadapt_core.coadapt.config import FIELD_NAMES, PRESETS, SECTIONS, CoadaptConfig
from coadapt_core.coadapt.config_aliases import RENAMED_KEYS, OptionAlias, option_aliases
from coadapt_core.coadapt.presets import check_preset
from coadapt_core.errors import UserError

#: config keys that are plugin-option mappings, merged key by key (CLI over YAML over preset)
OPTION_FIELDS = ("optimizer_options", "objective_options")
#: keys a run folder's config.yaml records beside the config (where and what it ran on);
#: a config file may hold them (a run's config.yaml given to --config) and they are ignored
RECORD_KEYS = ("run_id", "run_dir", "design_space", "grid_id", "grid_cell", "policy", "threads")


def load_yaml(path: str | Path) -> dict[str, Any]:
    import yaml

    path = Path(path)
    if not path.is_file():
        raise UserError(f"config file '{path}' does not exist", field="config")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except UnicodeDecodeError:
        raise UserError(f"config file '{path}' is not a text (YAML) file", field="config") from None
    except OSError as exc:
        raise UserError(
            f"config file '{path}' cannot be read ({exc.strerror})", field="config"
        ) from None
    except yaml.YAMLError as exc:
        raise UserError(
            f"config file '{path}' is not valid YAML: {str(exc).splitlines()[0]}", field="config"
        ) from None
    if not isinstance(data, dict):
        raise UserError(f"config file '{path}' must hold a mapping of config keys", field="config")
    return {str(k).replace("-", "_"): v for k, v in data.items()}


def make_config(
    preset: str | None = None,
    yaml_file: str | Path | None = None,
    overrides: dict[str, Any] | None = None,
) -> CoadaptConfig:
    """Preset, then YAML keys, then overrides (CLI options that were given), validated."""
    yaml_values = load_yaml(yaml_file) if yaml_file else {}
    for key in RECORD_KEYS:
        yaml_values.pop(key, None)
    overrides = {k: v for k, v in (overrides or {}).items() if v is not None}
    preset = preset or overrides.get("preset") or yaml_values.get("preset") or "quick"
    check_preset(preset)
    values: dict[str, Any] = {**PRESETS[preset], "preset": preset}
    aliases = option_aliases()
    for source, label in ((yaml_values, "config file"), (overrides, "option")):
        for key, value in source.items():
            _set_key(values, RENAMED_KEYS.get(key, key), value, label, aliases)
    values["preset"] = preset
    _fold_names(values)
    return _typed_options(CoadaptConfig(**values).validate())


def _set_key(
    values: dict[str, Any], key: str, value: Any, label: str, aliases: dict[str, OptionAlias]
) -> None:
    """One key of a config file or option into `values`: a plugin option's alias, a key of a
    nested section, a plugin-option mapping (merged) or a plain setting."""
    if key in aliases:  # an earlier version's key: one option of a plugin now
        alias = aliases[key]
        values[alias.field] = {**values.get(alias.field, {}), alias.option.name: value}
        return
    section, dot, rest = key.partition(".")
    if section not in FIELD_NAMES or (dot and section not in SECTIONS):
        _unknown_key(key, section, label)
    if value is None:
        raise UserError(f"config key '{key}' has no value", field=key)
    if dot or section in SECTIONS:  # a nested key: merged into its section
        _set_nested(values.setdefault(section, {}), key, rest.split(".") if dot else [], value)
        return
    if key in OPTION_FIELDS:  # merged key by key: a CLI option keeps the YAML file's others
        if not isinstance(value, Mapping):
            raise UserError(
                f"{key} must be a mapping of option names to values, got {value!r}",
                field=key,
            )
        value = {
            **values.get(key, {}),
            **{str(k).replace("-", "_"): v for k, v in value.items()},
        }
    values[key] = value


def _unknown_key(key: str, section: str, label: str) -> typing.NoReturn:
    import difflib

    close = difflib.get_close_matches(section, FIELD_NAMES, n=1, cutoff=0.75)
    if close:
        raise UserError(
            f"unknown {label} key '{key}'; did you mean '{close[0]}'? (every key: "
            "docs/settings.md)",
            field=key,
        )
    raise UserError(
        f"unknown {label} key '{key}'; accepted keys: {', '.join(FIELD_NAMES)}",
        field=key,
    )


def _set_nested(tree: dict[str, Any], key: str, path: list[str], value: Any) -> None:
    """A section's key (`train.lr`, path ['lr']) or the whole section's mapping (path [])
    merged into the section's `tree`."""
    if not isinstance(value, Mapping) and not path:
        raise UserError(f"{key} must be a mapping of its settings, got {value!r}", field=key)
    for name in path[:-1]:
        tree = tree.setdefault(name, {})
    if path:
        tree[path[-1]] = value
    else:
        _merge(tree, value)


def _merge(tree: dict[str, Any], new: Mapping[str, Any]) -> None:
    for key, value in new.items():
        if isinstance(value, Mapping) and isinstance(tree.get(key), dict):
            _merge(tree[key], value)
        else:
            tree[str(key)] = dict(value) if isinstance(value, Mapping) else value


#: settings that name a plugin or a fixed choice: `Torque` or `FLAT` is taken as written in
#: lower case when only that spelling is known
_FOLDED = ("robot", "sim", "optimizer", "objective", "terrain", "method", "evaluation_policy")


def _fold_names(values: dict[str, Any]) -> None:
    from coadapt_core.plugins import get_registry

    kinds = {
        "robot": "robot",
        "sim": "simulator",
        "optimizer": "optimizer",
        "objective": "objective",
    }
    for key in _FOLDED:
        value = values.get(key)
        if isinstance(value, list | tuple):
            value = ",".join(map(str, value))
        if not isinstance(value, str) or value == value.lower():
            continue
        if key in kinds:
            try:
                known = set(get_registry().names(kinds[key]))
            except Exception:  # the registry cannot be built: the run's own checks report it
                continue
        else:
            known = set(typing.get_args(CoadaptConfig.__pydantic_fields__[key].annotation))
        names = [n.strip() for n in value.split(",")]
        values[key] = ",".join(
            n.lower() if n not in known and n.lower() in known else n for n in names
        )


def _typed_options(config: CoadaptConfig) -> CoadaptConfig:
    """Plugin option values as the plugins declare them (command-line text '0.5' -> 0.5), so
    a config means one thing however its options were written (config.yaml, grid hashes).
    A bad value is the one-line user error the run would give; unknown plugins or
    undeclared keys are left for the run's own checks to report."""
    try:
        from coadapt_core.plugins import get_registry

        registry = get_registry()
        optimizer = registry.get("optimizer", config.optimizer)
        objectives = [registry.get("objective", n) for n in config.objectives]
    except Exception:
        return config
    sources = [
        ("optimizer_options", [optimizer], "optimizer"),
        ("objective_options", objectives, "objective"),
    ]
    for field_name, classes, kind in sources:
        given = dict(getattr(config, field_name))
        for key, value in given.items():
            owner = next(
                (c for c in classes if any(s.name == key for s in getattr(c, "option_specs", ()))),
                None,
            )
            if owner is not None:
                spec = next(s for s in owner.option_specs if s.name == key)
                given[key] = spec.convert(value, f"{kind} '{owner.name}'", field_name)
        setattr(config, field_name, given)
    return config


def config_from_dict(data: dict[str, Any]) -> CoadaptConfig:
    """Rebuild a recorded config (e.g. from a run folder's config.yaml)."""
    renamed = {
        RENAMED_KEYS[k]: v
        for k, v in data.items()
        if k in RENAMED_KEYS and RENAMED_KEYS[k] not in data
    }
    known = {k: v for k, v in {**data, **renamed}.items() if k in FIELD_NAMES and v is not None}
    # a config.yaml of an earlier version recorded every alias key; their old defaults are the
    # plugins' declared defaults now (empty text: unset), so only values that differed carry over
    for key, alias in option_aliases().items():
        if data.get(key) not in (None, "", alias.option.default):
            known[alias.field] = {alias.option.name: data[key], **known.get(alias.field, {})}
    return CoadaptConfig(**known).validate()
