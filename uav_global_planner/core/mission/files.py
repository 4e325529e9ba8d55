"""Mission files: the format of a path, the text in a format, and writing the file."""

from pathlib import Path
from typing import Union

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.mission.model import Mission
from uav_global_planner.core.mission.qgc_plan import plan_text
from uav_global_planner.core.mission.wpl import wpl_text

#: Mission file formats: QGroundControl's JSON ``.plan`` and the plain-text ``QGC WPL 110``.
FORMATS = ('qgc', 'wpl')


def mission_text(mission: Mission, file_format: str) -> str:
    """The file text in ``file_format`` (``qgc`` or ``wpl``)."""
    if file_format == 'qgc':
        return plan_text(mission)
    if file_format == 'wpl':
        return wpl_text(mission)
    raise InvalidInputError(f'format must be one of {", ".join(FORMATS)}, got {file_format!r}')


def format_from_path(path: Union[str, Path]) -> str:
    """``qgc`` for ``*.plan``, ``wpl`` for ``*.waypoints``/``*.txt``/``*.wpl``.

    Raises
    ------
    InvalidInputError
        For any other extension.
    """
    suffix = Path(path).suffix.lower()
    if suffix == '.plan':
        return 'qgc'
    if suffix in ('.waypoints', '.txt', '.wpl', '.mission'):
        return 'wpl'
    raise InvalidInputError(f'{path}: cannot tell the mission format from the extension '
                            f'{suffix!r}; use .plan (QGroundControl) or .waypoints (QGC WPL 110)')


def write_mission(mission: Mission, path: Union[str, Path], file_format: str) -> Path:
    """Write the mission file (UTF-8); returns the absolute path written."""
    text = mission_text(mission, file_format)
    target = Path(path).expanduser().resolve()
    try:
        target.write_text(text, encoding='utf-8')
    except OSError as error:
        raise InvalidInputError(f'{target}: cannot write mission file ({error.strerror})') \
            from None
    return target
