r"""Value types of scene files: each checks a TOML value with the project's wording and states the
same rule as JSON Schema (Draft 4), so the loader (:mod:`warp_sg.scene.loader`) and an editor
(``docs/scene.schema.json``) apply one rule.

``number(lo, lo_open, hi)``, ``integer(lo, hi, odd)``, ``vector(n)``, ``rgb()`` (a number or 3
numbers >= 0), ``number_or_vector(n)``, ``int_or_ints(n)``, ``string()``, ``path()``,
``boolean()``, ``choice(options)`` are ``Annotated`` pydantic types (a ``PlainValidator`` and
``WithJsonSchema``); a failed check raises a ``PydanticCustomError`` of type ``"scene"`` carrying the
message ("must be > 0, got -0.2") and, for table-level checks, the key it is about.
:class:`Table` is the base of every table model (unknown keys are errors naming the closest valid
key); :func:`tagged` builds a discriminated union whose tags are dropped from error locations by
:mod:`warp_sg.scene.schema`.
"""
from __future__ import annotations

import math
import numbers
from pathlib import Path
from typing import Annotated, Any, Union

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    PlainValidator,
    Tag,
    WithJsonSchema,
    model_validator,
)
from pydantic_core import PydanticCustomError

from warp_sg.core.suggest import did_you_mean


def fail(msg: str, key: str = "", sep: str = " "):
    """A validation failure with the project's wording; ``key`` names a key inside the table (the
    line reads ``key '<key>'<sep><msg>``)."""
    raise PydanticCustomError("scene", "{msg}", {"msg": msg, "key": key, "sep": sep})


def failure_text(err: dict, key: str = "") -> str:
    """The words of one failed check (a pydantic error dict) at key path ``key`` of its table:
    ``key '<key>'<sep><msg>`` for a :func:`fail` (its own ``key`` appended), ``<msg>`` for a
    failure of the table itself, ``key '<key>': <pydantic's message>`` for any other error."""
    if err["type"] != "scene":
        return f"key '{key}': {err['msg']}" if key else err["msg"]
    ctx = err["ctx"]
    key = ".".join(x for x in (key, ctx["key"]) if x)
    return f"key '{key}'{ctx['sep']}{ctx['msg']}" if key else ctx["msg"]


def _leaf(check, schema: dict, description: str | None = None):
    """A value type: ``check(v)`` returns the (normalised) value or calls :func:`fail`."""
    schema = dict(schema, **({"description": description} if description else {}))
    return Annotated[Any, PlainValidator(check), WithJsonSchema(schema)]


# --------------------------------------------------------------------------------------------
# leaf checks (each with its JSON Schema)
# --------------------------------------------------------------------------------------------
def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _num_schema(lo=None, lo_open=False, hi=None) -> dict:
    s = {"type": "number"}
    if lo is not None:
        s["minimum"] = lo
        if lo_open:
            s["exclusiveMinimum"] = True
    if hi is not None:
        s["maximum"] = hi
    return s


def _check_num(v, lo=None, lo_open=False, hi=None) -> float:
    if not _is_num(v):
        fail(f"must be a number, got {v!r}")
    v = float(v)
    if not math.isfinite(v):
        fail(f"must be finite, got {v}")
    if lo is not None and (v < lo or (lo_open and v <= lo)):
        fail(f"must be {'>' if lo_open else '>='} {lo}, got {v}")
    if hi is not None and v > hi:
        fail(f"must be <= {hi}, got {v}")
    return v


def number(lo=None, lo_open=False, hi=None, description=None):
    return _leaf(lambda v: _check_num(v, lo, lo_open, hi), _num_schema(lo, lo_open, hi), description)


def _check_int(v, lo=None, hi=None, odd=False) -> int:
    if isinstance(v, bool) or not isinstance(v, numbers.Integral):  # (a numpy integer of a Python-built scene too)
        fail(f"must be an integer, got {v!r}")
    v = int(v)
    if lo is not None and hi is not None and not lo <= v <= hi:
        fail(f"must be in [{lo}, {hi}], got {v}")
    if lo is not None and v < lo:
        fail(f"must be >= {lo}, got {v}")
    if odd and v % 2 == 0:
        fail(f"must be an odd integer, got {v}")
    return v


def _int_schema(lo=None, hi=None, odd=False) -> dict:
    s = {"type": "integer"}
    if lo is not None:
        s["minimum"] = lo
    if hi is not None:
        s["maximum"] = hi
    if odd:
        s["not"] = {"multipleOf": 2}
    return s


