"""Rules every options model (the run config's sections, each stage's options) shares.

pydantic's lax mode takes YAML's ``true`` as the count 1 and the text ``"20"`` as the number 20: a
config that said ``k: true`` ran SOR with k = 1 and ``truth_classes: [true]`` scored class 1.
``number_or_error`` refuses a boolean or a text where a field takes numbers (and neither booleans
nor texts), also inside a list of numbers. Non-finite numbers (``.nan``, ``.inf``) are refused by
the models' ``allow_inf_nan=False`` (a field that means something by infinity says so itself).
"""
from __future__ import annotations

import types
import typing

# the most characters of a value an error message repeats (a whole stage list was printed)
SHOWN_VALUE = 80


def _kinds(annotation) -> set:
    """What a field annotation accepts: 'number', 'bool', 'text', 'numbers' (a list or tuple of
    numbers) or 'other', through Optional / Union / Annotated / Literal."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _kinds(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        return set().union(*(_kinds(a) for a in typing.get_args(annotation)))
    if origin is typing.Literal:
        values = typing.get_args(annotation)
        return {"bool" if isinstance(v, bool) else "text" if isinstance(v, str) else "number"
                if isinstance(v, (int, float)) else "other" for v in values}
    if origin in (tuple, list):
        inner = set().union(*(_kinds(a) for a in typing.get_args(annotation) if a is not Ellipsis)) or {"other"}
        return {"numbers"} if inner <= {"number"} else {"other"}
    if annotation is bool:
        return {"bool"}
    if annotation in (int, float):
        return {"number"}
    if annotation is str:
        return {"text"}
    return {"other"}


def _wrong(value, kinds: set) -> bool:
    if isinstance(value, bool):
        return "bool" not in kinds and "other" not in kinds
    if isinstance(value, str):
        return "text" not in kinds and "other" not in kinds
    return False


def number_or_error(annotation, value):
    """``value`` unchanged, or ValueError when it is a boolean or a text where the field takes
    numbers only (a number, or a list of numbers)."""
    kinds = _kinds(annotation)
    if "number" in kinds and _wrong(value, kinds):
        raise ValueError(f"must be a number, not {value!r}")
    if "numbers" in kinds and isinstance(value, (list, tuple)):
        for item in value:
            if isinstance(item, (bool, str)):
                raise ValueError(f"must be numbers, not {item!r}")
    return value


def shown(value) -> str:
    """repr(value), cut to SHOWN_VALUE characters for an error message."""
    text = repr(value)
    return text if len(text) <= SHOWN_VALUE else text[:SHOWN_VALUE - 4] + " ..."
