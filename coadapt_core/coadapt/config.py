"""The co-adaptation run's settings: one documented dataclass (CleanRL style), presets, YAML
files and validation. Precedence: CLI option > YAML key > preset > dataclass default."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError
from coadapt_core.physics.simulator import TERRAINS

#: --method choices; see `METHOD_SWITCHES` in coadapt_core/coadapt/loop.py
METHODS: tuple[str, ...] = ("ours", "no-surrogate", "no-real", "no-retrain", "bo-specialized")
#: --evaluation-policy choices: the paper's fixed probability w, or the ensemble's agreement
EVALUATION_POLICIES: tuple[str, ...] = ("fixed", "uncertainty")


@dataclass
class CoadaptConfig:
    """Every setting of `coadapt run`. Each field is a CLI option (`--outer-iterations`) and
    a YAML key (`outer_iterations`)."""

    # -- what to co-adapt ------------------------------------------------------------------
    robot: str = "kuafu"  # robot plugin
    sim: str = "mujoco"  # simulator plugin
    optimizer: str = "pso"  # optimizer plugin; mixed-pso switches to the mixed design space
    objective: str = "torque"  # objective plugin, or a comma list of 2-3 for nsga2
    terrain: str = "flat"  # flat | slope | random
    method: str = "ours"  # ours | no-surrogate | no-real | no-retrain | bo-specialized
    mixed: bool = False  # add the robot's discrete variables (motor types); implied by mixed-pso
    design_ranges: str = ""  # initial range 'low:high,...' per continuous variable (default full)
    seed: int = 0
    # -- Algorithm 4 -------------------------------------------------------------------------
    outer_iterations: int = 3  # N: train / optimise / narrow rounds
    population: int = 100  # K: designs sampled for training = particles of the swarm
    optimizer_iterations: int = 5  # J: optimizer ask/tell rounds per outer iteration
    evaluation_probability: float = 0.5  # w: probability of surrogate (not real) evaluation
    agents_per_design: int = 50  # parallel agents per design in training and real evaluation
    train_steps: int = 24_000_000  # environment interactions of the first training phase
    retrain_steps: int = 24_000_000  # environment interactions of each later (re)training
    eval_steps: int = 800  # T_eval: policy steps per agent in a real evaluation (Alg. 2)
    eval_agents: int = 0  # paired scenarios (agents) per design in a real evaluation; 0 = agents_per_design
    surrogate_samples: int = 4096  # T_eval states drawn from R_eval by the surrogate (Alg. 3)
    measure_surrogate_error: bool = True  # also run the surrogate on every real batch (no interactions)
    # -- the surrogate (docs/coadaptation.md, "The surrogate") --------------------------------
    fit_surrogate: bool = True  # fit the pseudo-critics to each real round's measured designs before trusting them
    evaluation_policy: str = "fixed"  # fixed: surrogate round with probability w (paper) | uncertainty: when the ensemble agrees
    uncertainty_threshold: float = 0.5  # uncertainty: surrogate round when members' spread / designs' spread <= this
    final_candidates: int = 3  # lowest-real-cost designs re-evaluated in the final check
    final_max_blocks: int = 8  # final check: at most this many blocks of agents_per_design paired scenarios
    # -- plugin options: declared by the optimizer / objective plugin (`option_specs`) ------
    optimizer_options: dict[str, Any] = field(default_factory=dict)  # e.g. {inertia: 0.9} for pso
    objective_options: dict[str, Any] = field(default_factory=dict)  # e.g. {weights: 'torque=1'} for composite
    # -- narrowing (Algorithm 4 line 22) -----------------------------------------------------
    narrow_margin: float = 0.25  # widen the particles' span by this fraction on each side
    narrow_min_width: float = 0.1  # ... to at least this fraction of the full range
    # -- BO with specialised policies (Table 7 baseline) -------------------------------------
    bo_designs: int = 20  # designs BO proposes, each with its own specialised policy
    specialized_train_steps: int = 10_000_000  # interactions per specialised policy
    specialized_init: str = "scratch"  # scratch (the paper's) | universal: fine-tune the universal policy on the design
    # -- infrastructure ----------------------------------------------------------------------
    checkpoint: str = ""  # universal policy to start from ('' = the shipped one if any, 'none' = scratch)
    device: str = "cpu"  # torch device of the learner
    logger: str = "tensorboard"  # tensorboard | wandb | none: curves and rounds in <run folder>/tb
    out: str = "runs"  # parent folder of run folders
    store: str = ""  # results store URL or path (empty: $COADAPT_STORE, else coadapt.db beside `out`; "none": JSON files only)
    preset: str = "quick"  # the preset this config started from (recorded)

    # -----------------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @property
    def evaluation_agents(self) -> int:
        """Scenarios (agents) per design in real evaluation: eval_agents, else agents_per_design."""
        return int(self.eval_agents) or int(self.agents_per_design)

    @property
    def objectives(self) -> list[str]:
        return [o.strip() for o in self.objective.split(",") if o.strip()]

    def validate(self) -> CoadaptConfig:
        """Raise `UserError` (one line naming the field and what is accepted) on a bad value."""
        if self.method not in METHODS:
            raise UserError(f"method '{self.method}' is not one of {', '.join(METHODS)}", field="method")
        if self.method == "bo-specialized":
            # the BO baseline always searches with BO: record the optimizer it really uses
            # (run id, config.yaml, store), whatever the preset's or the option's optimizer
            self.optimizer = "bo"
        if self.terrain not in TERRAINS:
            raise UserError(f"terrain '{self.terrain}' is not one of {', '.join(TERRAINS)}", field="terrain")
        if not self.objectives:
            raise UserError("objective must name at least one objective", field="objective")
        if len(set(self.objectives)) != len(self.objectives):
            raise UserError(f"objective list '{self.objective}' repeats a name", field="objective")
        for name in ("outer_iterations", "population", "optimizer_iterations", "agents_per_design", "eval_steps", "surrogate_samples", "bo_designs", "final_candidates", "final_max_blocks"):
            _int_at_least(name, getattr(self, name), 1)
        for name in ("train_steps", "retrain_steps", "specialized_train_steps", "seed", "eval_agents"):
            _int_at_least(name, getattr(self, name), 0)
        p = self.evaluation_probability
        if not isinstance(p, int | float) or not (0.0 <= p <= 1.0):
            raise UserError(
                f"evaluation_probability must be a probability in [0, 1], got {p}", field="evaluation_probability"
            )
        for name in ("optimizer_options", "objective_options"):
            value = getattr(self, name)
            if not isinstance(value, Mapping):
                raise UserError(f"{name} must be a mapping of option names to values, got {value!r}", field=name)
            setattr(self, name, {str(k).replace("-", "_"): v for k, v in value.items()})
        _finite_at_least("narrow_margin", self.narrow_margin, 0.0)
        if not (0.0 < self.narrow_min_width <= 1.0):
            raise UserError(
                f"narrow_min_width must be in (0, 1] (a fraction of the full range), got {self.narrow_min_width}",
                field="narrow_min_width",
            )
        if self.specialized_init not in ("scratch", "universal"):
            raise UserError(
                f"specialized_init '{self.specialized_init}' is not one of scratch, universal", field="specialized_init"
            )
        if self.evaluation_policy not in EVALUATION_POLICIES:
            raise UserError(
                f"evaluation_policy '{self.evaluation_policy}' is not one of {', '.join(EVALUATION_POLICIES)}",
                field="evaluation_policy",
            )
        _finite_at_least("uncertainty_threshold", self.uncertainty_threshold, 0.0)
        if self.logger not in ("tensorboard", "wandb", "none"):
            raise UserError(f"logger '{self.logger}' is not one of tensorboard, wandb, none", field="logger")
        for f in fields(self):
            if f.type == "bool":
                setattr(self, f.name, _boolean(f.name, getattr(self, f.name)))
        if self.evaluation_policy == "uncertainty" and not self.fit_surrogate:
            raise UserError("evaluation_policy 'uncertainty' needs fit_surrogate (the fitted ensemble decides)",
                            field="evaluation_policy")
        check_device(self.device)
        parse_ranges(self.design_ranges)
        return self


def _int_at_least(name: str, value: Any, low: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise UserError(f"{name} must be an integer >= {low}, got {value!r}", field=name)


def _finite_at_least(name: str, value: Any, low: float) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value < low:
        raise UserError(f"{name} must be a finite number >= {low:g}, got {value!r}", field=name)


def parse_ranges(text: str) -> list[tuple[float, float]]:
    """'0.5:1.5,0.6:1.2' -> [(0.5, 1.5), (0.6, 1.2)]; inverted or malformed ranges are user errors."""
    out = []
    for part in [p.strip() for p in str(text).split(",") if p.strip()]:
        try:
            lo_s, hi_s = part.split(":")
            lo, hi = float(lo_s), float(hi_s)
        except ValueError:
            raise UserError(
                f"design range '{part}' must look like low:high, e.g. 0.5:1.5", field="design_ranges"
            ) from None
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise UserError(f"design range '{part}' must have finite bounds", field="design_ranges")
        if lo > hi:
            raise UserError(
                f"design range '{part}' has inverted bounds; the lower bound must not exceed the upper",
                field="design_ranges",
            )
        out.append((lo, hi))
    return out


#: presets: only the fields that differ from the dataclass defaults (which are the paper's)
PRESETS: dict[str, dict[str, Any]] = {
    # seconds on a laptop: for tests and for checking that everything is wired
    "smoke": dict(
        outer_iterations=2, population=4, optimizer_iterations=2, agents_per_design=2,
        train_steps=400, retrain_steps=200, eval_steps=20, surrogate_samples=64,
        bo_designs=2, specialized_train_steps=200,
    ),
    # meaningful on a 2-core laptop in <= 30 min, starting from the shipped universal policy.
    # Real evaluation 32 paired scenarios x 250 steps per design (8,000 interactions, as many as
    # the 16 x 500 before): the smallest size measured to rank a 5 x 5 grid alike under two
    # scenario seeds (Spearman 0.95-0.97 for tracking, power, torque; benchmarks/fitness_noise.py)
    "quick": dict(
        outer_iterations=3, population=16, optimizer_iterations=5, agents_per_design=16,
        train_steps=200_000, retrain_steps=100_000, eval_agents=32, eval_steps=250, surrogate_samples=4096,
        bo_designs=20, specialized_train_steps=100_000, specialized_init="universal",
    ),
    # section 4.1.3: N = 3, K = 100, J = 5, 50 agents, w = 0.5, inertia 0.9, c1 = c2 = 2
    "paper": dict(
        outer_iterations=3, population=100, optimizer_iterations=5, agents_per_design=50,
        evaluation_probability=0.5,
        train_steps=24_000_000, retrain_steps=24_000_000, eval_steps=800, bo_designs=20,
        specialized_train_steps=10_000_000,
    ),
}

FIELD_NAMES = tuple(f.name for f in fields(CoadaptConfig))
#: config keys that are plugin-option mappings, merged key by key (CLI over YAML over preset)
OPTION_FIELDS = ("optimizer_options", "objective_options")
#: keys of earlier versions, still accepted: (mapping they now go to, option name there)
LEGACY_KEYS: dict[str, tuple[str, str]] = {
    "inertia": ("optimizer_options", "inertia"),
    "c1": ("optimizer_options", "c1"),
    "c2": ("optimizer_options", "c2"),
    "bo_sampler": ("optimizer_options", "sampler"),
    "bo_storage": ("optimizer_options", "storage"),
    "objective_weights": ("objective_options", "weights"),
}


def _coerce(name: str, value: Any) -> Any:
    """YAML gives ints for floats and strings for anything quoted: bring values to the field's type."""
    kind = {f.name: f.type for f in fields(CoadaptConfig)}[name]
    if value is None:
        raise UserError(f"config key '{name}' has no value", field=name)
    if name in OPTION_FIELDS:
        if not isinstance(value, Mapping):
            raise UserError(f"config key '{name}' must be a mapping of option names to values, got {value!r}", field=name)
        return {str(k).replace("-", "_"): v for k, v in value.items()}
    if kind == "bool":
        return _boolean(name, value)
    try:
        if kind == "float" and not isinstance(value, bool):
            return float(value)
        if kind == "int" and isinstance(value, str):
            return int(value.replace("_", ""))
        if kind == "str":
            if isinstance(value, list | tuple):  # objective: [power, torque]
                return ",".join(str(v) for v in value)
            return str(value)
    except ValueError:
        raise UserError(f"config key '{name}' must be a {kind}, got {value!r}", field=name) from None
    return value


