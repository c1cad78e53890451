"""Defaults of the plugin kinds come from the plugins' own declarations (`default_rank`),
never from a name written in the core; ties are settled by name, whatever the load order."""

from __future__ import annotations

from coadapt_core.plugins import PluginInfo, Registry, get_registry


def _registry(*classes: type) -> Registry:
    registry = Registry()
    for cls in classes:
        registry.entries["robot"][cls.name] = PluginInfo(
            "robot", cls.name, cls, "test", "0", "test"
        )
    return registry


def _robot(name: str, rank: int | None = None) -> type:
    attrs: dict = {"name": name}
    if rank is not None:
        attrs["default_rank"] = rank
    return type(name.title(), (), attrs)


def test_highest_rank_wins_and_ties_go_to_the_first_name():
    low, high, other_high = _robot("alpha"), _robot("zeta", 5), _robot("mid", 5)
    assert _registry(low, high).default("robot") == "zeta"
    # a tie: the first name alphabetically, in either load order
    assert _registry(high, other_high, low).default("robot") == "mid"
    assert _registry(other_high, high, low).default("robot") == "mid"
    # nothing declared anywhere: the first name
    assert _registry(_robot("b"), _robot("a")).default("robot") == "a"
    # a second one (the report's transfer simulator): the next by rank after the default
    assert _registry(low, high, other_high).default("robot", exclude=("mid",)) == "zeta"
    assert _registry(low, high).default("robot", exclude=("zeta",)) == "alpha"


def test_a_third_party_plugin_can_become_the_default():
    builtin = get_registry().get("robot", get_registry().default("robot"))
    challenger = _robot("yours", int(getattr(builtin, "default_rank", 0)) + 1)
    assert _registry(builtin, challenger).default("robot") == "yours"


def test_the_run_config_takes_its_defaults_from_the_declarations():
    from coadapt_core.coadapt.config import CoadaptConfig

    registry = get_registry()
    config = CoadaptConfig()
    for kind, value in (
        ("robot", config.robot),
        ("simulator", config.sim),
        ("optimizer", config.optimizer),
        ("objective", config.objective),
    ):
        ranks = {
            name: getattr(registry.get(kind, name), "default_rank", 0)
            for name in registry.names(kind)
        }
        assert ranks[value] == max(ranks.values()), (kind, ranks)
        assert value == min(n for n, r in ranks.items() if r == ranks[value])


def test_an_empty_kind_is_a_one_line_user_error():
    import pytest

    from coadapt_core.errors import UserError

    with pytest.raises(UserError, match="unknown robot"):
        Registry().default("robot")
