"""Plugin discovery and the registry of robots, simulators, optimizers and objectives.

Every plugin — coadapt's own built-ins included — is a module named by an entry point in
the `coadapt` group, implementing one or more `coadapt_register_*` hooks. Entry points are
loaded one by one so a plugin that fails to import is reported by name while the others
load; two classes claiming one `name` within a kind is an error naming both distributions.

`COADAPT_LOAD_PLUGINS` (comma-separated distribution or entry-point names) restricts which
third-party plugins load; set but empty means built-ins only.
"""

from __future__ import annotations

import importlib
import os
import threading
from dataclasses import dataclass
from importlib import metadata
from types import ModuleType
from typing import Any

import pluggy

from coadapt_core import hookspecs
from coadapt_core.errors import PluginError, UnknownPluginError, UserError
from coadapt_core.options import check_specs
from coadapt_core.plugin_api import api_problem, declared_api

ENTRY_POINT_GROUP = "coadapt"
BUILTIN_DISTRIBUTION = "coadapt"
ENV_LOAD_PLUGINS = "COADAPT_LOAD_PLUGINS"

#: kind -> (hook name, base class import path)
KINDS: dict[str, tuple[str, str]] = {
    "robot": ("coadapt_register_robots", "coadapt_core.robot:Robot"),
    "simulator": ("coadapt_register_simulators", "coadapt_core.physics.simulator:Simulator"),
    "optimizer": ("coadapt_register_optimizers", "coadapt_core.optimizer:Optimizer"),
    "objective": ("coadapt_register_objectives", "coadapt_core.objective:Objective"),
}


def _base_class(kind: str) -> type:
    module, _, attr = KINDS[kind][1].partition(":")
    return getattr(importlib.import_module(module), attr)


@dataclass
class PluginInfo:
    """Where one registered class came from."""

    kind: str
    name: str
    cls: type
    distribution: str
    #: the distribution's version (`version` unless the class declares its own)
    release: str
    entry_point: str
    #: the plugin API version the class declares it was written for (None: undeclared)
    api: str | None = None

    @property
    def version(self) -> str:
        """The class's own `plugin_version` where it declares one as text (e.g. a data file's
        digest, which a class may read when first asked), else its distribution's version."""
        own = getattr(self.cls, "plugin_version", None)
        return own if isinstance(own, str) else self.release

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "kind": self.kind,
            "name": self.name,
            "class": f"{self.cls.__module__}.{self.cls.__qualname__}",
            "distribution": self.distribution,
            "version": self.version,
            "entry_point": self.entry_point,
            "plugin_api": self.api,
        }
        specs = getattr(self.cls, "option_specs", None)
        if specs is not None:  # optimizers and objectives: the options they declare
            out["options"] = [spec.to_dict() for spec in specs]
        return out


@dataclass
class BrokenPlugin:
    entry_point: str
    distribution: str
    error: str
    #: the (kind, name) of a class refused for the plugin API version it declares (or not)
    refused: tuple[str, str] | None = None

    def line(self) -> str:
        where = f"plugin '{self.entry_point}' (distribution {self.distribution})"
        return f"{where} failed to load: {self.error}"


#: one plugin module to ask for classes: (plugin, distribution, version, entry-point name)
Source = tuple[object, str, str, str]


