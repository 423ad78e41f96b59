"""TOML files into frozen dataclass trees: typed, unknown keys rejected, errors naming file and key.

One loader for every configuration file of the product (the job file, the cell configuration), so
that each is validated the same way at load time and nothing downstream sees a raw dict. Supported
field types: ``bool``, ``int``, ``float`` (ints accepted), ``str``, ``tuple[float, ...]`` and
fixed-length ``tuple[float, float, float]``, ``list[Dataclass]``, nested dataclasses, and
``X | None``. A field's ``metadata["help"]`` is used in error messages when present.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, TypeVar

from controller.errors import ConfigError

T = TypeVar("T")


def _fail(path: str, key: str, what: str) -> ConfigError:
    return ConfigError(f"{path}: {key}: {what}", file=path, key=key)


def _convert(tp: Any, value: Any, path: str, key: str) -> Any:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        return _convert(inner[0], value, path, key)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise _fail(path, key, f"must be a table, got {type(value).__name__}")
        return from_dict(typing.cast(type, tp), value, path, key)
    if origin is list:
        if not isinstance(value, list):
            raise _fail(path, key, f"must be a list, got {type(value).__name__}")
        return [_convert(args[0], v, path, f"{key}[{i}]") for i, v in enumerate(value)]
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise _fail(path, key, f"must be a list of numbers, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, path, f"{key}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise _fail(path, key, f"must be {len(args)} values, got {len(value)}: {value!r}")
        return tuple(_convert(a, v, path, f"{key}[{i}]")
                     for i, (a, v) in enumerate(zip(args, value, strict=True)))
    if tp is bool:
        if not isinstance(value, bool):
            raise _fail(path, key, f"must be true or false, got {value!r}")
        return value
    if tp is int:
        if not isinstance(value, int) or isinstance(value, bool):
            raise _fail(path, key, f"must be a whole number, got {value!r}")
        return value
    if tp is float:
        if not isinstance(value, int | float) or isinstance(value, bool) \
                or not math.isfinite(value):
            raise _fail(path, key, f"must be a finite number, got {value!r}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise _fail(path, key, f"must be a string, got {value!r}")
        return value
    raise _fail(path, key, f"unsupported field type {tp!r}")  # a programming error


def from_dict(cls: type[T], data: dict[str, Any], path: str = "<config>", prefix: str = "") -> T:
    """Build dataclass ``cls`` from ``data``; :class:`ConfigError` names ``path`` and the key.

    Missing keys take the field default; a missing key without default and any unknown key are
    errors. ``__post_init__`` validation errors (ConfigError) are re-raised with the key prefix.
    """
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(data) - set(fields))
    if unknown:
        where = f"{prefix}.{unknown[0]}" if prefix else unknown[0]
        raise _fail(path, where, f"unknown key; known keys here: {', '.join(sorted(fields))}")
    kwargs = {}
    for name, f in fields.items():
        key = f"{prefix}.{name}" if prefix else name
        if name in data:
            kwargs[name] = _convert(hints[name], data[name], path, key)
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise _fail(path, key, "missing; " + f.metadata.get("help", "it is required"))
    try:
        return cls(**kwargs)
    except ConfigError as err:
        raise ConfigError(f"{path}: {prefix + ': ' if prefix else ''}{err}", file=path) from err


def load_toml(cls: type[T], path: str | os.PathLike[str]) -> T:
    """Read a TOML file into dataclass ``cls`` (see :func:`from_dict`)."""
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError as err:
        raise ConfigError(f"{p} does not exist", file=str(p)) from err
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f"{p} cannot be read: {err}", file=str(p)) from err
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{p} is not valid TOML: {err}", file=str(p)) from err
    return from_dict(cls, data, str(p))


def to_dict(obj: Any) -> Any:
    """Dataclass tree to plain TOML-ready data (tuples become lists, None fields are dropped)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out = {}
        for f in dataclasses.fields(obj):
            v = getattr(obj, f.name)
            if v is not None:
                out[f.name] = to_dict(v)
        return out
    if isinstance(obj, list | tuple):
        return [to_dict(v) for v in obj]
    return obj
