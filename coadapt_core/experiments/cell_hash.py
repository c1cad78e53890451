"""The config hash that tells whether a stored run answers a grid cell: a short hash of the
resolved run config (preset, YAML and options applied) without the keys that only say where
or how a run is stored or executed. A cell's hash is the one `coadapt run` will record for
it; a stored run's is its recorded config resolved again."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from coadapt_core.errors import UserError

if TYPE_CHECKING:
    from coadapt_core.experiments.cell import Cell

#: config keys that say where or how a run is stored or executed, not what it computes
CONFIG_HASH_IGNORES = frozenset(
    {
        "out",
        "store",
        "run_id",
        "run_dir",
        "device",
        "design_space",
        "grid_id",
        "grid_cell",
        "logger",
    }
)


def config_hash(config: dict[str, Any]) -> str:
    """A short hash of a resolved run config (preset, YAML and options applied), without the
    keys that do not change what the run computes (`CONFIG_HASH_IGNORES`)."""
    kept = {k: v for k, v in sorted(config.items()) if k not in CONFIG_HASH_IGNORES}
    return hashlib.sha1(json.dumps(kept, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _extra_overrides(extra: Sequence[str]) -> dict[str, Any] | None:
    """`coadapt run` options given as grid --run-arg (`--population 3`, `--no-mixed`,
    `--train-epochs 3`) as config overrides (keys of the settings tree, dotted for a section);
    None when one of them is not a config option (the hash is then unknown)."""
    from coadapt_core.coadapt.config import CoadaptConfig
    from coadapt_core.settings import leaves

    settings = {leaf.param: leaf for leaf in leaves(CoadaptConfig) if leaf.extra.get("cli", True)}
    out: dict[str, Any] = {}
    items = list(extra)
    i = 0
    while i < len(items):
        token = items[i]
        if not token.startswith("--"):
            return None
        name, eq, value = token[2:].partition("=")
        param = name.replace("-", "_")
        negated = settings.get(param[3:]) if param.startswith("no_") else None
        leaf = settings.get(param)
        if not eq and negated is not None and negated.kind == "bool":
            out[negated.key] = False
        elif not eq and leaf is not None and leaf.kind == "bool":
            out[leaf.key] = True
        elif leaf is not None and leaf.key != "preset":
            if not eq:
                i += 1
                if i >= len(items):
                    return None
                value = items[i]
            out[leaf.key] = value
        else:
            return None
        i += 1
    return out


def cell_config_hash(cell: Cell, extra: Sequence[str] = ()) -> str | None:
    """The config hash `coadapt run` will record for this cell, or None when it cannot be
    known here (an --run-arg option that is not a config field, a config that does not validate)."""
    from coadapt_core.coadapt.config_loading import make_config

    overrides = _extra_overrides(extra)
    if overrides is None:
        return None
    overrides.update(
        method=cell.method,
        objective=cell.objective,
        terrain=cell.terrain,
        seed=cell.seed,
        sim=cell.sim,
    )
    if cell.robot:
        overrides["robot"] = cell.robot
    if cell.optimizer:
        overrides["optimizer"] = cell.optimizer
    try:
        return config_hash(make_config(cell.preset, None, overrides).to_dict())
    except (UserError, TypeError, ValueError):
        return None


def run_config_hash(run: dict[str, Any]) -> str | None:
    """The config hash of a stored run (its recorded config, resolved again), or None."""
    from coadapt_core.coadapt.config_loading import config_from_dict

    config = run.get("config")
    if not isinstance(config, dict) or not config:
        return None
    try:
        return config_hash(config_from_dict(config).to_dict())
    except (UserError, TypeError, ValueError):
        return None
