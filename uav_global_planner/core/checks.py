"""The checks of the numbers, points and files the planner is given, with one message style.

Every refusal is an :class:`~uav_global_planner.core.errors.InvalidInputError` that names the
setting first and then says what it accepts and what it got::

    resolution must be > 0 m, got -0.5
    safety_margin must be in [0.0, 100.0], got 101.0
    max_expansions must be an integer, got True
    sphere center must be three numbers [x, y, z], got [1, 2]
    obstacles[0].radius: must be finite, got inf
    /data/map.pcd: cannot read map file (no such file)

The name is the setting's own (``resolution``), or, for a value read from a file, its key path
followed by a colon (``obstacles[0].radius:``), so that a message shows where in the file the
value is. The reasons (``must be ...``, ``got ...``) are those of :func:`number_refusal`,
:func:`integer_refusal` and :func:`point_refusal`, which code that builds its own messages (the
settings table, for one) uses as well.

A value that is not a number is told ``must be a number``, NaN and infinities ``must be
finite`` (unless the check lets infinities through), and a number out of range what the range
is: ``> 0 m``, ``>= 0``, ``<= 90`` or ``in [0.0, 100.0]`` (round brackets for open ends).
"""

import math
import os
from pathlib import Path
from typing import Any, Optional, Union

import numpy as np

from uav_global_planner.core.errors import InvalidInputError

#: The Python and numpy types a number may have (bool is refused separately).
NUMBER_TYPES = (int, float, np.integer, np.floating)

_AXIS_WORDS = {2: 'two', 3: 'three'}


def _format_end(value: float) -> str:
    return f'{float(value)}'


def interval_text(low: float = -math.inf, high: float = math.inf, low_open: bool = False,
                  high_open: bool = False, unit: str = '') -> str:
    """The accepted values of a number in words: ``> 0 m``, ``in [0.0, 1.0]``.

    Parameters
    ----------
    low, high : float
        Ends of the range; -inf / +inf for none.
    low_open, high_open : bool
        The range excludes that end.
    unit : str
        Appended after a space when given (``'m'``).
    """
    suffix = f' {unit}' if unit else ''
    if math.isinf(low) and math.isinf(high):
        return f'a number{suffix}'
    if math.isinf(high):
        return f'{">" if low_open else ">="} {low:g}{suffix}'
    if math.isinf(low):
        return f'{"<" if high_open else "<="} {high:g}{suffix}'
    return (f'in {"(" if low_open else "["}{_format_end(low)}, {_format_end(high)}'
            f'{")" if high_open else "]"}{suffix}')


def number_refusal(value: Any, low: float = -math.inf, high: float = math.inf, *,
                   low_open: bool = False, high_open: bool = False, unit: str = '',
                   accepted: Optional[str] = None, finite: bool = True,
                   convert: bool = False) -> Optional[str]:
    """Why ``value`` is refused as a number of the range, or None when it is accepted.

    Parameters
    ----------
    value : Any
    low, high, low_open, high_open, unit
        The range, as :func:`interval_text` takes it.
    accepted : str, optional
        The range in words, instead of :func:`interval_text`'s.
    finite : bool
        False: +-inf are accepted too (a zone without a floor); NaN never is.
    convert : bool
        Take anything ``float()`` reads (a numpy scalar, a numeric string) instead of only
        numbers; a bool is a number neither way.

    Returns
    -------
    str or None
        ``must be a number, got 'x'``, ``must be finite, got nan`` or ``must be <accepted>,
        got <value>``.
    """
    if isinstance(value, (bool, np.bool_)):
        return f'must be a number, got {value!r}'
    if convert:
        try:
            number = float(value)
        except (TypeError, ValueError):
            return f'must be a number, got {value!r}'
    elif not isinstance(value, NUMBER_TYPES):
        return f'must be a number, got {value!r}'
    else:
        number = float(value)
    if math.isnan(number) or (finite and math.isinf(number)):
        return f'must be finite, got {number}'
    below = number <= low if low_open else number < low
    above = number >= high if high_open else number > high
    if below or above:
        if accepted is None:
            accepted = interval_text(low, high, low_open, high_open, unit)
        return f'must be {accepted}, got {number}'
    return None


def check_number(name: str, value: Any, low: float = -math.inf, high: float = math.inf, *,
                 low_open: bool = False, high_open: bool = False, unit: str = '',
                 accepted: Optional[str] = None, finite: bool = True,
                 convert: bool = False) -> float:
    """``value`` as a float, checked by :func:`number_refusal` (same parameters).

    Raises
    ------
    InvalidInputError
        ``<name> must be ..., got ...``.
    """
    reason = number_refusal(value, low, high, low_open=low_open, high_open=high_open, unit=unit,
                            accepted=accepted, finite=finite, convert=convert)
    if reason is not None:
        raise InvalidInputError(f'{name} {reason}')
    return float(value)


def check_positive(name: str, value: Any, unit: str = '', convert: bool = True) -> float:
    """A finite number > 0: ``<name> must be > 0 <unit>, got ...``."""
    return check_number(name, value, 0.0, low_open=True, unit=unit, convert=convert)


def check_non_negative(name: str, value: Any, unit: str = '', convert: bool = True) -> float:
    """A finite number >= 0: ``<name> must be >= 0 <unit>, got ...``."""
    return check_number(name, value, 0.0, unit=unit, convert=convert)


