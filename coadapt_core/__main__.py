"""`python -m coadapt_core ...` runs the `coadapt` command (for machines where the console
script is not on PATH, e.g. packages installed with `pip install --target`)."""

from coadapt_core.launch import entry

entry()
