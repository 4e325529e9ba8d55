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

When: numba is imported at the first call of a kernel, not when a module defining kernels is
imported (numba takes 0.3-1 s to import), so a program reads its options and its input first.
Until then :func:`njit` hands out lazy kernels; the first call makes the dispatchers of every
kernel decorated so far and puts them in place of the lazy ones in the modules that hold them,
so that compiled code calling another kernel finds its dispatcher.
"""

import functools
import importlib.util
import os
import sys
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
    # Read by numba when it is imported (by _import_numba, or earlier by another module: then
    # numba.config is set as well, there).
    os.environ[CACHE_ENV] = default_cache_dir()


def _numba_installed() -> bool:
    """True when numba can be imported (found, not disabled), without importing it."""
    if _DISABLED:
        return False
    if 'numba' in sys.modules:
        return True
    try:
        return importlib.util.find_spec('numba') is not None
    except (ImportError, ValueError):
        return False


#: True when functions decorated with :func:`njit` are compiled by numba.
JIT_ENABLED: bool = _numba_installed()

#: numba, once the first kernel call imported it (None before, and without the JIT).
numba: Optional[ModuleType] = None

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
# Guards the import of numba and the making of the dispatchers (a kernel may first be called
# on two threads at once).
_LOCK = threading.RLock()


#: What numba's array functions import to find a BLAS for np.dot.
_BLAS = 'scipy.linalg.cython_blas'


def _import_numba() -> Optional[ModuleType]:
    """numba, imported on first use with its cache folder and the compile clocks set (None
    without the JIT, or when numba fails to import: the kernels then run as Python)."""
    global numba, JIT_ENABLED
    with _LOCK:
        if numba is not None or not JIT_ENABLED:
            return numba
        # numba imports coverage (0.1-0.3 s) to report compiled lines to a running measurement;
        # one runs only when coverage was imported already. Its array functions import
        # scipy.linalg (0.2-0.3 s) only to see whether np.dot may call BLAS, which no kernel
        # here does (without it, np.dot would be a plain loop).
        hidden = [name for name in ('coverage', _BLAS) if name not in sys.modules]
        for name in hidden:
            sys.modules[name] = None  # type: ignore[assignment]
        try:
            import numba as module
            from numba.core import event
            from numba.extending import typeof_impl
            import numba.np.arraymath  # noqa: F401 - imported here, with scipy.linalg hidden
        except ImportError:
            JIT_ENABLED = False
            return None
        finally:
            for name in hidden:
                if sys.modules.get(name, 0) is None:
                    del sys.modules[name]
        config: Any = module.config
        if not config.CACHE_DIR:
            # numba was imported before this module, without NUMBA_CACHE_DIR.
            config.CACHE_DIR = os.environ[CACHE_ENV]

        class _Listener(event.Listener):
            # The one-off clock encloses the compile clock, so one_off_seconds() never falls
            # short of compile_seconds() over the same compilations.
            def on_start(self, event: Any) -> None:
                _ONE_OFF.on_start(event)
                _CLOCK.on_start(event)

            def on_end(self, event: Any) -> None:
                _CLOCK.on_end(event)
                _ONE_OFF.on_end(event)

        # Fired for compilations only, not for kernels loaded from the cache.
        event.register('numba:compile', _Listener())

        @typeof_impl.register(_LazyKernel)
        def _typeof_lazy(value: '_LazyKernel', context: Any) -> Any:
            # A lazy kernel held where the swap does not reach (a container, a class), seen
            # by compiled code: the type of its dispatcher.
            return module.typeof(value.dispatcher(), context.purpose)

        numba = module
        return numba


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
    """Count the dispatcher's specialising in :func:`one_off_seconds`: each new argument
    type's compilation or load from the cache, with numba's work around it (type resolution,
    the new overload's entry point)."""
    compile_ = getattr(dispatcher, 'compile', None)
    if compile_ is None:
        return

    def timed_compile(*args: Any, **kwargs: Any) -> Any:
        _ONE_OFF.on_start(None)
        try:
            return compile_(*args, **kwargs)
        finally:
            _ONE_OFF.on_end(None)

    dispatcher.compile = timed_compile


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
    if not JIT_ENABLED:
        return None
    if numba is None:  # not imported yet: it will read the environment's value
        return os.environ.get(CACHE_ENV) or None
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


class _LazyKernel:
    """A kernel whose dispatcher is made at the first call of any kernel (numba imported then).

    Called, or asked for a dispatcher's attribute (``signatures``, ``stats``), it makes the
    dispatchers of every kernel decorated so far (:func:`_make_dispatchers`). ``py_func`` is
    the Python function, as on a dispatcher.
    """

    def __init__(self, function: Callable, settings: Dict[str, Any]) -> None:
        self._target: Optional[Callable] = None
        self._settings = settings
        self.py_func = function
        functools.update_wrapper(self, function)

    def dispatcher(self) -> Callable:
        """The dispatcher (the Python function when numba failed to import)."""
        if self._target is None:
            _make_dispatchers()
        assert self._target is not None
        return self._target

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.dispatcher()(*args, **kwargs)

    def __getattr__(self, name: str) -> Any:
        # Only for names the kernel does not have itself: the dispatcher's.
        if name.startswith('__') or name == '_target':
            raise AttributeError(name)
        return getattr(self.dispatcher(), name)

    def __repr__(self) -> str:
        return f'<kernel {self.__qualname__}>'


# Lazy kernels whose dispatchers are not made yet.
_PENDING: List[_LazyKernel] = []


def _dispatcher(function: Callable, settings: Dict[str, Any]) -> Callable:
    """numba's dispatcher of ``function``, counted in :func:`kernel_counts` and the clocks."""
    assert numba is not None
    dispatcher = numba.njit(**settings)(function)
    _time_cache_loads(dispatcher)
    _DISPATCHERS.append(dispatcher)
    return dispatcher


def _make_dispatchers() -> None:
    """Import numba, make the dispatcher of every pending lazy kernel and put it in place of
    the kernel in every module that holds it (compiled code resolves its callees there).

    Counted in :func:`one_off_seconds`, as the loads from the cache: once per process.
    """
    _ONE_OFF.on_start(None)
    try:
        _make_pending()
    finally:
        _ONE_OFF.on_end(None)


def _make_pending() -> None:
    with _LOCK:
        module = _import_numba()
        made = 0
        try:
            # One by one: a kernel numba refuses (its source file gone, say) raises here, as
            # at its definition, and leaves the others pending for the next call.
            while _PENDING:
                kernel = _PENDING[0]
                kernel._target = (kernel.py_func if module is None
                                  else _dispatcher(kernel.py_func, kernel._settings))
                _PENDING.pop(0)
                made += 1
        finally:
            if made:
                _swap_made()


def _swap_made() -> None:
    """Put the dispatchers made in place of their lazy kernels, in every module."""
    with _LOCK:
        for loaded in list(sys.modules.values()):
            names = getattr(loaded, '__dict__', None)
            if not isinstance(names, dict):
                continue
            for name, value in list(names.items()):
                if type(value) is _LazyKernel and value._target is not None:
                    names[name] = value._target


def njit(func: Optional[Callable] = None, **options: Any) -> Any:
    """Compile ``func`` in nopython mode when the JIT is enabled, else return it unchanged.

    Usable bare (``@njit``) or with numba options (``@njit(fastmath=False)``); the options
    override the defaults ``cache=True, nogil=True`` and are ignored without the JIT. Before
    the first kernel call the result is a lazy kernel (see the module's docstring), after it
    numba's dispatcher.
    """
    def decorate(function: Callable) -> Callable:
        if not JIT_ENABLED:
            return function
        settings: Dict[str, Any] = {'cache': True, 'nogil': True}
        settings.update(options)
        with _LOCK:
            if numba is not None:
                return _dispatcher(function, settings)
            kernel = _LazyKernel(function, settings)
            _PENDING.append(kernel)
            return kernel

    if func is None:
        return decorate
    return decorate(func)