def integer_refusal(value: Any, low: Optional[int] = None, high: Optional[int] = None,
                    accepted: Optional[str] = None) -> Optional[str]:
    """Why ``value`` is refused as an integer in [low, high], or None.

    A float is refused even when whole (``1e6`` in a YAML file is a typo for ``1000000`` as
    often as not); a bool is refused. The range reads ``>= low`` or ``in [low, high]``.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        return f'must be an integer, got {value!r}'
    number = int(value)
    if (low is not None and number < low) or (high is not None and number > high):
        if accepted is None:
            accepted = f'>= {low}' if high is None else (
                f'<= {high}' if low is None else f'in [{low}, {high}]')
        return f'must be {accepted}, got {number}'
    return None


def check_integer(name: str, value: Any, low: Optional[int] = None,
                  high: Optional[int] = None) -> int:
    """``value`` as an int, checked by :func:`integer_refusal`.

    Raises
    ------
    InvalidInputError
        ``<name> must be an integer, got ...`` or ``<name> must be >= 1, got 0``.
    """
    reason = integer_refusal(value, low, high)
    if reason is not None:
        raise InvalidInputError(f'{name} {reason}')
    return int(value)


def point_refusal(value: Any, axes: str = 'xyz') -> Optional[str]:
    """Why ``value`` is refused as a finite point with one number per axis, or None.

    ``value`` may be any array_like; the reason reads ``must be three numbers [x, y, z], got
    ...`` or ``must be finite, got [...]``.
    """
    wanted = f"{_AXIS_WORDS[len(axes)]} numbers [{', '.join(axes)}]"
    if isinstance(value, (str, bytes)):
        return f'must be {wanted}, got {value!r}'
    try:
        point = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return f'must be {wanted}, got {value!r}'
    if point.shape != (len(axes),):
        return f'must be {wanted}, got {value!r}'
    if not np.all(np.isfinite(point)):
        return f'must be finite, got {point.tolist()}'
    return None


def check_point(name: str, value: Any, axes: str = 'xyz') -> np.ndarray:
    """``value`` as a finite float64 array with one item per axis.

    Parameters
    ----------
    name : str
        The setting (``'start'``), or a key path with a colon (``'center:'``).
    value : array_like
    axes : str
        Axis letters: ``'xyz'`` (shape (3,)) or ``'xy'`` (shape (2,)).

    Raises
    ------
    InvalidInputError
        ``<name> must be three numbers [x, y, z], got ...`` (``two numbers [x, y]``) or
        ``<name> must be finite, got [...]``.
    """
    reason = point_refusal(value, axes)
    if reason is not None:
        raise InvalidInputError(f'{name} {reason}')
    return np.asarray(value, dtype=np.float64)


def path_refusal(value: Any, allow_empty: bool = False) -> Optional[str]:
    """Why ``value`` is refused as a polyline of finite points [x, y, z], or None.

    The reason reads ``must be an (N, 3) array of numbers [x, y, z], got shape (4,)`` or
    ``must be finite, got [nan, 0.0, 1.0] in row 2``; no rows at all (N = 0) are refused
    unless ``allow_empty``.
    """
    wanted = 'must be an (N, 3) array of numbers [x, y, z]'
    if value is None or isinstance(value, (str, bytes)):
        return f'{wanted}, got {value!r}'
    try:
        points = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return f'{wanted}, got {type(value).__name__}'
    if points.size == 0 and allow_empty:
        return None
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        return f'{wanted}, got shape {points.shape}'
    bad = ~np.all(np.isfinite(points), axis=1)
    if bad.any():
        row = int(np.argmax(bad))
        return f'must be finite, got {points[row].tolist()} in row {row}'
    return None


def check_path(name: str, value: Any, allow_empty: bool = False) -> np.ndarray:
    """``value`` as a finite float64 array of shape (N, 3), N >= 1 (N >= 0 with
    ``allow_empty``), checked by :func:`path_refusal`.

    Raises
    ------
    InvalidInputError
        ``<name> must be an (N, 3) array of numbers [x, y, z], got ...`` or ``<name> must be
        finite, got [...] in row <i>``.
    """
    reason = path_refusal(value, allow_empty)
    if reason is not None:
        raise InvalidInputError(f'{name} {reason}')
    return np.asarray(value, dtype=np.float64).reshape(-1, 3)


def file_refusal(path: Union[str, Path]) -> Optional[str]:
    """Why the file at ``path`` cannot be read: ``no such file``, ``it is a folder`` or
    ``permission denied``; None when it is a readable file."""
    file = Path(path)
    if file.is_dir():
        return 'it is a folder'
    if not file.is_file():
        return 'no such file'
    if not os.access(file, os.R_OK):
        return 'permission denied'
    return None


def check_file(path: Union[str, Path], what: str) -> Path:
    """The path of an existing, readable file.

    Parameters
    ----------
    path : str or Path
    what : str
        The kind of file, for the message (``'map file'``).

    Raises
    ------
    InvalidInputError
        ``<path>: cannot read <what> (no such file)`` (or ``it is a folder``, ``permission
        denied``).
    """
    file = Path(path)
    reason = file_refusal(file)
    if reason is not None:
        raise InvalidInputError(f'{file}: cannot read {what} ({reason})')
    return file
