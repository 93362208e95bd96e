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

from pydantic import BaseModel, ConfigDict, field_validator

# the most characters of a value an error message repeats (a whole stage list was printed)
SHOWN_VALUE = 80


def _accepts(annotation) -> tuple[set, set]:
    """(kinds, words) a field annotation accepts, through Optional / Union / Annotated / Literal:
    kinds among 'number', 'bool', 'text' (any text), 'numbers' (a list or tuple of numbers) and
    'other'; words: the texts a Literal allows ('auto')."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _accepts(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        kinds, words = set(), set()
        for member in typing.get_args(annotation):
            k, w = _accepts(member)
            kinds |= k
            words |= w
        return kinds, words
    if origin is typing.Literal:
        values = typing.get_args(annotation)
        return ({"bool" for v in values if isinstance(v, bool)} | {"number" for v in values if isinstance(v, (int, float))
                                                                      and not isinstance(v, bool)}), \
            {v for v in values if isinstance(v, str)}
    if origin in (tuple, list):
        inner = set()
        for member in typing.get_args(annotation):
            if member is not Ellipsis:
                inner |= _accepts(member)[0]
        return ({"numbers"} if inner and inner <= {"number"} else {"other"}), set()
    if annotation is type(None):
        return set(), set()         # None is YAML's null, never a boolean or a text
    if annotation is bool:
        return {"bool"}, set()
    if annotation in (int, float):
        return {"number"}, set()
    if annotation is str:
        return {"text"}, set()
    return {"other"}, set()


def number_or_error(annotation, value):
    """``value`` unchanged, or ValueError when it is a boolean or a text where the field takes a
    number (and no boolean, or no such text: 'auto' where the field takes 'auto'), or a list of
    numbers holding either."""
    kinds, words = _accepts(annotation)
    if "number" in kinds and "other" not in kinds:
        if isinstance(value, bool) and "bool" not in kinds:
            raise ValueError(f"must be a number, not {value!r}")
        if isinstance(value, str) and "text" not in kinds and value not in words:
            wanted = "a number" + "".join(f" or {w!r}" for w in sorted(words))
            raise ValueError(f"must be {wanted}, not {value!r}")
    if "numbers" in kinds and isinstance(value, (list, tuple)):
        for item in value:
            if isinstance(item, (bool, str)):
                raise ValueError(f"must be numbers, not {item!r}")
    return value


def shown(value) -> str:
    """repr(value), cut to SHOWN_VALUE characters for an error message."""
    text = repr(value)
    return text if len(text) <= SHOWN_VALUE else text[:SHOWN_VALUE - 4] + " ..."


class CheckedOptions(BaseModel):
    """Base of the options models (the run config's sections, each stage's options): unknown keys
    are errors, numbers finite (a field that means something by infinity allows it itself) and
    neither booleans nor texts (number_or_error)."""
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _numbers_are_numbers(cls, value, info):
        return number_or_error(cls.model_fields[info.field_name].annotation, value)
