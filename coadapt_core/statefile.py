"""Files that coadapt writes and reads back, as data only: JSON plus numeric arrays.

Nothing read back from a run folder, a checkpoint or a store is ever unpickled: a pickle (or
`torch.load(weights_only=False)`) runs whatever code its author planted, and run folders
are shared between people and machines. This module turns a tree of plain values and
arrays into JSON (`encode`/`decode`) and writes it atomically:

- dicts with string keys, lists, tuples, str, int, float (NaN and infinities kept), bool and
  None as themselves;
- numpy arrays and torch tensors of numeric dtypes as {dtype, shape, bytes} (base64 inline,
  or a named member of an `.npz` for large ones); object arrays are refused;
- dataclasses only when their class was registered with `register_dataclass` (by name; the
  class is looked up in the registry, never imported from the file).

`write_json`/`write_npz` write to a temporary file in the same folder and rename it, so a
kill or a full disk leaves the previous file and no partial one; a full disk is one line
(`UserError`) naming the file. `read_json`/`read_npz` raise `StateFileError` (one line,
naming the file and how to recover) for a damaged file.
"""

from __future__ import annotations

import base64
import dataclasses
import io
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core.errors import UserError
from coadapt_core.io import write_atomic

_NUMERIC_KINDS = "biufc"
_DATACLASSES: dict[str, type] = {}


class StateFileError(UserError):
    """A file coadapt wrote earlier is damaged or not one of its files."""


def register_dataclass(cls: type) -> type:
    """Allow instances of dataclass `cls` in encoded state (e.g. a backend's evaluation
    buffer). Usable as a decorator; returns `cls`."""
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"{cls!r} is not a dataclass")
    _DATACLASSES[f"{cls.__module__}:{cls.__qualname__}"] = cls
    return cls


def _array_header(a: np.ndarray) -> dict:
    if a.dtype.kind not in _NUMERIC_KINDS:
        raise TypeError(f"cannot store an array of dtype {a.dtype} (numeric arrays only)")
    return {"dtype": a.dtype.str, "shape": list(a.shape)}


def encode(obj: Any, arrays: dict[str, np.ndarray] | None = None) -> Any:
    """A JSON-able tree for `obj`. With `arrays`, arrays go there (by key) instead of inline."""
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (int, np.integer)) and not isinstance(obj, bool):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, dict):
        if all(isinstance(k, str) for k in obj):
            if any(k.startswith("__") and k.endswith("__") for k in obj):
                return {"__dict__": [[k, encode(v, arrays)] for k, v in obj.items()]}
            return {k: encode(v, arrays) for k, v in obj.items()}
        return {"__dict__": [[encode(k, arrays), encode(v, arrays)] for k, v in obj.items()]}
    if isinstance(obj, list):
        return [encode(v, arrays) for v in obj]
    if isinstance(obj, tuple):
        return {"__tuple__": [encode(v, arrays) for v in obj]}
    torch = _torch_if_loaded()
    if torch is not None and isinstance(obj, torch.Tensor):
        out = _encode_array(obj.detach().cpu().numpy(), arrays)
        out["torch"] = True
        return {"__array__": out}
    if isinstance(obj, np.ndarray):
        return {"__array__": _encode_array(obj, arrays)}
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        key = f"{type(obj).__module__}:{type(obj).__qualname__}"
        if key not in _DATACLASSES:
            raise TypeError(
                f"dataclass {key} is not registered for state files (statefile.register_dataclass)"
            )
        fields = {f.name: encode(getattr(obj, f.name), arrays) for f in dataclasses.fields(obj)}
        return {"__dataclass__": key, "fields": fields}
    raise TypeError(f"cannot store a value of type {type(obj).__name__} in a state file")


def _encode_array(a: np.ndarray, arrays: dict[str, np.ndarray] | None) -> dict:
    a = np.ascontiguousarray(a)
    head = _array_header(a)
    if arrays is None:
        head["base64"] = base64.b64encode(a.tobytes()).decode("ascii")
    else:
        key = f"a{len(arrays)}"
        arrays[key] = a
        head["key"] = key
    return head


def _torch_if_loaded():
    import sys

    return sys.modules.get("torch")