_TRUE, _FALSE = ("true", "yes", "on", "1"), ("false", "no", "off", "0")


def _boolean(name: str, value: Any) -> bool:
    """A YAML/CLI boolean: true/false (also yes/no, on/off, 1/0, in any case, quoted or not);
    anything else is a one-line error, never read as true because it is a non-empty string."""
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower() if isinstance(value, str | int) else None
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    raise UserError(f"config key '{name}' must be true or false, got {value!r}", field=name)


def check_device(device: Any, field: str = "device") -> str:
    """A torch device name coadapt accepts: cpu, cuda or cuda:N (one line otherwise)."""
    text = str(device)
    index = text[5:] if text.startswith("cuda:") else "0"
    if text not in ("cpu", "cuda") and not (text.startswith("cuda:") and index.isdigit()):
        raise UserError(f"{field} '{device}' is not one of: cpu, cuda, cuda:N", field=field)
    return text


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
        raise UserError(f"config file '{path}' cannot be read ({exc.strerror})", field="config") from None
    except yaml.YAMLError as exc:
        raise UserError(f"config file '{path}' is not valid YAML: {str(exc).splitlines()[0]}", field="config") from None
    if not isinstance(data, dict):
        raise UserError(f"config file '{path}' must hold a mapping of config keys", field="config")
    return {str(k).replace("-", "_"): v for k, v in data.items()}


