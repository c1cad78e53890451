"""The probability of a surrogate round has one name, `surrogate_probability` (the setting,
the loop's hybrid policy and `Method.surrogate_probability`); its earlier name
`evaluation_probability` is still read from YAML files, stored configs and the command line,
and a config stored under the old name resolves to the same config hash as the new one (so a
grid finds runs recorded by older code)."""

from __future__ import annotations

import pytest

from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.config_loading import config_from_dict, make_config
from coadapt_core.methods import METHODS

BASE = {"method": "ours", "objective": "torque", "terrain": "flat", "seed": 0, "sim": "mujoco"}


def _as_older_code_stored_it(config: CoadaptConfig) -> dict:
    stored = config.to_dict()
    stored["evaluation_probability"] = stored.pop("surrogate_probability")
    return stored


def test_a_stored_config_with_the_old_key_has_the_same_hash_as_the_new_one():
    from coadapt_core.experiments.cell import Cell
    from coadapt_core.experiments.cell_hash import cell_config_hash, config_hash, run_config_hash

    new = make_config("smoke", None, {**BASE, "surrogate_probability": 0.3})
    old = _as_older_code_stored_it(new)
    assert "surrogate_probability" not in old and old["evaluation_probability"] == 0.3
    assert (
        run_config_hash({"config": old})
        == run_config_hash({"config": new.to_dict()})
        == config_hash(new.to_dict())
    )
    # the value is carried over, not dropped for the default (0.5 hashes differently)
    default = make_config("smoke", None, BASE)
    assert run_config_hash({"config": old}) != config_hash(default.to_dict())
    assert config_from_dict(old).surrogate_probability == 0.3
    # the grid's cell with the same setting given as a run argument finds the old run
    cell = Cell("ours", "torque", "flat", 0, "smoke", "mujoco")
    assert cell_config_hash(cell, ["--surrogate-probability", "0.3"]) == run_config_hash(
        {"config": old}
    )


def test_the_old_yaml_key_and_override_still_set_it(tmp_path):
    path = tmp_path / "old.yaml"
    path.write_text("evaluation_probability: 0.2\n")
    assert make_config("smoke", path).surrogate_probability == 0.2
    assert make_config("smoke", None, {"evaluation_probability": 0.7}).surrogate_probability == 0.7
    assert (
        make_config("smoke", path, {"surrogate_probability": 0.9}).surrogate_probability == 0.9
    )  # option over YAML


def test_the_old_command_line_option_is_an_alias():
    from coadapt_core.cli.run import config_options

    option = next(o.option for o in config_options() if o.param == "surrogate_probability")
    assert {"--surrogate-probability", "--evaluation-probability"} <= set(option.param_decls)


@pytest.mark.parametrize(
    ("method", "forced"), [("ours", None), ("no-surrogate", 0.0), ("no-real", 1.0)]
)
def test_the_loop_uses_the_setting_unless_the_method_forces_it(method, forced):
    from coadapt_core.coadapt.hybrid import HybridPolicy
    from coadapt_core.coadapt.state import LoopState

    config = make_config("smoke", None, {"surrogate_probability": 0.25, "method": method})
    assert METHODS[method].surrogate_probability == forced
    policy = HybridPolicy(
        config,
        METHODS[method],
        [],
        LoopState(run_id="r", config={}),
        None,
        lambda: None,
        lambda *parts: 0,
    )
    assert policy.surrogate_probability == (0.25 if forced is None else forced)
