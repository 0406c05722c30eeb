"""Any field of a task's dataclass config, changed from the command line as ``dotted.key=value``.

Keys follow the config's structure (``runner.algorithm.learning_rate``, ``env.push.interval_s``,
``runner.actor.hidden_dims``); an element of a list of dataclasses is named by its index or its name
(``env.rewards.feet_slip.weight``, the reward term's function name). Values are parsed against the field's type
hint: ``1e-3`` for a float, ``128,64`` or ``[128, 64]`` for a list, ``none`` for an optional field,
``{"a": 1}`` (JSON or a Python literal) for a dict. A model's ``kwargs`` also take an argument its class accepts
that the config does not name yet (``runner.actor.kwargs.trained_experts=[3,4]``). Unknown keys and wrong types fail
with one line that names the closest valid key.
"""

from __future__ import annotations

import ast
import dataclasses
import difflib
import json
import math
import types
import typing
from typing import Any, Union

from pchc_rsl.configs.base import constructor_arguments

READ_ONLY = {"name": "the task is chosen with --task"}


class OverrideError(ValueError):
    """An override that does not fit the config: unknown key, wrong type, no '='."""


def apply_overrides(cfg: Any, overrides: list[str]) -> list[str]:
    """Set each ``key=value`` on ``cfg`` in order. Returns them as ``key=value`` with the parsed values. A key given
    twice with different values is refused (which one was meant?)."""
    applied = []
    seen: dict[str, str] = {}
    for item in overrides:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise OverrideError(f"'{item}' is not a KEY=VALUE override (e.g. runner.algorithm.learning_rate=3e-4).")
        if key in seen and seen[key] != text:
            raise OverrideError(f"{key} is set twice, to {seen[key]} and to {text}; give it once.")
        seen[key] = text
        value = set_value(cfg, key, text)
        applied.append(f"{key}={json.dumps(value)}")
    return applied


def set_value(cfg: Any, key: str, text: str) -> Any:
    """Parse ``text`` against the type of ``key`` and set it; the parsed value."""
    fields = config_fields(cfg)
    if key in READ_ONLY:
        raise OverrideError(f"'{key}' cannot be overridden: {READ_ONLY[key]}.")
    if key not in fields and (kwargs := _kwargs_taking(fields, key)) is not None:
        value = coerce(text, Any, None, key)
        kwargs[key.rpartition(".")[2]] = value
        return value
    if key not in fields:
        groups = {k.rsplit(".", 1)[0] for k in fields if "." in k}
        if key in groups:
            example = next(k for k in fields if k.startswith(key + "."))
            raise OverrideError(f"'{key}' is a group of settings; set one of its fields, e.g. {example}=...")
        close = difflib.get_close_matches(key, list(fields), n=1, cutoff=0.5)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise OverrideError(f"unknown config key '{key}'{hint} (--show-config lists every key)")
    parent, name, hint, current = fields[key]
    value = coerce(text, hint, current, key)
    if isinstance(parent, dict):
        parent[name] = value
    else:
        setattr(parent, name, value)
    return value


def _kwargs_taking(fields: dict, key: str) -> dict | None:
    """The ``kwargs`` dict of a model config when ``key`` names an argument of that model's class inside it."""
    parent_key, _, name = key.rpartition(".")
    if not parent_key.endswith(".kwargs") or parent_key not in fields:
        return None
    model, _, _, kwargs = fields[parent_key]
    class_name = getattr(model, "class_name", None)
    if not isinstance(class_name, str) or not isinstance(kwargs, dict):
        return None
    return kwargs if name in constructor_arguments(class_name) else None


def config_fields(cfg: Any, aliases: bool = True) -> dict[str, tuple[Any, Any, Any, Any]]:
    """Every settable leaf of a config: dotted key -> (parent object, attribute/key, type hint, current value).
    Elements of a list of dataclasses appear by index and, when they have a unique name, by name; ``aliases=False``
    keeps only one of the two (the name)."""
    out: dict[str, tuple[Any, Any, Any, Any]] = {}

    def visit(obj: Any, hint: Any, prefix: str) -> None:
        for name, child_hint, value in _children(obj, hint):
            key = f"{prefix}{name}"
            if key in READ_ONLY:
                continue
            if dataclasses.is_dataclass(value) and not isinstance(value, type):
                visit(value, None, key + ".")
                continue
            if isinstance(value, list) and value and all(dataclasses.is_dataclass(v) for v in value):
                for index, item in enumerate(value):
                    label = _element_name(item)
                    unique = label is not None and sum(_element_name(v) == label for v in value) == 1
                    if aliases or not unique:
                        visit(item, None, f"{key}.{index}.")
                    if unique:
                        visit(item, None, f"{key}.{label}.")
                continue
            out[key] = (obj, name, child_hint, value)
            if isinstance(value, dict) and all(isinstance(k, str) for k in value):
                visit(value, child_hint, key + ".")

    visit(cfg, None, "")
    return out


