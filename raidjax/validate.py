"""Host-side checks of user input, shared by ``EnvConfig``, ``make_params``, ``playtest`` and the trainers' configs.

Every check runs in plain Python before anything is traced or compiled, never coerces a value
of the wrong type (a ``str``, a ``bool`` for a number, ``None``, a list), and raises a one-line
``ValueError`` ``"<field>: value <value> is <what it is>; allowed: <what is allowed>"``.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import numpy as np

_MAX_SHOWN = 60


def show(value) -> str:
    """``repr(value)`` on one line, at most about 60 characters (arrays and long lists cut)."""
    text = " ".join(repr(value).split())
    return text if len(text) <= _MAX_SHOWN else text[: _MAX_SHOWN - 3] + "..."


def kind_of(value) -> str:
    """What ``value`` is, for messages: ``"None"``, ``"a bool"``, ``"a str"``, ``"a list of length 1"``,
    ``"an array of shape (2,)"``, ``"a traced value"``, else ``"a <type name>"``."""
    if value is None:
        return "None"
    if isinstance(value, bool | np.bool_):
        return "a bool"
    if isinstance(value, jax.core.Tracer):
        return "a traced value (checks run on the host, outside jit)"
    shape = getattr(value, "shape", None)
    if shape is not None and tuple(shape) != ():
        return f"an array of shape {tuple(shape)}"
    if isinstance(value, list | tuple):
        return f"a {type(value).__name__} of length {len(value)}"
    name = type(value).__name__
    return f"{'an' if name[0] in 'aeiouAEIOU' else 'a'} {name}"


def fail(field: str, value, allowed: str, what: str | None = None) -> ValueError:
    """The error for ``field``: ``"<field>: value <value> is <what>; allowed: <allowed>"``
    (``what`` defaults to the value's type, ``kind_of(value)``); the caller raises it."""
    if value is None and what is None:
        return ValueError(f"{field}: value None; allowed: {allowed}")
    return ValueError(f"{field}: value {show(value)} is {what or kind_of(value)}; allowed: {allowed}")


def _scalar_array(value, kinds: str):
    """``value`` as a 0-d numpy array when it is a concrete numpy/JAX scalar of a dtype kind in
    ``kinds`` (e.g. ``"iu"``, ``"iuf"``), else ``None``."""
    if isinstance(value, jax.core.Tracer) or not hasattr(value, "dtype") or not hasattr(value, "shape"):
        return None
    if tuple(value.shape) != ():
        return None
    arr = np.asarray(value)
    return arr if arr.dtype.kind in kinds else None


def number(field: str, value, allowed: str, allow_bool: bool = False) -> float:
    """``value`` as a float if it is a real number: a Python ``int``/``float`` or a 0-d numpy/JAX
    number (``bool`` only with ``allow_bool``, for 0/1 flags). NaN and infinities pass (range
    checks report them); a Python int too large for a float becomes ``inf``.

    Args:
        field: the name the message gives. value: the user's value.
        allowed: what is allowed, for the message (e.g. ``"a number in [0, 100]"``).

    Returns:
        ``float``.

    Raises:
        ValueError: ``value`` is a ``str``, ``bool``, ``None``, a list, an array with ``ndim > 0``,
            a complex number or anything else that is not a real number.
    """
    if isinstance(value, bool | np.bool_):
        if allow_bool:
            return float(value)
        raise fail(field, value, allowed)
    if isinstance(value, int | float | np.integer | np.floating):
        try:
            return float(value)
        except OverflowError:  # a Python int beyond float range
            return math.inf if value > 0 else -math.inf
    arr = _scalar_array(value, "iuf" + ("b" if allow_bool else ""))
    if arr is None:
        raise fail(field, value, allowed)
    return float(arr)


def whole_number(field: str, value, low: int = 1, allowed: str | None = None) -> int:
    """``value`` as an ``int`` if it is a whole number ``>= low``: a Python ``int`` or a numpy/JAX
    integer scalar (not a ``bool``, not a ``float`` such as ``2.5`` or ``2.0``).

    Returns:
        ``int``.

    Raises:
        ValueError: another type, or a value below ``low`` (naming ``field``, the value and
            ``allowed``, default ``"a whole number >= low"``).
    """
    allowed = allowed or f"a whole number >= {low}"
    if isinstance(value, bool | np.bool_):
        raise fail(field, value, allowed)
    if isinstance(value, int | np.integer):
        v = int(value)
    else:
        arr = _scalar_array(value, "iu")
        if arr is None:
            raise fail(field, value, allowed)
        v = int(arr)
    if v < low:
        raise ValueError(f"{field}: value {v!r} is too small; allowed: {allowed}")
    return v


def flag(field: str, value) -> bool:
    """``value`` as a ``bool`` if it is one (Python or numpy ``bool``); ``1``, ``"True"`` are not.

    Raises:
        ValueError: any other type.
    """
    if isinstance(value, bool | np.bool_):
        return bool(value)
    raise fail(field, value, "True or False")


def name(field: str, value, known, what: str) -> str:
    """``value`` if it is a ``str`` in ``known``; ``what`` names the kind, e.g. ``"class preset"``.

    Raises:
        ValueError: not a ``str``, or unknown (the message lists ``known``).
    """
    allowed = f"a {what}, one of {sorted(known)}"
    if not isinstance(value, str):
        raise fail(field, value, allowed)
    if value not in known:
        raise fail(field, value, allowed, f"an unknown {what}")
    return value


# --- the fields of config dataclasses (trainers.config) ------------------------------------------

def is_number(v) -> bool:
    """A finite int or float, not a bool."""
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def check_fields(obj, bounds: dict[str, tuple]) -> None:
    """Check every field of the dataclass ``obj`` against its annotated type (``int``, ``float``,
    ``bool``; no string or bool coercion) and ``bounds``: ``name -> (low, high[, wording])`` with
    ``None`` for no bound and an exclusive low when the wording says ``"> low"``.

    Raises:
        ValueError: ``"<field>: value <v!r> ...; allowed: ..."``, one line.
    """
    for f in dataclasses.fields(obj):
        v, kind = getattr(obj, f.name), str(f.type)
        ok = {"int": isinstance(v, int) and not isinstance(v, bool), "float": is_number(v),
              "bool": isinstance(v, bool)}.get(kind, True)
        if not ok:
            finite = not isinstance(v, float) or math.isfinite(v)
            raise fail(f.name, v, kind_word(kind), None if finite else "not finite")
        if f.name in bounds:
            low, high, *wording = bounds[f.name]
            exclusive = bool(wording) and wording[0].startswith(">")
            if (low is not None and (v <= low if exclusive else v < low)) or (high is not None and v > high):
                allowed = wording[0] if wording else (f">= {low}" if high is None else f"in [{low}, {high}]")
                raise ValueError(f"{f.name}: value {v!r}; allowed: {kind_word(kind)} {allowed}")


def kind_word(kind: str) -> str:
    """``"int"`` -> ``"a whole number"``, ``"float"`` -> ``"a number"``, ``"bool"`` -> ``"true or false"``."""
    return {"int": "a whole number", "float": "a number", "bool": "true or false"}.get(kind, kind)


def one_arena(call: str, team) -> None:
    """Raise a one-line ``ValueError`` unless ``team`` (``Params.team``) is one arena's, of shape
    ``[U]``: ``call`` (``"reset"``, ``"step"``, ...) plays one arena and is vmapped over a batch."""
    shape = tuple(getattr(team, "shape", ()))
    if len(shape) != 1:
        raise ValueError(f"params: team of shape {list(shape)}; allowed: one arena's params (team of shape [U]) "
                         f"in {call}: jax.vmap({call}) plays a batch, jax.tree.map(lambda x: x[0], params) is its "
                         "first arena")
