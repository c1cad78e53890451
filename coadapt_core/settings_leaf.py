"""One setting of a settings tree (`coadapt_core.settings`), read: its YAML key, its
command-line option and parameter name, its kind of value, default, help and constraints, and
what it accepts in words. `coadapt_core.settings.leaves` walks a tree into these; the
command line (cli/options.py), the settings reference and the one-line errors of
a bad value read a setting through them."""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import TYPE_CHECKING, Annotated, Any, Literal

if TYPE_CHECKING:  # pydantic is loaded with the settings classes, not to read one
    from pydantic.fields import FieldInfo


def _unwrap(annotation: Any) -> tuple[Any, list[Any]]:
    """Annotated[Annotated[T, a], b] -> (T, [a, b])."""
    metadata: list[Any] = []
    while typing.get_origin(annotation) is Annotated:
        args = typing.get_args(annotation)
        annotation, metadata = args[0], [*args[1:], *metadata]
    return annotation, metadata


def strip_optional(annotation: Any) -> tuple[Any, bool]:
    """`T | None` -> (T, True); any other annotation -> (it, False)."""
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(args) == 1:
            return args[0], True
    return annotation, False


@dataclasses.dataclass(frozen=True)
class Leaf:
    """One setting of a settings tree: its key path, type, default, help and constraints."""

    path: tuple[str, ...]
    info: FieldInfo
    owner: type

    @property
    def key(self) -> str:
        """The dotted YAML key: `task.commands.yaw_range`."""
        return ".".join(self.path)

    @property
    def option(self) -> str:
        """The command-line option: `--task-commands-yaw-range`."""
        return "--" + "-".join(self.path).replace("_", "-")

    @property
    def param(self) -> str:
        """The Python parameter name of the option: `task_commands_yaw_range`."""
        return "_".join(self.path)

    @property
    def annotation(self) -> Any:
        return _unwrap(strip_optional(self.info.annotation)[0])[0]

    @property
    def metadata(self) -> list[Any]:
        return [*self.info.metadata, *_unwrap(strip_optional(self.info.annotation)[0])[1]]

    @property
    def optional(self) -> bool:
        return strip_optional(self.info.annotation)[1]

    @property
    def kind(self) -> str:
        """bool | int | float | str | choice | range | ints | weights | mapping."""
        ann = self.annotation
        if typing.get_origin(ann) is Literal:
            return "choice"
        if ann in (bool, int, float, str):
            return ann.__name__
        args = typing.get_args(ann)
        if typing.get_origin(ann) is tuple:
            return "ints" if args[-1] is Ellipsis else "range"
        if typing.get_origin(ann) is dict:
            return "weights" if args[1] is float else "mapping"
        return "str"

    @property
    def choices(self) -> tuple[Any, ...] | None:
        return typing.get_args(self.annotation) if self.kind == "choice" else None

    @property
    def help(self) -> str:
        return self.info.description or ""

    @property
    def extra(self) -> dict[str, Any]:
        return (
            dict(self.info.json_schema_extra or {})
            if isinstance(self.info.json_schema_extra, dict)
            else {}
        )

    @property
    def required(self) -> bool:
        """Declared without a default: the command cannot run without it."""
        return self.info.is_required()

    @property
    def default(self) -> Any:
        if self.info.default_factory is not None:
            return self.info.default_factory()
        return (
            None if self.info.default is dataclasses.MISSING or self.required else self.info.default
        )

    def bounds(self) -> dict[str, float]:
        out: dict[str, float] = {}
        for item in self.metadata:
            for name in ("ge", "gt", "le", "lt"):
                value = getattr(item, name, None)
                if value is not None:
                    out[name] = value
        return out

    def accepted(self) -> str:
        """What the setting accepts, in words: 'an integer >= 1', 'one of a, b'."""
        if self.extra.get("accepted"):
            return str(self.extra["accepted"])
        kind = self.kind
        if kind == "choice":
            return "one of " + ", ".join(str(c) for c in self.choices or ())
        words = {
            "bool": "true or false",
            "int": "an integer",
            "float": "a finite number",
            "str": "text",
            "range": "a range low:high",
            "ints": "comma-separated integers",
            "weights": "name=number pairs, comma-separated",
            "mapping": "a mapping of names to values",
        }[kind]
        b = self.bounds()
        low = ("ge", b["ge"]) if "ge" in b else ("gt", b["gt"]) if "gt" in b else None
        high = ("le", b["le"]) if "le" in b else ("lt", b["lt"]) if "lt" in b else None
        if low and high:
            opening, closing = "[" if low[0] == "ge" else "(", "]" if high[0] == "le" else ")"
            words += f" in {opening}{low[1]:g}, {high[1]:g}{closing}"
        elif low:
            words += f" {'>=' if low[0] == 'ge' else '>'} {low[1]:g}"
        elif high:
            words += f" {'<=' if high[0] == 'le' else '<'} {high[1]:g}"
        validators = {getattr(getattr(m, "func", None), "__name__", "") for m in self.metadata}
        if "_positive" in validators:
            words += " of positive numbers"
        elif "_nonnegative" in validators:
            words += " of numbers >= 0"
        return words
