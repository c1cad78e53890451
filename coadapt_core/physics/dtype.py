"""`TorchDtype`: a class attribute holding a torch dtype by name, resolved when it is read.

`Simulator.dtype` is one (`torch.float64`), so that defining a simulator class, and listing
the simulator plugins (`coadapt plugins`), imports no torch (docs/architecture.md,
"Start-up"). Reading it, on the class or on an instance, gives the dtype itself, as a plain
class attribute would; a backend overrides it with a plain value (`dtype = torch.float32`)
or, to keep its own module free of torch, with `TorchDtype("float32")`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import torch


class TorchDtype:
    """The torch dtype `torch.<name>`, imported and looked up when the attribute is read."""

    def __init__(self, name: str):
        self.name = name

    def __get__(self, obj: object, owner: type | None = None) -> torch.dtype:
        import torch

        return getattr(torch, self.name)

    def __repr__(self) -> str:
        return f"TorchDtype({self.name!r})"
