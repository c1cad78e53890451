"""coadapt's built-in plugins (installed as the package `coadapt_plugins`). Each is found
through the `coadapt` entry-point group, exactly as a third-party plugin would be."""
