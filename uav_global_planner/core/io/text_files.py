"""Reading a text file through a parser, with refusals that name the file.

One place turns the ways a file can fail to be read (missing, unreadable, not UTF-8 text, not
the format) into :class:`~uav_global_planner.core.errors.InvalidInputError` messages that start
with the file's path.
"""

from pathlib import Path
from typing import Any, Callable, Optional, Tuple, Type, Union

from uav_global_planner.core.errors import InvalidInputError


def parse_text_file(path: Union[str, Path], what: str, parse: Callable[[str], Any],
                    parse_errors: Union[Type[Exception], Tuple[Type[Exception], ...]],
                    not_parsed: str, not_text: Optional[str] = None) -> Any:
    """``parse`` of the UTF-8 text of the file at ``path``.

    Parameters
    ----------
    path : str or Path
    what : str
        The kind of file, for the message of a file that cannot be read (``'plan file'``).
    parse : callable
        Text to content (``json.loads``, ``yaml.safe_load``).
    parse_errors : exception type or tuple of them
        What ``parse`` raises for text that is not its format.
    not_parsed : str
        Message of such text (``'not valid JSON'``), followed by the parser's words.
    not_text : str, optional
        Message of a file that is not UTF-8 text, where ``{reason}`` and ``{start}`` stand for
        the decoder's reason and the offset of the first bad byte; by default such a file is
        refused as ``not_parsed`` is.

    Raises
    ------
    InvalidInputError
        ``<path>: cannot read <what> (<reason>)``, ``<path>: <not_text>`` or
        ``<path>: <not_parsed> (<parser's words>)``.
    """
    file = Path(path)
    try:
        text = file.read_text(encoding='utf-8')
    except OSError as error:
        raise InvalidInputError(f'{file}: cannot read {what} ({error.strerror})') from None
    except UnicodeDecodeError as error:
        if not_text is not None:
            words = not_text.format(reason=error.reason, start=error.start)
            raise InvalidInputError(f'{file}: {words}') from None
        raise InvalidInputError(f'{file}: {not_parsed} ({error})') from None
    try:
        return parse(text)
    except parse_errors as error:
        raise InvalidInputError(f'{file}: {not_parsed} ({error})') from None
