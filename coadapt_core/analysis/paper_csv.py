"""The columns of the comparison's CSV files (paper_table6.csv, paper_order.csv,
paper_table7.csv, paper_table9.csv) and their writing: one row per comparison row."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path
from typing import Any

#: the common yardstick (coadapt_core.experiments.yardstick): every run's best design and its
#: nominal design with the run's own policy on one common scenario set, under the run's rule
#: and the plain mean, with the paired fall-rate difference
COMMON_COLUMNS = (
    "common_improvement",
    "common_improvement_se",
    "common_improvement_verdict",
    "common_improvement_plain",
    "common_improvement_plain_se",
    "common_improvement_plain_verdict",
    "common_fall_rate_difference",
    "common_fall_rate_difference_se",
)
#: the objective's own measure beside the paper's (1 - c / c0), where the two differ (tracking)
OWN_COLUMNS = (
    "measure_differs",
    "improvement_own",
    "improvement_own_se",
    "improvement_plain_own",
    "improvement_plain_own_se",
    "common_improvement_own",
    "common_improvement_own_se",
    "common_improvement_plain_own",
    "common_improvement_plain_own_se",
)
#: a Table 6 or Table 9 cell: which runs, and their design beside the paper's
CELL_COLUMNS = (
    "objective",
    "method",
    "optimizer",
    "terrain",
    "runs",
    "seeds",
    "thigh",
    "thigh_se",
    "paper_thigh",
    "shank",
    "shank_se",
    "paper_shank",
    "direction",
)
#: an improvement beside the paper's: the run's cost rule, the plain mean, the common yardstick
IMPROVEMENT_COLUMNS = (
    "improvement",
    "improvement_se",
    "paper_improvement",
    "improvement_verdict",
    "improvement_plain",
    "improvement_plain_se",
    "improvement_plain_verdict",
    *COMMON_COLUMNS,
)
T6_COLUMNS = (
    *CELL_COLUMNS,
    *IMPROVEMENT_COLUMNS,
    "sim2sim_improvement",
    "sim2sim_improvement_se",
    "paper_sim2sim_improvement",
    "sim2sim_verdict",
    *OWN_COLUMNS,
    "sim2sim_improvement_own",
)
ORDER_COLUMNS = (
    "objective",
    "terrain",
    "measure",
    "methods",
    "paper_order",
    "our_order",
    "pairs",
    "reversed",
    "clear_reversals",
    "verdict",
)
T7_COLUMNS = (
    "method",
    "optimizer",
    "runs",
    "pairs",
    "interactions_training",
    "interactions_evaluation",
    "seconds_training",
    "seconds_evaluation",
    "interactions_ratio",
    "interactions_ratio_se",
    "paper_interactions_ratio",
    "interactions_verdict",
    "evaluation_ratio",
    "evaluation_ratio_se",
    "paper_evaluation_ratio",
    "time_pairs",
    "time_ratio",
    "time_ratio_se",
    "paper_time_ratio",
    "time_verdict",
    "speed_time_ratio",
    "speed_time_ratio_se",
    "speed_time_verdict",
    "paper_interactions_training",
    "paper_interactions_evaluation",
    "paper_hours_training",
    "paper_hours_evaluation",
)
T9_COLUMNS = (
    *CELL_COLUMNS,
    "hip_motor",
    "paper_hip_motor",
    "hip_motor_verdict",
    "knee_motor",
    "paper_knee_motor",
    "knee_motor_verdict",
    *IMPROVEMENT_COLUMNS,
    *OWN_COLUMNS,
)


def write_columns(path: Path, columns: Sequence[str], rows: Sequence[dict[str, Any]]) -> None:
    """`rows` into the CSV file `path` under `columns`: a float in full (its repr), a missing
    value as an empty cell."""
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(columns))
        writer.writeheader()
        for r in rows:
            writer.writerow(
                {
                    k: ("" if r.get(k) is None else repr(r[k]) if isinstance(r[k], float) else r[k])
                    for k in columns
                }
            )
