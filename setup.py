"""Package discovery only: the folder `plugins/` is installed as the package `coadapt_plugins`
(design.md section 2), which pyproject.toml alone cannot express for every sub-package."""

from setuptools import find_packages, setup

plugin_packages = ["coadapt_plugins"] + [
    f"coadapt_plugins.{name}" for name in find_packages("plugins")
]
setup(
    packages=find_packages(include=["coadapt_core", "coadapt_core.*"]) + plugin_packages,
    package_dir={"coadapt_plugins": "plugins"},
)