def make_config(
    preset: str | None = None, yaml_file: str | Path | None = None, overrides: dict[str, Any] | None = None
) -> CoadaptConfig:
    """Preset, then YAML keys, then overrides (CLI options that were given), validated."""
    yaml_values = load_yaml(yaml_file) if yaml_file else {}
    overrides = {k: v for k, v in (overrides or {}).items() if v is not None}
    preset = preset or overrides.get("preset") or yaml_values.get("preset") or "quick"
    if preset not in PRESETS:
        raise UserError(f"preset '{preset}' is not one of {', '.join(PRESETS)}", field="preset")
    values: dict[str, Any] = {**PRESETS[preset], "preset": preset}
    for source, label in ((yaml_values, "config file"), (overrides, "option")):
        for key, value in source.items():
            if key in LEGACY_KEYS:  # an earlier version's key: one option of a plugin now
                target, option = LEGACY_KEYS[key]
                values[target] = {**values.get(target, {}), option: value}
                continue
            if key not in FIELD_NAMES:
                raise UserError(
                    f"unknown {label} key '{key}'; accepted keys: {', '.join(FIELD_NAMES)}", field=key
                )
            value = _coerce(key, value)
            if key in OPTION_FIELDS:  # merged key by key: a CLI option keeps the YAML file's others
                value = {**values.get(key, {}), **value}
            values[key] = value
    values["preset"] = preset
    return _typed_options(CoadaptConfig(**values).validate())


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
    sources = [("optimizer_options", [optimizer], "optimizer"), ("objective_options", objectives, "objective")]
    for field_name, classes, kind in sources:
        given = dict(getattr(config, field_name))
        for key, value in given.items():
            owner = next((c for c in classes if any(s.name == key for s in getattr(c, "option_specs", ()))), None)
            if owner is not None:
                spec = next(s for s in owner.option_specs if s.name == key)
                given[key] = spec.convert(value, f"{kind} '{owner.name}'", field_name)
        setattr(config, field_name, given)
    return config


def config_from_dict(data: dict[str, Any]) -> CoadaptConfig:
    """Rebuild a recorded config (e.g. from a run folder's config.yaml)."""
    known = {k: _coerce(k, v) for k, v in data.items() if k in FIELD_NAMES}
    # a config.yaml of an earlier version recorded every legacy key; their old defaults are the
    # plugins' defaults now, so only values that differed are carried over
    old_defaults = {"inertia": 0.9, "c1": 2.0, "c2": 2.0, "bo_sampler": "tpe", "bo_storage": "", "objective_weights": ""}
    for key, (target, option) in LEGACY_KEYS.items():
        if key in data and data[key] is not None and data[key] != old_defaults[key]:
            known[target] = {option: data[key], **known.get(target, {})}
    return CoadaptConfig(**known).validate()


__all__ = ["FIELD_NAMES", "METHODS", "PRESETS", "CoadaptConfig", "config_from_dict", "make_config", "parse_ranges"]