def format_config(cfg: Any) -> str:
    """One ``key = value  (type)`` line per settable field, in the config's order."""
    return "\n".join(
        f"{key} = {json.dumps(value, default=str)}  ({_type_name(hint, value)})"
        for key, (_, _, hint, value) in config_fields(cfg, aliases=False).items()
    )


def _children(obj: Any, hint: Any):
    """(name, type hint, value) of a dataclass's fields or a dict's items (typed by the dict's hint)."""
    if dataclasses.is_dataclass(obj):
        try:
            hints = typing.get_type_hints(type(obj))
        except Exception:  # an unresolvable annotation: fall back to the values' types
            hints = {}
        for f in dataclasses.fields(obj):
            yield f.name, hints.get(f.name, Any), getattr(obj, f.name)
    elif isinstance(obj, dict):
        dict_hint = next((a for a in typing.get_args(hint) if typing.get_origin(a) is dict), hint)
        args = typing.get_args(dict_hint) if typing.get_origin(dict_hint) is dict else ()
        for name, value in obj.items():
            yield name, args[1] if len(args) == 2 else Any, value


def _element_name(item: Any) -> str | None:
    """How an element of a list of dataclasses is addressed by name: its ``name``, or its function's name."""
    if isinstance(getattr(item, "name", None), str):
        return item.name
    func = getattr(item, "func", None)
    if isinstance(func, str):
        return func.rsplit(":", 1)[-1].rsplit(".", 1)[-1]
    return None


def coerce(text: Any, hint: Any, current: Any, key: str) -> Any:
    """``text`` (a str from the command line, or an already parsed object) as a value of type ``hint``."""
    try:
        return _coerce(text, hint, current)
    except (ValueError, TypeError, SyntaxError) as error:
        shown = text if isinstance(text, str) else json.dumps(text, default=str)
        detail = f" ({error})" if str(error) else ""
        raise OverrideError(f"{key}={shown}: expected {_type_name(hint, current)}{detail}") from None


def _coerce(value: Any, hint: Any, current: Any) -> Any:
    if hint is Any:
        hint = type(current) if current is not None else Any
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (Union, types.UnionType):
        if isinstance(value, str) and value.strip().lower() in ("none", "null") and type(None) in args:
            return None
        if value is None and type(None) in args:
            return None
        for arg in (a for a in args if a is not type(None)):
            try:
                return _coerce(value, arg, current)
            except (ValueError, TypeError, SyntaxError):
                continue
        raise ValueError("")
    if hint is Any:
        return _literal(value) if isinstance(value, str) else value
    if hint is bool:
        if isinstance(value, bool):
            return value
        text = str(value).strip().lower()
        if text in ("true", "1", "yes", "on"):
            return True
        if text in ("false", "0", "no", "off"):
            return False
        raise ValueError("")
    if hint is int:
        if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
            raise ValueError("")
        return int(value) if not isinstance(value, str) else int(value.strip())
    if hint is float:
        if isinstance(value, bool):
            raise ValueError("")
        number = float(value)
        if not math.isfinite(number):  # nan and inf would only fail later, deep inside the physics or rsl-rl
            raise ValueError("a finite number")
        return number
    if hint is str:
        if not isinstance(value, str):
            raise ValueError("")
        return value
    sequence = origin if origin in (list, tuple) else hint if hint in (list, tuple) else None
    if sequence is not None:
        items = _sequence(value)
        if sequence is tuple and args and args[-1] is not Ellipsis:
            if len(items) != len(args):
                raise ValueError(f"{len(args)} values")
            return tuple(_coerce(v, a, None) for v, a in zip(items, args))
        item_hint = args[0] if args else Any
        converted = [_coerce(v, item_hint, None) for v in items]
        return tuple(converted) if sequence is tuple else converted
    if origin is dict or hint is dict:
        parsed = _literal(value) if isinstance(value, str) else value
        if not isinstance(parsed, dict):
            raise ValueError("")
        if args:
            return {_coerce(k, args[0], None): _coerce(v, args[1], None) for k, v in parsed.items()}
        return parsed
    if isinstance(hint, type) and isinstance(value, hint):
        return value
    raise TypeError(f"cannot parse a {getattr(hint, '__name__', hint)} from the command line")


def _sequence(value: Any) -> list:
    if isinstance(value, (list, tuple)):
        return list(value)
    text = value.strip()
    if text.startswith(("[", "(")):
        parsed = _literal(text)
        if not isinstance(parsed, (list, tuple)):
            raise ValueError("")
        return list(parsed)
    return [] if not text else [part.strip() for part in text.split(",")]


def _literal(text: str) -> Any:
    """JSON or a Python literal; plain text stays a string."""
    for parse in (json.loads, ast.literal_eval):
        try:
            return parse(text)
        except (ValueError, SyntaxError, TypeError):
            continue
    return text


def _type_name(hint: Any, value: Any = None) -> str:
    if hint is Any:
        return type(value).__name__ if value is not None else "any"
    if typing.get_origin(hint) in (Union, types.UnionType):
        return " | ".join(_type_name(a) for a in typing.get_args(hint))
    if typing.get_args(hint):
        return str(hint).replace("typing.", "")
    return "None" if hint is type(None) else getattr(hint, "__name__", str(hint))
