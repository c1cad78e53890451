"""`coadapt dashboard`: a live, read-only web view of the results store and the run folders
(`coadapt_core.dashboard`), on 127.0.0.1 unless another address is asked for."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import typer

from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import filled, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.settings import Int, setting, settings, shared

#: the address served unless --host says otherwise: this machine only
LOCAL = "127.0.0.1"


@settings
class DashboardCommand:
    """`coadapt dashboard`'s settings."""

    store: Any = shared(CommonOptions)
    runs: Path | None = setting(
        None,
        "Folder of run folders, looked in by run id (default: the folder each run's row names).",
    )
    port: Int = setting(8090, "Port to serve on (0: a free one, printed).", ge=0, le=65535)
    host: str = setting(
        LOCAL,
        "Address to serve on. Another than 127.0.0.1 lets other machines read the store: "
        "prefer an SSH tunnel (docs/dashboard.md).",
    )


def register(app: typer.Typer) -> None:
    options = options_of(DashboardCommand)

    def dashboard_command(**values: Any) -> None:
        """Serve a live, read-only web view of the runs, a run, a grid and a comparison."""
        import sqlalchemy as sa

        from coadapt_core.cli.common import fail
        from coadapt_core.dashboard.files import RunFolders
        from coadapt_core.dashboard.readonly import ReadOnlyStore
        from coadapt_core.dashboard.server import start

        o = filled(values, options)
        if o["runs"] is not None and not Path(o["runs"]).is_dir():
            fail(f"--runs {o['runs']}: no such folder; give the folder that holds the run folders")
        store = ReadOnlyStore(o["store"])
        server = start(store, RunFolders(o["runs"]), o["host"], o["port"])
        shown = sa.engine.make_url(store.url).render_as_string(hide_password=True)
        print(f"dashboard: {server.url} (store {shown}, read-only; Ctrl-C stops it)", flush=True)
        if not server.local_only:
            print(
                f"dashboard: serving on {o['host']}, not only this machine: anyone who reaches "
                "this port reads the store; an SSH tunnel to 127.0.0.1 is safer",
                file=sys.stderr,
                flush=True,
            )
        try:
            server.serve_forever(poll_interval=0.5)
        except KeyboardInterrupt:
            print("dashboard: stopped", file=sys.stderr)
        finally:
            server.server_close()
            store.close()

    register_command(app, "dashboard", dashboard_command, options)
