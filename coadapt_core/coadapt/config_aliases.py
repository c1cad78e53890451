"""Keys of earlier versions that `coadapt run` and its config files still take: settings
renamed since (`RENAMED_KEYS`, with their old options `OPTION_ALIASES`) and top-level keys
that now set one option of a plugin, as the plugins declare them (`option_aliases`)."""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

from coadapt_core.options import PluginOption

#: the plugin kind whose declared options each plugin-option mapping of the config holds
OPTION_KINDS = {"objective_options": "objective", "optimizer_options": "optimizer"}
#: settings of earlier versions under another name: old YAML key -> the setting's key now
#: (the old command-line option is kept as an alias, `OPTION_ALIASES`)
RENAMED_KEYS: dict[str, str] = {"evaluation_probability": "surrogate_probability"}
OPTION_ALIASES: dict[str, tuple[str, ...]] = {
    new: ("--" + old.replace("_", "-"),) for old, new in RENAMED_KEYS.items()
}


@dataclass(frozen=True)
class OptionAlias:
    """A top-level key (and `coadapt run` option) that sets one plugin option, as the plugin
    declares it (`PluginOption.alias`): the keys of earlier versions."""

    key: str
    field: str  # optimizer_options | objective_options
    option: PluginOption
    plugins: tuple[str, ...]  # the installed plugins declaring it


def option_aliases(settings: Collection[str] | None = None) -> dict[str, OptionAlias]:
    """Every alias the installed optimizer and objective plugins declare for their options,
    by key (none when the registry cannot be built; a key that is a config setting, or that
    two plugins declare for different options, is left out). `settings`: the config's
    top-level setting names when known without it (`coadapt run`'s stored option table,
    `coadapt_core.cli.run_options`); by default read from `CoadaptConfig`."""
    from coadapt_core.plugins import get_registry

    if settings is None:
        from coadapt_core.coadapt.config import FIELD_NAMES

        settings = FIELD_NAMES

    try:
        registry = get_registry()
    except Exception:  # the commands report why the registry cannot be built
        return {}
    out: dict[str, OptionAlias] = {}
    clashes: set[str] = set()
    for field_name, kind in OPTION_KINDS.items():
        for name in registry.names(kind):
            for spec in getattr(registry.get(kind, name), "option_specs", ()):
                if not spec.alias or spec.alias in settings:
                    continue
                known = out.get(spec.alias)
                if known is None:
                    out[spec.alias] = OptionAlias(spec.alias, field_name, spec, (name,))
                elif (known.field, known.option.name) == (field_name, spec.name):
                    out[spec.alias] = OptionAlias(
                        spec.alias, field_name, known.option, (*known.plugins, name)
                    )
                else:
                    clashes.add(spec.alias)
    return {k: v for k, v in out.items() if k not in clashes}
