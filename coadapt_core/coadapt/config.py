"""The co-adaptation run's settings: one typed tree (`CoadaptConfig`, a settings dataclass of
`coadapt_core.settings`), presets, YAML files and validation. The `coadapt run` options, the
YAML keys, the checks and docs/settings.md all come from the fields declared here.
Precedence: CLI option > YAML key > preset > declared default."""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import fields
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, field_validator

from coadapt_core.coadapt.learner_overrides import resolve_learner
from coadapt_core.coadapt.presets import PRESETS
from coadapt_core.costs import COST_RULES
from coadapt_core.design_space import parse_range_pairs
from coadapt_core.errors import UserError
from coadapt_core.learning.config import TrainConfig
from coadapt_core.methods import DEFAULT_METHOD, METHOD_NAMES, method_help, optimizer_for
from coadapt_core.physics.randomization import RANDOMIZATION_PRESETS, RandomizationConfig
from coadapt_core.physics.terrain import TERRAINS
from coadapt_core.plugins import default_plugin
from coadapt_core.settings import (
    Float,
    Int,
    overrides,
    partial,
    sections,
    setting,
    settings,
    to_plain,
)
from coadapt_core.task.config import TaskConfig


def check_device(device: Any, field: str = "device") -> str:
    """A torch device name coadapt accepts: cpu, cuda or cuda:N (one line otherwise)."""
    text = str(device)
    index = text[5:] if text.startswith("cuda:") else "0"
    if text not in ("cpu", "cuda") and not (text.startswith("cuda:") and index.isdigit()):
        raise UserError(f"{field} '{device}' is not one of: cpu, cuda, cuda:N", field=field)
    return text


#: a torch device name (checked by `check_device`)
Device = Annotated[str, AfterValidator(check_device)]

#: --evaluation-policy choices: the paper's fixed probability w, or the ensemble's agreement
EVALUATION_POLICIES: tuple[str, ...] = ("fixed", "uncertainty")


UNSET = "the starting policy's"
#: the run sets these itself (population, agents_per_design, device, seed; its own checkpoints)
TrainSection = partial(
    TrainConfig,
    "TrainSection",
    unset=UNSET,
    exclude=("num_designs", "agents_per_design", "device", "seed", "extra", "checkpoint_every"),
)
TaskSection = partial(TaskConfig, "TaskSection", unset=UNSET)
RandomizationSection = partial(
    RandomizationConfig,
    "RandomizationSection",
    unset=UNSET,
    extra={
        "preset": (
            Literal[RANDOMIZATION_PRESETS] | None,
            setting(
                None,
                "Named ranges the others apply over: table2 (the paper's), engine (table2 plus "
                "contact softness, joint damping, armature and delay) or off (unset: the starting "
                "policy's, table2 when it names none).",
            ),
        )
    },
)