def integer(lo=None, hi=None, odd=False, description=None):
    return _leaf(lambda v: _check_int(v, lo, hi, odd), _int_schema(lo, hi, odd), description)


def _check_vec(v, n=3, lo=None, lo_open=False, what="numbers", hi=None) -> tuple:
    if not isinstance(v, list) or len(v) != n or not all(_is_num(x) for x in v):
        fail(f"must be a list of {n} {what}, got {v!r}")
    if not all(math.isfinite(x) for x in v):
        fail(f"must be finite, got {v!r}")
    if lo is not None and any(x < lo or (lo_open and x <= lo) for x in v):
        fail(f"must be {'>' if lo_open else '>='} {lo}, got {v!r}")
    if hi is not None and any(x > hi for x in v):
        fail(f"must be <= {hi:g}, got {v!r}")
    return tuple(float(x) for x in v)


def _vec_schema(n=3, lo=None, lo_open=False, hi=None) -> dict:
    return {"type": "array", "items": _num_schema(lo, lo_open, hi), "minItems": n, "maxItems": n}


def vector(n=3, nonzero=False, description=None):
    def check(v):
        t = _check_vec(v, n)
        if nonzero and not any(t):
            fail("must be a non-zero vector")
        return t

    schema = _vec_schema(n)
    if nonzero:
        schema["not"] = {"items": {"enum": [0]}}  # not every component 0
    return _leaf(check, schema, description)


def number_or_vector(n, lo=0, lo_open=True, description=None):
    """A number (every component) or ``n`` numbers, all ``> lo`` (``scale``, ``size``)."""
    def check(v):
        if isinstance(v, list):
            return _check_vec(v, n, lo, lo_open)
        if not _is_num(v):
            fail(f"must be a number or a list of {n} numbers, got {v!r}")
        return _check_num(v, lo, lo_open)

    return _leaf(check, {"anyOf": [_num_schema(lo, lo_open), _vec_schema(n, lo, lo_open)]}, description)


def rgb(raw=False, hi=None, description=None, lo_open=False):
    """A colour: a number (grey) or 3 numbers, all >= 0 (> 0 with ``lo_open``; <= ``hi``); ``raw``
    keeps the value as written."""
    def check(v):
        if _is_num(v):
            out = (_check_num(v, 0, lo_open=lo_open, hi=hi),) * 3
        else:
            if not isinstance(v, list) or len(v) != 3 or not all(_is_num(x) for x in v):
                fail(f"must be a number or a list of 3 numbers (RGB), got {v!r}")
            out = _check_vec(v, 3, 0, lo_open=lo_open, hi=hi)
        return v if raw else out

    return _leaf(check, {"anyOf": [_num_schema(0, lo_open, hi=hi), _vec_schema(3, 0, lo_open, hi=hi)]}, description)


def int_or_ints(n, lo=1, description=None):
    def check(v):
        if isinstance(v, list):
            if len(v) != n:
                fail(f"must be an integer or a list of {n} integers, got {v!r}")
            return tuple(_check_int(x, lo) for x in v)
        return _check_int(v, lo)

    s = _int_schema(lo)
    return _leaf(check, {"anyOf": [s, {"type": "array", "items": s, "minItems": n, "maxItems": n}]}, description)


def _check_str(v, what="a string", nonempty=False):
    if not isinstance(v, str) or (nonempty and not v):
        fail(f"must be {what}, got {v!r}")
    return v


def string(description=None):
    return _leaf(_check_str, {"type": "string"}, description)


def path(description=None):
    return _leaf(lambda v: _check_str(v, "a file path (string)", True), {"type": "string", "minLength": 1},
                 description)


def boolean(description=None):
    def check(v):
        if not isinstance(v, bool):
            fail(f"must be true or false, got {v!r}")
        return v

    return _leaf(check, {"type": "boolean"}, description)


def choice(options, description=None, *, fold_case=False):
    """One of ``options`` (strings); ``fold_case`` accepts any case (the schema lists them as given)."""
    def check(v):
        if not isinstance(v, str):
            fail(f"must be a string ({', '.join(options)}), got {v!r}")
        w = v.strip().lower() if fold_case else v
        if w not in options:
            if len(options) <= 3:
                fail(f"must be {' or '.join(repr(o) for o in options)}, got {v!r}")
            fail(f"unknown value {v!r}{did_you_mean(v, options)} (use {', '.join(options)})", sep=": ")
        return v

    return _leaf(check, {"type": "string", "enum": list(options)}, description)


