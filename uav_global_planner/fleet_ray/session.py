"""Starting and joining Ray: an embedded local cluster by default, an existing one by address.

:func:`ray_session` is a context manager around ``ray.init`` / ``ray.shutdown``:

- without an address it starts Ray inside this process with ``num_cpus`` CPUs, no dashboard,
  and, when the environment says nothing about Ray's token authentication, a fresh token kept
  in this process's environment only (``RAY_AUTH_MODE=token``, ``RAY_AUTH_TOKEN``), so a run
  writes nothing into the home folder;
- with an address (``auto``, ``HOST:PORT`` or ``ray://HOST:PORT``) it joins that cluster, whose
  token is the cluster's business (``RAY_AUTH_TOKEN`` or ``~/.ray/auth_token`` as Ray reads it);
- when Ray is already running in this process (a test, a notebook) it uses it and leaves it
  running.
"""

from contextlib import contextmanager
from dataclasses import dataclass
import os
import secrets
import socket
from typing import Any, Dict, Iterator, Optional

from uav_global_planner.core.errors import InvalidInputError, MissingDependencyError

# Environment variables Ray reads for its token authentication.
_AUTH_VARIABLES = ('RAY_AUTH_MODE', 'RAY_AUTH_TOKEN', 'RAY_AUTH_TOKEN_PATH')


def import_ray() -> Any:
    """The ``ray`` module.

    Raises
    ------
    MissingDependencyError
        When Ray is not installed; the message names the pip package and the extra.
    """
    try:
        import ray
    except ImportError:
        raise MissingDependencyError(
            "planning a fleet on Ray needs the Python package 'ray', which is not installed: "
            'pip install ray (or pip install uav_global_planner[fleet])') from None
    return ray


@dataclass(frozen=True)
class SessionInfo:
    """What :func:`ray_session` connected to.

    Attributes
    ----------
    address : str
        The cluster's address (the GCS), ``local`` for an embedded cluster.
    embedded : bool
        True when this process started the cluster (and shuts it down at the end).
    nodes : int
        Nodes alive when connected.
    cpus : float
        CPUs the cluster offers.
    """

    address: str
    embedded: bool
    nodes: int
    cpus: float


@contextmanager
def ray_session(address: Optional[str] = None, num_cpus: Optional[int] = None,
                temp_dir: Optional[str] = None) -> Iterator[SessionInfo]:
    """Ray for the duration of a ``with`` block.

    Parameters
    ----------
    address : str, optional
        A running cluster to join (``auto``, ``HOST:PORT``, ``ray://HOST:PORT``); None starts
        an embedded local cluster.
    num_cpus : int, optional
        CPUs of the embedded cluster (default: this machine's); ignored when joining.
    temp_dir : str, optional
        Folder for the embedded cluster's sockets, logs and spilled objects (default Ray's,
        ``/tmp/ray``). Unix socket paths are limited to about 100 characters: keep it short.

    Yields
    ------
    SessionInfo

    Raises
    ------
    InvalidInputError
        For ``num_cpus`` < 1, or a cluster that cannot be reached (the message names the
        address).
    MissingDependencyError
        When Ray is not installed.
    """
    ray = import_ray()
    if num_cpus is not None and num_cpus < 1:
        raise InvalidInputError(f'num_cpus must be >= 1, got {num_cpus}')
    if ray.is_initialized():
        yield _info(ray, 'running', False)
        return
    saved = {name: os.environ.get(name) for name in _AUTH_VARIABLES}
    options: Dict[str, Any] = {'include_dashboard': False, 'configure_logging': False,
                               'log_to_driver': False}
    if address is None:
        if all(value is None for value in saved.values()):
            # Token authentication, the token in this process's environment only (workers
            # inherit it); nothing is written to ~/.ray.
            os.environ['RAY_AUTH_MODE'] = 'token'
            os.environ['RAY_AUTH_TOKEN'] = secrets.token_hex(32)
            _reload_ray_config()
        options['num_cpus'] = num_cpus
        if temp_dir is not None:
            options['_temp_dir'] = str(temp_dir)
    else:
        _check_reachable(address)
        options['address'] = address
    try:
        try:
            ray.init(**options)
        except (ConnectionError, RuntimeError, ValueError) as error:
            where = 'an embedded cluster' if address is None else f'the cluster at {address}'
            raise InvalidInputError(f'--address: cannot start or join {where}: {error}'
                                    if address is not None else
                                    f'cannot start {where}: {error}') from None
        try:
            yield _info(ray, 'local' if address is None else address, address is None)
        finally:
            ray.shutdown()
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        _reload_ray_config()


def _check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Refuse a ``HOST:PORT`` (or ``ray://HOST:PORT``) nobody answers on within
    ``timeout_s`` [s], instead of letting Ray retry for minutes; ``auto`` is left to Ray."""
    target = address.split('://', 1)[-1]
    host, _, port = target.rpartition(':')
    if not host or not port.isdigit():
        if address != 'auto':
            raise InvalidInputError(f'--address must be auto, HOST:PORT or ray://HOST:PORT, '
                                    f'got {address!r}')
        return
    try:
        with socket.create_connection((host, int(port)), timeout=timeout_s):
            pass
    except OSError as error:
        raise InvalidInputError(f'--address {address}: no Ray cluster answers there '
                                f'({error.strerror or error}); start one with ray start '
                                '--head, or leave --address out to run on this machine') from None


def _reload_ray_config() -> None:
    """Make this process's Ray read the authentication variables again (Ray reads them once
    and caches the token; its own ``ray.init`` refreshes them the same way when it turns token
    authentication on)."""
    try:
        from ray._raylet import (AuthenticationTokenLoader,  # type: ignore[attr-defined]
                                 Config)
    except ImportError:  # a Ray without them reads the environment at ray.init
        return
    Config.initialize('')
    AuthenticationTokenLoader.instance().reset_cache()


def _info(ray: Any, address: str, embedded: bool) -> SessionInfo:
    nodes = [node for node in ray.nodes() if node.get('Alive')]
    return SessionInfo(address=address, embedded=embedded, nodes=len(nodes),
                       cpus=float(ray.cluster_resources().get('CPU', 0.0)))
