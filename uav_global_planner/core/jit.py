"""Optional numba compilation of the hot loops.

:func:`njit` compiles a function with ``numba.njit(cache=True, nogil=True)`` when numba imports
and the environment variable ``UAV_PLANNER_DISABLE_JIT`` is not ``1``. Otherwise it returns the
function unchanged, so the very same source is the pure-Python fallback (slow, but it gives the
same results, which the tests check). ``nogil`` lets the ROS executor keep serving callbacks
while a search runs; ``cache`` keeps the compiled code on disk (``NUMBA_CACHE_DIR``) so only the
first run pays the compile time. :func:`compile_seconds` tells how long this process has spent
compiling, so a time budget can leave that one-off cost out.
"""

import os
import threading
import time
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


class _CompileClock:
    """Wall time spent in numba compilations (outermost ones: a kernel's callees compile
    within it), summed over the process [s]."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._depth = 0
        self._since = 0.0
        self.total_s = 0.0

    def on_start(self, event: Any) -> None:
        with self._lock:
            if self._depth == 0:
                self._since = time.perf_counter()
            self._depth += 1

    def on_end(self, event: Any) -> None:
        with self._lock:
            self._depth = max(self._depth - 1, 0)
            if self._depth == 0:
                self.total_s += time.perf_counter() - self._since


_CLOCK = _CompileClock()
if numba is not None:
    from numba.core import event as _event

    class _Listener(_event.Listener):
        def on_start(self, event: Any) -> None:
            _CLOCK.on_start(event)

        def on_end(self, event: Any) -> None:
            _CLOCK.on_end(event)

    _event.register('numba:compile', _Listener())


def compile_seconds() -> float:
    """Wall time this process has spent compiling kernels so far [s] (0 without numba).

    Compiled code is kept on disk, so this is a first-run cost: after an install, an upgrade or
    a change of the sources.
    """
    with _CLOCK._lock:
        return _CLOCK.total_s


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
