"""Shared fixtures: the example third-party plugin installed into a private folder."""

from __future__ import annotations

import atexit
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE_PLUGIN = ROOT / "tests" / "example_plugin"

# The suite never sees the spec robots of whoever runs it: `coadapt robot new` writes them to
# ~/.coadapt/robots (or COADAPT_ROBOT_PATH), which every process would register beside the
# built-in ones (a trial robot there failed five tests). Tests that want spec robots set the
# variable themselves; the rest, and their subprocesses, find an empty folder.
os.environ["COADAPT_ROBOT_PATH"] = tempfile.mkdtemp(prefix="coadapt-test-robots-")
atexit.register(shutil.rmtree, os.environ["COADAPT_ROBOT_PATH"], True)


@pytest.fixture(scope="session")
def example_plugin_site(tmp_path_factory) -> Path:
    """`pip install` the example plugin into a folder of its own (not the environment), so
    tests can put it on PYTHONPATH for a subprocess, exactly as an installed plugin."""
    site = tmp_path_factory.mktemp("example_site")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "-q",
            "--no-deps",
            "--no-build-isolation",
            "--disable-pip-version-check",
            "--target",
            str(site),
            str(EXAMPLE_PLUGIN),
        ],
        check=True,
        capture_output=True,
    )
    return site


def run_cli(
    *args: str, pythonpath: list[Path] | None = None, env: dict | None = None, timeout: float = 120
) -> subprocess.CompletedProcess:
    """Run `coadapt ARGS` in a fresh interpreter (fresh entry-point discovery)."""
    full_env = dict(os.environ)
    full_env.pop("COADAPT_LOAD_PLUGINS", None)
    if pythonpath:
        full_env["PYTHONPATH"] = os.pathsep.join(str(p) for p in pythonpath)
    full_env.update(env or {})
    return subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from coadapt_core.cli import main; sys.exit(main(sys.argv[1:]))",
            *args,
        ],
        capture_output=True,
        text=True,
        env=full_env,
        timeout=timeout,
    )


def make_dist(
    site: Path, name: str, entry_points: str, modules: dict[str, str] | None = None
) -> Path:
    """Create a minimal installed distribution (dist-info + modules) in `site`."""
    site.mkdir(parents=True, exist_ok=True)
    info = site / f"{name.replace('-', '_')}-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(entry_points)
    for module, source in (modules or {}).items():
        (site / f"{module}.py").write_text(source)
    return site
