"""The grid's bookkeeping in the store: a grid's spec and, per cell, its status, run and
attempts (`coadapt grid` resumes from these). Mixed into `ResultsStore`, whose engine it
uses; a cell's key is `coadapt_core.experiments.cell.Cell.key`."""

from __future__ import annotations

import time
from typing import Any

import sqlalchemy as sa

from coadapt_core.results.rows import dumps, loads
from coadapt_core.results.schema import grid_cells, grids


class GridCells:
    """Grid specs and cell statuses (pending | running | finished | failed | skipped)."""

    engine: sa.Engine

    def save_grid(self, grid_id: str, spec: dict[str, Any]) -> None:
        now = time.time()
        with self.engine.begin() as conn:
            if conn.execute(sa.select(grids.c.id).where(grids.c.id == grid_id)).first() is None:
                conn.execute(
                    grids.insert().values(
                        id=grid_id, spec=dumps(spec), created_at=now, updated_at=now
                    )
                )
            else:
                conn.execute(
                    grids.update()
                    .where(grids.c.id == grid_id)
                    .values(spec=dumps(spec), updated_at=now)
                )

    def get_grid(self, grid_id: str) -> dict[str, Any] | None:
        with self.engine.connect() as conn:
            row = conn.execute(sa.select(grids).where(grids.c.id == grid_id)).mappings().first()
        return (
            None
            if row is None
            else {"id": row["id"], "spec": loads(row["spec"]), "created_at": row["created_at"]}
        )

    def list_grids(self) -> list[str]:
        with self.engine.connect() as conn:
            return [r[0] for r in conn.execute(sa.select(grids.c.id).order_by(grids.c.created_at))]

    def set_cell(
        self,
        grid_id: str,
        cell: str,
        *,
        status: str,
        run_id: str | None = None,
        error: str | None = None,
        attempt: bool = False,
    ) -> None:
        now = time.time()
        with self.engine.begin() as conn:
            row = (
                conn.execute(
                    sa.select(grid_cells).where(
                        (grid_cells.c.grid_id == grid_id) & (grid_cells.c.cell == cell)
                    )
                )
                .mappings()
                .first()
            )
            if row is None:
                conn.execute(
                    grid_cells.insert().values(
                        grid_id=grid_id,
                        cell=cell,
                        run_id=run_id,
                        status=status,
                        attempts=int(attempt),
                        last_error=error,
                        updated_at=now,
                    )
                )
            else:
                values: dict[str, Any] = {"status": status, "updated_at": now, "last_error": error}
                if run_id is not None:
                    values["run_id"] = run_id
                if attempt:
                    values["attempts"] = row["attempts"] + 1
                conn.execute(
                    grid_cells.update()
                    .where((grid_cells.c.grid_id == grid_id) & (grid_cells.c.cell == cell))
                    .values(**values)
                )

    def cells(self, grid_id: str) -> dict[str, dict[str, Any]]:
        with self.engine.connect() as conn:
            rows = conn.execute(
                sa.select(grid_cells).where(grid_cells.c.grid_id == grid_id)
            ).mappings()
            return {r["cell"]: dict(r) for r in rows}
