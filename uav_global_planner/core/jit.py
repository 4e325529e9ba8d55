"""Optional numba compilation of the hot loops.

:func:`njit` compiles a function with ``numba.njit(cache=True, nogil=True)`` when numba imports
and the environment variable ``UAV_PLANNER_DISABLE_JIT`` is not ``1``. Otherwise it returns the
function unchanged, so the very same source is the pure-Python fallback (slow, but it gives the
same results, which the tests check). ``nogil`` lets the ROS executor keep serving callbacks
while a search runs; ``cache`` keeps the compiled code on disk (``NUMBA_CACHE_DIR``) so only the
first run pays the compile time.
"""

import os
from types import ModuleType
from typing import Any, Callable, Dict, Optional

_DISABLED = os.environ.get('UAV_PLANNER_DISABLE_JIT', '') == '1'

numba: Optional[ModuleType]
try:
    if _DISABLED:
        raise ImportError('disabled by UAV_PLANNER_DISABLE_JIT=1')
    import numba
except ImportError:
    numba = None

#: True when functions decorated with :func:`njit` are compiled by numba.
JIT_ENABLED: bool = numba is not None


def njit(func: Optional[Callable] = None, **options: Any) -> Any:
    """Compile ``func`` in nopython mode when the JIT is enabled, else return it unchanged.

    Usable bare (``@njit``) or with numba options (``@njit(fastmath=False)``); the options
    override the defaults ``cache=True, nogil=True`` and are ignored without the JIT.
    """
    def decorate(function: Callable) -> Callable:
        if numba is None:
            return function
        settings: Dict[str, Any] = {'cache': True, 'nogil': True}
        settings.update(options)
        return numba.njit(**settings)(function)

    if func is None:
        return decorate
    return decorate(func)