@settings
class CoadaptConfig:
    """Every setting of `coadapt run`. Each field is a CLI option (`--outer-iterations`) and
    a YAML key (`outer_iterations`); its help, default and constraints are declared here
    once (`coadapt_core.settings`), and docs/settings.md is generated from them."""

    # -- what to co-adapt ------------------------------------------------------------------
    robot: str = setting(
        default_factory=lambda: default_plugin("robot"), help="Robot.", plugin="robot"
    )
    sim: str = setting(
        default_factory=lambda: default_plugin("simulator"),
        help="Simulator backend.",
        plugin="simulator",
    )
    optimizer: str = setting(
        default_factory=lambda: default_plugin("optimizer"),
        plugin="optimizer",
        help="Design optimizer; one that declares implies_mixed searches the mixed design space.",
    )
    objective: str = setting(
        default_factory=lambda: default_plugin("objective"),
        plugin="objective",
        help="Objective to minimise, or a comma list of 2-3 for a multi-objective optimizer.",
    )
    terrain: Literal[TERRAINS] = setting("flat", "Terrain.")
    method: Literal[METHOD_NAMES] = setting(DEFAULT_METHOD, method_help())
    mixed: bool = setting(
        False,
        "Add the robot's discrete variables (motor types); implied by an optimizer that declares "
        "implies_mixed.",
    )
    design_ranges: str = setting(
        "",
        "Initial range low:high per continuous variable, e.g. 0.5:1.5,0.5:1.0 (empty: the full "
        "range).",
    )
    seed: Int = setting(0, "Random seed.", ge=0)
    # -- Algorithm 4 -------------------------------------------------------------------------
    outer_iterations: Int = setting(3, "N: outer iterations (train, optimise, narrow).", ge=1)
    population: Int = setting(100, "K: designs per training phase = swarm size.", ge=1)
    optimizer_iterations: Int = setting(5, "J: optimizer rounds per outer iteration.", ge=1)
    surrogate_probability: Float = setting(
        0.5,
        "w: probability of a surrogate (not real) round (earlier name: evaluation_probability).",
        ge=0,
        le=1,
        accepted="a probability in [0, 1]",
    )
    agents_per_design: Int = setting(50, "Agents per design in training and real evaluation.", ge=1)
    train_steps: Int = setting(24_000_000, "Interactions of the first training phase.", ge=0)
    retrain_steps: Int = setting(24_000_000, "Interactions of each later retraining phase.", ge=0)
    eval_steps: Int = setting(
        800, "T_eval: policy steps per agent in a real evaluation (Algorithm 2).", ge=1
    )
    eval_agents: Int = setting(
        0, "Paired scenarios (agents) per design in a real evaluation (0: agents_per_design).", ge=0
    )
    surrogate_samples: Int = setting(
        4096, "States drawn from the evaluation buffer by the surrogate (Algorithm 3).", ge=1
    )
    measure_surrogate_error: bool = setting(
        True, "Run the surrogate on real batches too, to record its error (no interactions)."
    )
    surrogate_error_fits: bool = setting(
        False,
        "Fit the pseudo-critics before every real round too, so each one's "
        "surrogate error is measured (a fit per round); off: a real round is judged "
        "only where a fit already covers it.",
    )
    # -- the surrogate (docs/coadaptation.md, "The surrogate") --------------------------------
    fit_surrogate: bool = setting(
        True,
        "Fit the pseudo-critics to each real round's measured designs before a surrogate "
        "round (off: the paper's pseudo-critics as trained).",
    )
    surrogate_trend: bool = setting(
        False,
        "Surrogate rounds cost designs by a least-squares plane in the design through this "
        "policy's real rounds, not the pseudo-critics (beyond the paper; docs/coadaptation.md).",
    )
    evaluation_policy: Literal[EVALUATION_POLICIES] = setting(
        "fixed",
        "fixed: a surrogate round with probability surrogate_probability (w, the paper's); "
        "uncertainty: a surrogate round when the fitted ensemble agrees (spread ratio <= "
        "uncertainty_threshold).",
    )
    uncertainty_threshold: Float = setting(
        0.5,
        "uncertainty policy: trust the surrogate when the members' spread over "
        "the designs' spread is at most this.",
        ge=0,
    )
    final_candidates: Int = setting(
        3, "Lowest-real-cost designs re-evaluated in the final check.", ge=1
    )
    final_max_blocks: Int = setting(
        8, "Final check: at most this many blocks of agents_per_design paired scenarios.", ge=1
    )
    final_min_blocks: Int = setting(
        4,
        "Final check: at least this many blocks (the fall-rate comparison needs scenarios).",
        ge=1,
    )
    # -- a design's cost over its scenarios (docs/coadaptation.md, "How a fall enters the fitness")
    cost_rule: Literal[COST_RULES] = setting(
        "capped",
        "capped: each scenario costs at most cost_cap x the nominal design's median scenario and a "
        "fall costs that cap (every design on the same scenarios, the same rule); mean: the "
        "paper's plain mean (eq. 4); trimmed: each design's costliest quarter of scenarios left "
        "out (the rule before, falls unpriced).",
    )
    cost_cap: Float = setting(
        3.0,
        "capped rule: a scenario's cost cap, and a fall's cost, in units of the nominal "
        "design's median scenario cost.",
        gt=1,
    )
    fall_tolerance: Float = setting(
        0.01,
        "Final check: a candidate whose fall rate exceeds the nominal design's by more "
        "than max(this, 2 paired standard errors) cannot be the best (1: no fall gate).",
        ge=0,
        le=1,
    )
    # -- plugin options: declared by the optimizer / objective plugin (`option_specs`) ------
    optimizer_options: dict[str, Any] = setting(
        default_factory=dict,
        help="Options the optimizer plugin declares (`coadapt plugins --json`), e.g. "
        "{inertia: 0.9}.",
        cli=False,
    )
    objective_options: dict[str, Any] = setting(
        default_factory=dict,
        help="Options the objective plugin declares, e.g. {weights: 'torque=1'}.",
        cli=False,
    )
    # -- the refinement stage after the search (coadapt/refine.py; beyond the paper) ----------
    refine_with: str = setting(
        "",
        "Refinement after the last outer iteration (empty: none; beyond the paper): an "
        "optimizer that follows the surrogate's gradient (declares follows_surrogate_slope, "
        "e.g. gradient) descends from the best real design, its steps confirmed real.",
    )
    refine_rounds: Int = setting(
        8,
        "Refinement: real rounds, the first re-evaluating the start design under the final policy.",
        ge=1,
    )
    # -- narrowing (Algorithm 4 line 22) -----------------------------------------------------
    narrow_margin: Float = setting(
        0.25, "Narrowing: widen the final particles' span by this fraction on each side.", ge=0
    )
    narrow_min_width: Float = setting(
        0.1, "Narrowing: minimum width as a fraction of the full range.", gt=0, le=1
    )
    # -- BO with specialised policies (Table 7 baseline) -------------------------------------
    bo_designs: Int = setting(
        20, "bo-specialized: designs BO proposes, each with its own specialised policy.", ge=1
    )
    specialized_train_steps: Int = setting(
        10_000_000, "bo-specialized: interactions per specialised policy.", ge=0
    )
    specialized_init: Literal["scratch", "universal"] = setting(
        "scratch",
        "bo-specialized: scratch (the paper's) or universal (fine-tune the universal policy per "
        "design).",
    )
    # -- infrastructure ----------------------------------------------------------------------
    checkpoint_interactions: Int = setting(
        3_000_000,
        "Interactions between checkpoints inside a training "
        "phase, which --resume continues from (0: between phases only).",
        ge=0,
    )
    checkpoint: str = setting(
        "",
        "Universal policy to start from (empty: the one the robot ships, if any; none: from "
        "scratch).",
    )
    device: Device = setting(
        "cpu", "Torch device of the learner.", accepted="one of cpu, cuda, cuda:N"
    )
    logger: Literal["tensorboard", "wandb", "none"] = setting(
        "tensorboard",
        "Experiment tracking: tensorboard (event files in <run folder>/tb), wandb (if installed) "
        "or none.",
    )
    out: str = setting("runs", "Parent folder of run folders.")
    store: str = setting(
        "",
        "Results store URL or path (empty: $COADAPT_STORE, else coadapt.db beside out; none: JSON "
        "files only).",
    )
    preset: Literal[tuple(PRESETS)] = setting(
        "quick", "Preset the other defaults come from (recorded)."
    )
    # -- the learner: overrides of the starting policy's settings ----------------------------
    train: TrainSection = setting(
        default_factory=TrainSection,
        help=(
            "PPO and training settings of the universal policy "
            "(`coadapt_core.learning.config.TrainConfig`). Unset keys keep the starting policy's "
            "(its checkpoint records them), else the defaults shown. The batch size, device and "
            "seed are the run's own population, agents_per_design, device and seed."
        ),
    )
    task: TaskSection = setting(
        default_factory=TaskSection,
        help=(
            "The locomotion task: commands, rewards, gait reference, observation noise, "
            "termination (`coadapt_core.task.config.TaskConfig`). Unset keys keep the starting "
            "policy's; weights given replace those terms' weights only."
        ),
    )
    randomization: RandomizationSection = setting(
        default_factory=RandomizationSection,
        help=(
            "Domain randomization (paper Table 2; "
            "`coadapt_core.physics.randomization.RandomizationConfig`): a preset, then single "
            "ranges over it. Unset: the starting policy's preset (table2 when it names none)."
        ),
    )

    @field_validator("objective", mode="before")
    @classmethod
    def _objective_list(cls, value: Any) -> Any:
        if isinstance(value, list | tuple):  # YAML: objective: [power, torque]
            return ",".join(str(v) for v in value)
        return value

    @field_validator("optimizer_options", "objective_options", mode="before")
    @classmethod
    def _option_keys(cls, value: Any) -> Any:
        if isinstance(value, Mapping):
            return {str(k).replace("-", "_"): v for k, v in value.items()}
        return value

    @field_validator("design_ranges")
    @classmethod
    def _ranges(cls, value: str) -> str:
        parse_range_pairs(value, field="design_ranges")
        return value

    # -----------------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return to_plain(self)

    @property
    def evaluation_agents(self) -> int:
        """Scenarios (agents) per design in real evaluation: eval_agents, else agents_per_design."""
        return int(self.eval_agents) or int(self.agents_per_design)

    @property
    def objectives(self) -> list[str]:
        return [o.strip() for o in self.objective.split(",") if o.strip()]

    def validate(self) -> CoadaptConfig:
        """Every field checked again (values may have been assigned since construction), then
        what involves several fields; a `UserError` (one line naming the field) otherwise."""
        checked = type(self)(**{f.name: getattr(self, f.name) for f in fields(self)})
        for f in fields(self):
            setattr(self, f.name, getattr(checked, f.name))
        # a method that needs an optimizer capability (the BO baseline: `sequential`) records
        # the optimizer it really searches with (run id, config.yaml, store)
        self.optimizer = optimizer_for(self.method, self.optimizer)
        if not self.objectives:
            raise UserError("objective must name at least one objective", field="objective")
        if len(set(self.objectives)) != len(self.objectives):
            raise UserError(f"objective list '{self.objective}' repeats a name", field="objective")
        if self.evaluation_policy == "uncertainty" and not self.fit_surrogate:
            raise UserError(
                "evaluation_policy 'uncertainty' needs fit_surrogate (the fitted ensemble decides)",
                field="evaluation_policy",
            )
        if self.evaluation_policy == "uncertainty" and self.surrogate_trend:
            raise UserError(
                "evaluation_policy 'uncertainty' decides by the fitted ensemble's spread; "
                "surrogate_trend replaces that ensemble's costs: use one of them",
                field="surrogate_trend",
            )
        # the sections' keys applied over the defaults: checked together
        resolve_learner(
            None, overrides(self.train), overrides(self.task), overrides(self.randomization)
        )
        return self


FIELD_NAMES = tuple(f.name for f in fields(CoadaptConfig))
#: the nested sections of the config (YAML mappings; options --train-..., --task-..., ...)
SECTIONS = tuple(sections(CoadaptConfig))


@functools.cache
def preset_defaults() -> dict[str, tuple[Any, dict[str, Any]]]:
    """{option parameter name: (its `Leaf`, {preset: default})} for every config setting
    (the preset itself excluded): what an option left unset takes."""
    from coadapt_core.settings import leaves

    out = {}
    for leaf in leaves(CoadaptConfig):
        if leaf.key != "preset":  # a plugin's default is looked up when shown (`default_rank`)
            values = (
                {}
                if leaf.extra.get("plugin")
                else {p: PRESETS[p].get(leaf.key, leaf.default) for p in PRESETS}
            )
            out[leaf.param] = (leaf, values)
    return out
