"""Changed copies of YAML documents (scenes, geofences), for tests of refused keys."""

import copy
from typing import Any, Sequence


def changed(document: Any, path: Sequence[Any], value: Any) -> Any:
    """A deep copy of ``document`` with the entry at ``path`` (keys and list indexes) set to
    ``value``, or removed when ``value`` is ``KeyError``."""
    data = copy.deepcopy(document)
    *parents, last = path
    target = data
    for key in parents:
        target = target[key]
    if value is KeyError:
        del target[last]
    else:
        target[last] = value
    return data