def anything(schema: dict, description=None):
    """Any value (a model validator checks it); ``schema`` is what the JSON Schema says."""
    return _leaf(lambda v: v, schema, description)


# --------------------------------------------------------------------------------------------
# tables
# --------------------------------------------------------------------------------------------
class Table(BaseModel):
    """A TOML table: unknown keys are errors naming the closest valid key."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data):
        if not isinstance(data, dict):
            fail(f"must be a table, got {type(data).__name__}")
        allowed = tuple(cls.model_fields)
        for k in data:
            if k not in allowed:
                fail("unknown" + (did_you_mean(k, allowed) or f" (valid keys: {', '.join(allowed)})"), key=k)
        return data


def require_tag(v, key: str, options, noun: str) -> None:
    """The checks before a union on ``key``: ``v`` is a table whose ``key`` is one of ``options``
    (a misspelt ``key`` is reported as such, an unknown value with the closest option)."""
    if not isinstance(v, dict):
        fail(f"must be a table, got {type(v).__name__}")
    if key not in v:
        typo = next((k for k in v if did_you_mean(k, (key,))), None)
        if typo is not None:
            fail(f"unknown — did you mean '{key}'?", key=typo)
        fail("is missing", key=key)
    if v[key] not in options:
        fail(f"unknown {noun} {v[key]!r}{did_you_mean(v[key], options)} (use {', '.join(options)})", key=key, sep=": ")


def tagged(branches: dict, tag_of, before=None):
    """A discriminated union: ``branches`` {tag: model}; ``tag_of(value)`` picks the branch;
    ``before(value)`` rejects values no branch can take, with the project's message."""
    union = Union[tuple(Annotated[m, Tag(t)] for t, m in branches.items())]
    metadata = [Discriminator(tag_of)]
    if before is not None:
        metadata.append(BeforeValidator(before))
    return Annotated[(union, *metadata)]


# --------------------------------------------------------------------------------------------
# records built in Python: the same check, the same words
# --------------------------------------------------------------------------------------------
def plain(v):
    """``v`` as TOML would give it: numpy scalars as Python numbers, arrays and tuples as lists
    (element-wise), so a record built in Python (``Camera(origin=np.array(...))``) is checked by the
    same model as the file's table."""
    if isinstance(v, Path):
        return str(v)
    if hasattr(v, "tolist") and not isinstance(v, (bool, int, float, str)):
        return v.tolist()  # numpy arrays and scalars
    if isinstance(v, (tuple, list)):
        return [plain(x) for x in v]
    if isinstance(v, dict):
        return {k: plain(x) for k, x in v.items()}
    return v


_ADAPTERS: dict = {}


def _adapter(model):
    """A (kept) pydantic ``TypeAdapter`` of ``model``: building one costs far more than a check."""
    from pydantic import TypeAdapter

    kept = _ADAPTERS.get(id(model))
    if kept is None or kept[0] is not model:
        kept = _ADAPTERS[id(model)] = (model, TypeAdapter(model))  # the model kept alive with its id
    return kept[1]


def check_record(model, data: dict, label: str):
    """Validate ``data`` (a record's fields, :func:`plain`-ed) with the table model ``model`` (a
    :class:`Table` or a :func:`tagged` union): the validated value, or a
    :class:`~warp_sg.core.errors.SceneError` ``<label> key 'k' ...`` in the words of the scene-file
    loader for the first failure (what ``Camera``, the light records and ``RenderSettings`` raise)."""
    from pydantic import ValidationError

    from warp_sg.core.errors import SceneError

    try:
        return _adapter(model).validate_python({k: plain(v) for k, v in data.items()})
    except ValidationError as e:
        err = e.errors()[0]
        loc = [x for x in err["loc"] if not (isinstance(x, str) and x.startswith("<"))]  # union tags
        raise SceneError(f"{label} {failure_text(err, '.'.join(map(str, loc)))}") from None


__all__ = ["Table", "tagged", "require_tag", "fail", "failure_text", "plain", "check_record", "number", "integer",
           "vector", "number_or_vector", "rgb", "int_or_ints", "string",
           "path", "boolean", "choice", "anything"]
