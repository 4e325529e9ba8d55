"""Optional numba compilation of the hot loops, and where the compiled code is kept.

:func:`njit` compiles a function with ``numba.njit(cache=True, nogil=True)`` when numba imports
and the environment variable ``UAV_PLANNER_DISABLE_JIT`` is not ``1``. Otherwise it returns the
function unchanged, so the very same source is the pure-Python fallback (slow, but it gives the
same results, which the tests check). ``nogil`` lets the ROS executor keep serving callbacks
while a search runs; ``cache`` keeps the compiled code on disk so only the first run pays the
compile time.

Where: numba writes its cache beside the sources (``__pycache__``) unless ``NUMBA_CACHE_DIR``
names a folder, and beside the sources is not writable in a system or ROS install. So, before
numba is imported, this module sets ``NUMBA_CACHE_DIR`` (when the environment does not) to a
folder of the user: ``$XDG_CACHE_HOME/uav_global_planner/numba`` (``~/.cache/...`` without
``XDG_CACHE_HOME``); :func:`cache_dir` names it. Processes started from this one inherit it.

:func:`compile_seconds` tells how long this process has spent compiling, so a time budget can
leave that one-off cost out; :func:`on_next_compile` lets a program say why its first run
waits; :func:`kernel_counts` tells how many kernels were compiled and how many were loaded
from the cache.
"""

import os
import threading
import time
from types import ModuleType
from typing import Any, Callable, Dict, List, NamedTuple, Optional

#: The environment variable naming the folder of compiled kernels (numba's own).
CACHE_ENV = 'NUMBA_CACHE_DIR'

_DISABLED = os.environ.get('UAV_PLANNER_DISABLE_JIT', '') == '1'


def default_cache_dir() -> str:
    """The folder of compiled kernels when ``NUMBA_CACHE_DIR`` is not set: the user's cache
    folder (``$XDG_CACHE_HOME``, else ``~/.cache``) + ``uav_global_planner/numba``."""
    base = os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return os.path.join(base, 'uav_global_planner', 'numba')


if not os.environ.get(CACHE_ENV):
    # Read by numba when it is imported (just below, or earlier by another module: then
    # numba.config is set as well, further down).
    os.environ[CACHE_ENV] = default_cache_dir()

numba: Optional[ModuleType]
try:
    if _DISABLED:
        raise ImportError('disabled by UAV_PLANNER_DISABLE_JIT=1')
    import numba
except ImportError:
    numba = None

#: True when functions decorated with :func:`njit` are compiled by numba.
JIT_ENABLED: bool = numba is not None

if numba is not None and not numba.config.CACHE_DIR:
    # numba was imported before this module, without NUMBA_CACHE_DIR.
    numba.config.CACHE_DIR = os.environ[CACHE_ENV]

# Every dispatcher njit made, for kernel_counts().
_DISPATCHERS: List[Any] = []


class _CompileClock:
    """Wall time spent in numba compilations (outermost ones: a kernel's callees compile
    within it), summed over the process [s]; calls the first-compile callbacks once."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._depth = 0
        self._since = 0.0
        self.total_s = 0.0
        self.callbacks: List[Callable[[], None]] = []

    def on_start(self, event: Any) -> None:
        waiting: List[Callable[[], None]] = []
        with self._lock:
            if self._depth == 0:
                self._since = time.perf_counter()
                waiting, self.callbacks = self.callbacks, []
            self._depth += 1
        for callback in waiting:
            callback()

    def on_end(self, event: Any) -> None:
        with self._lock:
            self._depth = max(self._depth - 1, 0)
            if self._depth == 0:
                self.total_s += time.perf_counter() - self._since


_CLOCK = _CompileClock()
#: Compilations and loads from the cache together (nested ones counted once): the one-off work
#: of a process's first calls, which a time budget leaves out.
_ONE_OFF = _CompileClock()
if numba is not None:
    from numba.core import event as _event

    class _Listener(_event.Listener):
        # The one-off clock encloses the compile clock, so one_off_seconds() never falls
        # short of compile_seconds() over the same compilations.
        def on_start(self, event: Any) -> None:
            _ONE_OFF.on_start(event)
            _CLOCK.on_start(event)

        def on_end(self, event: Any) -> None:
            _CLOCK.on_end(event)
            _ONE_OFF.on_end(event)

    # Fired for compilations only, not for kernels loaded from the cache.
    _event.register('numba:compile', _Listener())


def compile_seconds() -> float:
    """Wall time this process has spent compiling kernels so far [s] (0 without numba).

    Compiled code is kept on disk (:func:`cache_dir`), so this is a first-run cost: after an
    install, an upgrade or a change of the sources (``uav-plan warmup`` pays it ahead).
    """
    with _CLOCK._lock:
        return _CLOCK.total_s


def one_off_seconds() -> float:
    """Wall time this process has spent compiling kernels or loading them from the cache [s].

    Both happen once per kernel and process: loading a cached kernel costs numba 5-400 ms (its
    first load sets up the compiler's registries), more on a loaded machine, so a time budget
    that counted it could refuse the first request of a process that compiles nothing.
    """
    with _ONE_OFF._lock:
        return _ONE_OFF.total_s


def _time_cache_loads(dispatcher: Any) -> None:
    """Count the dispatcher's loads from the cache in :func:`one_off_seconds`."""
    cache: Any = getattr(dispatcher, '_cache', None)
    load = getattr(cache, 'load_overload', None)
    if cache is None or load is None:
        return

    def timed_load(*args: Any, **kwargs: Any) -> Any:
        _ONE_OFF.on_start(None)
        try:
            return load(*args, **kwargs)
        finally:
            _ONE_OFF.on_end(None)

    cache.load_overload = timed_load


def on_next_compile(callback: Callable[[], None]) -> Callable[[], None]:
    """Call ``callback()`` once, when this process next starts compiling a kernel; never for
    kernels loaded from the cache. The callback runs on the compiling thread and must not
    raise.

    Returns
    -------
    callable
        Withdraws the callback if it has not run yet (a command that compiled nothing).
    """
    with _CLOCK._lock:
        _CLOCK.callbacks.append(callback)

    def withdraw() -> None:
        with _CLOCK._lock:
            if callback in _CLOCK.callbacks:
                _CLOCK.callbacks.remove(callback)
    return withdraw


def cache_dir() -> Optional[str]:
    """The folder compiled kernels are kept in (None without numba).

    ``NUMBA_CACHE_DIR`` as numba read it: the environment's value, else
    :func:`default_cache_dir`. numba falls back to ``__pycache__`` beside the sources when the
    folder cannot be created or written.
    """
    if numba is None:
        return None
    return str(numba.config.CACHE_DIR) or None


class KernelCounts(NamedTuple):
    """Specialisations of the kernels this process used so far.

    Attributes
    ----------
    compiled : int
        Compiled in this process (none were in the cache, or the sources changed).
    loaded : int
        Loaded from the cache (:func:`cache_dir`).
    """

    compiled: int
    loaded: int


def kernel_counts() -> KernelCounts:
    """How many kernel specialisations this process compiled and loaded from the cache
    (numba's dispatcher statistics; zeros without numba)."""
    compiled = loaded = 0
    for dispatcher in list(_DISPATCHERS):
        stats = dispatcher.stats
        compiled += sum(stats.cache_misses.values())
        loaded += sum(stats.cache_hits.values())
    return KernelCounts(compiled, loaded)


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
        dispatcher = numba.njit(**settings)(function)
        _time_cache_loads(dispatcher)
        _DISPATCHERS.append(dispatcher)
        return dispatcher

    if func is None:
        return decorate
    return decorate(func)
