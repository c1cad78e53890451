"""What `coadapt eval --checkpoint` accepts (issue 43): a checkpoint file, a `coadapt train`
folder (its newest checkpoint), a `coadapt run` folder or a run id under ./runs (the run's
last policy, `viz.video.run_checkpoint`); anything else, `none` included, is one line that
says what is accepted."""

from __future__ import annotations

import sys
from pathlib import Path

from coadapt_core.cli.common import fail
from coadapt_core.errors import UserError

#: what `coadapt eval --checkpoint` accepts, said when it gets something else
EVAL_CHECKPOINTS = (
    "a checkpoint file (.pt), the --out folder of a `coadapt train`, a `coadapt run` folder or run "
    "id under ./runs (its last checkpoint), or no --checkpoint for the robot's shipped policy"
)


def eval_checkpoint_path(checkpoint: Path | None) -> Path | None:
    """--checkpoint: a file; a training folder stands for its newest checkpoint, a run folder
    or a run id under ./runs for the run's last policy (`run_checkpoint`)."""
    if checkpoint is None:
        return None
    from coadapt_core.io import checkpoint_path
    from coadapt_core.validation import is_run_id

    text = str(checkpoint)
    if text.strip().lower() == "none":
        fail(f"--checkpoint {text}: coadapt eval needs a policy; give {EVAL_CHECKPOINTS}")
    run_dir = next(
        (
            p
            for p in (checkpoint, Path("runs") / text)
            if (p / "config.yaml").is_file() and (p == checkpoint or is_run_id(text))
        ),
        None,
    )
    if run_dir is not None:  # a `coadapt run` folder: its final universal policy
        import yaml

        from coadapt_core.viz.video import run_checkpoint

        try:
            config = yaml.safe_load((run_dir / "config.yaml").read_text()) or {}
        except (OSError, yaml.YAMLError):
            config = {}
        found = run_checkpoint(run_dir, config if isinstance(config, dict) else {})
        if found is None:
            fail(
                f"--checkpoint {text}: run folder {run_dir} holds no policy (no "
                "checkpoints/backend-outer*.pt and no starting policy file); give "
                f"{EVAL_CHECKPOINTS}"
            )
        print(f"policy: {found} (the last of run {run_dir.name})", file=sys.stderr)
        return found
    try:
        return checkpoint_path(checkpoint, field="--checkpoint")
    except UserError as exc:
        fail(f"{exc}; or give {EVAL_CHECKPOINTS.split(', ', 2)[2]}")