class Registry:
    """`{kind: {name: PluginInfo}}` plus the plugins that failed to load.

    A registry made by `load_registry(lazy=True)` (the process-wide one, `get_registry`) has
    imported every plugin module but calls a kind's `coadapt_register_*` hooks only when that
    kind is first asked for: naming the simulators imports no robot's module and reads no
    robot's data file. `entries`, `broken` and `all()` load every kind first, so they are
    complete whenever read; a kind's names, default and classes load that kind alone.
    """

    def __init__(
        self,
        entries: dict[str, dict[str, PluginInfo]] | None = None,
        broken: list[BrokenPlugin] | None = None,
        manager: pluggy.PluginManager | None = None,
    ):
        self._entries = {k: {} for k in KINDS} if entries is None else entries
        self._broken = list(broken or [])
        self.manager = manager
        self._sources: list[Source] = []  # the plugins whose hooks give the classes
        self._pending: list[str] = []  # the kinds whose hooks are not asked yet
        self._loading: set[str] = set()  # the kinds whose hooks are being asked
        self._lock = threading.RLock()  # threads (a grid's cells) ask a kind once

    @property
    def entries(self) -> dict[str, dict[str, PluginInfo]]:
        self.load_all()
        return self._entries

    @property
    def broken(self) -> list[BrokenPlugin]:
        self.load_all()
        return self._broken

    def load_all(self) -> Registry:
        """Every kind's classes registered (a plugin's module imported by its hook may
        register what it saves, e.g. `statefile.register_dataclass`)."""
        for kind in list(self._pending):
            self._of(kind)
        return self

    def _of(self, kind: str) -> dict[str, PluginInfo]:
        """`kind`'s classes, asked of every plugin's hook the first time; a name claimed twice
        (`PluginError`) leaves the kind unloaded, so the next use says so again."""
        if kind in self._pending:
            with self._lock:
                if kind in self._pending and kind not in self._loading:  # (a hook asking it)
                    self._loading.add(kind)
                    known = len(self._broken)
                    try:
                        for source in self._sources:
                            _register_classes(self, kind, *source)
                    except PluginError:
                        self._entries[kind], self._broken[known:] = {}, []
                        raise
                    finally:
                        self._loading.discard(kind)
                    self._pending.remove(kind)
        return self._entries[kind]

    def names(self, kind: str) -> list[str]:
        return sorted(self._of(kind))

    def get(self, kind: str, name: str) -> type:
        """The class registered as `name` for `kind`; `UnknownPluginError` (a user error,
        listing what is available and every plugin that failed to load, with its error)
        otherwise (the plugins that failed to import, and the classes refused so far: those of
        `kind` among them)."""
        try:
            return self._of(kind)[name].cls
        except KeyError:
            refused = [b.line() for b in self._broken if b.refused == (kind, name)]
            # written for another plugin API: that line alone says what to do
            raise UnknownPluginError(
                kind,
                name,
                self.names(kind),
                [b.line() for b in self._broken],
                reason=refused[0] if refused else None,
            ) from None

    def default(self, kind: str, exclude: tuple[str, ...] = ()) -> str:
        """The name a command takes for `kind` when none is given: the registered class with
        the highest `default_rank` class attribute (0 when it declares none); ties go to the
        name first in alphabetical order, so the choice never depends on load order. `exclude`
        leaves names out (a second simulator: exclude the default one). A kind with nothing
        left is the registry's one-line `UnknownPluginError`."""
        infos = [i for i in self._of(kind).values() if i.name not in exclude]
        if not infos:
            raise UnknownPluginError(kind, "(default)", [], [b.line() for b in self._broken])
        return min(infos, key=lambda i: (-int(getattr(i.cls, "default_rank", 0)), i.name)).name

    def defaults(self, kind: str) -> list[str]:
        """The names a command takes for `kind` when it takes several and none is given (the
        objectives of a grid): every registered class with a positive `default_rank`, lowest
        rank first, so the default of the kind (`default`) comes last; ties by name. A kind
        where none declares a rank gives its default alone."""
        ranked = [i for i in self._of(kind).values() if int(getattr(i.cls, "default_rank", 0)) > 0]
        if not ranked:
            return [self.default(kind)]
        return [
            i.name
            for i in sorted(ranked, key=lambda i: (int(getattr(i.cls, "default_rank", 0)), i.name))
        ]

    def create(self, kind: str, name: str, *args: Any, **kwargs: Any) -> Any:
        return self.get(kind, name)(*args, **kwargs)

    def all(self) -> list[PluginInfo]:
        return [
            info for kind in KINDS for info in sorted(self._of(kind).values(), key=lambda i: i.name)
        ]


def _allowed(ep: metadata.EntryPoint, distribution: str) -> bool:
    """Built-ins always load; third-party ones only when listed (if the variable is set)."""
    if distribution == BUILTIN_DISTRIBUTION:
        return True
    raw = os.environ.get(ENV_LOAD_PLUGINS)
    if raw is None:
        return True
    wanted = {w.strip() for w in raw.split(",") if w.strip()}
    return distribution in wanted or ep.name in wanted


def _distribution_of(ep: metadata.EntryPoint, read: dict[int, tuple[str, str]]) -> tuple[str, str]:
    """(name, version) of the distribution declaring `ep`, its metadata file parsed once per
    distribution (`read`: by the distribution object, which its entry points share)."""
    dist = getattr(ep, "dist", None)
    if dist is None:
        return "unknown", "unknown"
    if id(dist) not in read:
        found = dist.metadata
        read[id(dist)] = (found["Name"], found["Version"])
    return read[id(dist)]


def _entry_point_plugins(registry: Registry) -> list[Source]:
    """The plugin modules the entry points name, loaded one by one (allowed ones only, each
    distribution once), as (plugin, distribution, version, entry-point name); one that fails
    to import is recorded in the registry's broken plugins, the others load."""
    sources: list[Source] = []
    seen: set[tuple[str, str]] = set()
    read: dict[int, tuple[str, str]] = {}
    entry_points = list(metadata.entry_points(group=ENTRY_POINT_GROUP))  # alive: ids stay
    for ep in entry_points:
        dist, version = _distribution_of(ep, read)
        if (dist, ep.name) in seen:  # the same distribution visible twice on sys.path
            continue
        seen.add((dist, ep.name))
        if not _allowed(ep, dist):
            continue
        try:
            plugin = ep.load()
        except Exception as exc:  # a broken plugin must not take the others down
            registry._broken.append(BrokenPlugin(ep.name, dist, f"{type(exc).__name__}: {exc}"))
            continue
        sources.append((plugin, dist, version, ep.name))
    return sources