def decode(tree: Any, arrays: Any = None) -> Any:
    """The value `encode` was given (tuples, arrays, tensors and registered dataclasses
    rebuilt). Raises ValueError on anything that is not a tree `encode` writes."""
    if tree is None or isinstance(tree, (bool, str, int, float)):
        return tree
    if isinstance(tree, list):
        return [decode(v, arrays) for v in tree]
    if not isinstance(tree, dict):
        raise ValueError(f"unexpected value of type {type(tree).__name__}")
    if "__tuple__" in tree:
        return tuple(decode(v, arrays) for v in tree["__tuple__"])
    if "__dict__" in tree:
        return {decode(k, arrays): decode(v, arrays) for k, v in tree["__dict__"]}
    if "__array__" in tree:
        return _decode_array(tree["__array__"], arrays)
    if "__dataclass__" in tree:
        key = str(tree["__dataclass__"])
        module = key.partition(":")[0]
        if (
            key not in _DATACLASSES
            and module.startswith("coadapt_core.")
            and module.replace(".", "").replace("_", "").isalnum()
        ):
            import importlib

            importlib.import_module(module)  # a core module registers its classes on import
        cls = _DATACLASSES.get(key)
        if cls is None:
            raise ValueError(f"unknown stored type '{tree['__dataclass__']}'")
        return cls(**{str(k): decode(v, arrays) for k, v in dict(tree["fields"]).items()})
    return {k: decode(v, arrays) for k, v in tree.items()}


def _decode_array(head: dict, arrays: Any) -> Any:
    dtype = np.dtype(str(head["dtype"]))
    if dtype.kind not in _NUMERIC_KINDS:
        raise ValueError(f"array of dtype {dtype} refused (numeric arrays only)")
    shape = tuple(int(n) for n in head["shape"])
    if "base64" in head:
        a = np.frombuffer(base64.b64decode(head["base64"]), dtype=dtype).reshape(shape).copy()
    else:
        if arrays is None:
            raise ValueError("array stored outside the file but no arrays were given")
        a = np.asarray(arrays[str(head["key"])])
        if a.dtype != dtype or a.shape != shape:
            raise ValueError("stored array does not match its description")
    if head.get("torch"):
        import torch

        return torch.from_numpy(a)
    return a


# -- atomic files ---------------------------------------------------------------------------
def dumps(obj: Any) -> bytes:
    return json.dumps(encode(obj), separators=(",", ":")).encode("utf-8")


def write_json(path: str | os.PathLike, obj: Any) -> Path:
    """`obj` encoded (arrays inline) as JSON, atomically."""
    return write_atomic(path, dumps(obj))


def write_npz(path: str | os.PathLike, obj: Any) -> Path:
    """`obj` as an `.npz`: its arrays as members, the rest as a JSON member `__tree__`.
    Read back with `np.load(allow_pickle=False)` only."""
    arrays: dict[str, np.ndarray] = {}
    tree = encode(obj, arrays)
    buf = io.BytesIO()
    np.savez(
        buf, __tree__=np.frombuffer(json.dumps(tree).encode("utf-8"), dtype=np.uint8), **arrays
    )
    return write_atomic(path, buf.getvalue())


def read_json(path: str | os.PathLike, *, what: str = "state file", recover: str = "") -> Any:
    path = Path(path)
    try:
        with open(path, "rb") as f:
            return decode(json.loads(f.read().decode("utf-8")))
    except OSError as exc:
        raise StateFileError(
            f"{what} '{path}' cannot be read ({exc.strerror or type(exc).__name__}){recover}",
            field="resume",
        ) from None
    except (ValueError, TypeError, KeyError, UnicodeDecodeError) as exc:
        raise StateFileError(
            f"{what} '{path}' is damaged ({_short(exc)}){recover}", field="resume"
        ) from None


def read_npz(path: str | os.PathLike, *, what: str = "state file", recover: str = "") -> Any:
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        tree = json.loads(arrays.pop("__tree__").tobytes().decode("utf-8"))
        return decode(tree, arrays)
    except OSError as exc:
        raise StateFileError(
            f"{what} '{path}' cannot be read ({exc.strerror or type(exc).__name__}){recover}",
            field="resume",
        ) from None
    except Exception as exc:  # zip, npy and JSON parsers raise many kinds; all mean damaged
        raise StateFileError(
            f"{what} '{path}' is damaged ({_short(exc)}){recover}", field="resume"
        ) from None


def _short(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:80]}" if text else type(exc).__name__