def _refusal(kind: str, cls: Any, plugin: object) -> tuple[str, bool] | None:
    """Why a class a `coadapt_register_*` hook returned cannot be registered as a `kind`
    (with whether it was refused for the plugin API version it declares), or None."""
    hook_name, base = KINDS[kind][0], _base_class(kind)
    if not (isinstance(cls, type) and issubclass(cls, base)):
        return f"{hook_name} returned {cls!r}, not a {base.__name__} subclass", False
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not name:
        return f"{cls.__qualname__} has no `name`", False
    unavailable = getattr(cls, "unavailable", None)  # e.g. a robot whose data file is broken
    if isinstance(unavailable, str) and unavailable:
        return unavailable, True
    problem = api_problem(declared_api(cls, plugin))  # the API version it was written for
    if problem is not None:
        return f"{kind} '{name}' {problem}", True
    try:  # declared options must be well formed before anyone passes values to them
        check_specs(getattr(cls, "option_specs", ()), f"{kind} '{name}'")
    except (TypeError, UserError) as exc:
        return str(exc), False
    return None


def _gives_way(
    registry: Registry, kind: str, existing: PluginInfo, cls: type, dist: str, ep_name: str
) -> bool:
    """A name claimed twice: a class declaring `yields_name = True` (a robot found in a
    user's folder) gives way in one broken line, the new one (True: skip it) or the one
    registered before; otherwise `PluginError` naming both distributions."""
    if getattr(cls, "yields_name", False):
        line = f"{kind} name '{cls.name}' is taken by {existing.distribution}'s; rename this one"
        registry._broken.append(BrokenPlugin(ep_name, dist, line))
        return True
    if getattr(existing.cls, "yields_name", False):
        line = f"{kind} name '{cls.name}' is taken by {dist}'s; rename this one"
        registry._broken.append(BrokenPlugin(existing.entry_point, existing.distribution, line))
        return False
    raise PluginError(
        f"{kind} name '{cls.name}' is claimed twice: by {existing.cls.__qualname__} "
        f"from distribution {existing.distribution} and by {cls.__qualname__} from "
        f"distribution {dist}; uninstall one or restrict {ENV_LOAD_PLUGINS}"
    )


def _register_classes(
    registry: Registry, kind: str, plugin: object, dist: str, version: str, ep_name: str
) -> None:
    """The classes of `kind` that `plugin`'s hook returns, checked (`_refusal`) and entered in
    `registry`; `PluginError` when a name of the kind is claimed twice."""
    hook_name = KINDS[kind][0]
    impl = getattr(plugin, hook_name, None)
    if impl is None:
        return
    try:
        classes = impl() or []
    except Exception as exc:
        error = f"{hook_name} raised {type(exc).__name__}: {exc}"
        registry._broken.append(BrokenPlugin(ep_name, dist, error))
        return
    for cls in classes:
        refused = _refusal(kind, cls, plugin)
        if refused is not None:
            error, for_api = refused
            claim = (kind, cls.name) if for_api else None
            registry._broken.append(BrokenPlugin(ep_name, dist, error, claim))
            continue
        existing = registry._entries[kind].get(cls.name)
        clash = existing is not None and existing.cls is not cls
        if clash and _gives_way(registry, kind, existing, cls, dist, ep_name):
            continue
        api = declared_api(cls, plugin)  # the version is the class's own when it has one
        registry._entries[kind][cls.name] = PluginInfo(
            kind, cls.name, cls, dist, version, ep_name, api
        )


def load_registry(
    extra_plugins: list[tuple[ModuleType | object, str]] | None = None, *, lazy: bool = False
) -> Registry:
    """Discover plugins from entry points (and `extra_plugins`: (module-or-object,
    distribution) pairs, for tests) and build a fresh registry.

    Raises `PluginError` when two plugins claim the same name for one kind. `lazy`: every
    plugin module is imported here, each kind's hooks are called when the kind is first
    used (`Registry`), which is where a name claimed twice is raised then.
    """
    pm = pluggy.PluginManager("coadapt")
    pm.add_hookspecs(hookspecs)
    registry = Registry(manager=pm)
    sources = _entry_point_plugins(registry)
    for plugin, dist in extra_plugins or []:
        sources.append((plugin, dist, "test", getattr(plugin, "__name__", repr(plugin))))
    for plugin, dist, version, ep_name in sources:
        try:
            pm.register(plugin, name=f"{dist}:{ep_name}")
        except ValueError as exc:
            registry._broken.append(BrokenPlugin(ep_name, dist, str(exc)))
            continue
        registry._sources.append((plugin, dist, version, ep_name))
    pm.check_pending()
    registry._pending = list(KINDS)
    return registry if lazy else registry.load_all()


_REGISTRY: Registry | None = None


def default_plugin(kind: str) -> str:
    """`get_registry().default(kind)`: the plugin a command takes when none is named."""
    return get_registry().default(kind)


def get_registry(refresh: bool = False) -> Registry:
    """The process-wide registry, built on first use; each kind's classes are registered when
    the kind is first used (`load_registry(lazy=True)`)."""
    global _REGISTRY
    if _REGISTRY is None or refresh:
        _REGISTRY = load_registry(lazy=True)
    return _REGISTRY
