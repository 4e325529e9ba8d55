"""ROS domain ids that no other ROS system on this machine is using.

A domain counts as in use while a DDS participant holds one of its discovery ports. DDS maps
domain ``d`` and participant ``p`` to fixed UDP ports (the RTPS standard port mapping, which
Fast DDS uses, and Cyclone DDS with localhost discovery): ``7400 + 250 d`` for multicast
discovery and ``7410 + 250 d + 2 p`` for unicast discovery. Trying to bind those ports answers
at once, without joining the domain.
"""

import errno
import os
import socket
from typing import Iterable, Iterator, Optional

#: Domain ids that are safe on Linux with the standard port mapping (the others reach into the
#: ephemeral port range or past port 65535). 0, everyone's default, is not among them.
SAFE_DOMAIN_IDS = tuple(range(1, 102)) + tuple(range(215, 233))

_PORT_BASE = 7400
_DOMAIN_GAIN = 250
_PARTICIPANT_GAIN = 2
_UNICAST_OFFSET = 10
# Participants per domain looked for: one per ROS process (a context), numbered from 0.
_PARTICIPANTS = 32


def discovery_ports(domain_id: int) -> Iterator[int]:
    """UDP discovery ports of ``domain_id``: multicast, then unicast of participants 0, 1, ..."""
    base = _PORT_BASE + _DOMAIN_GAIN * domain_id
    yield base
    for participant in range(_PARTICIPANTS):
        yield base + _UNICAST_OFFSET + _PARTICIPANT_GAIN * participant


def _port_taken(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.bind(('', port))
        except OSError as error:
            return error.errno == errno.EADDRINUSE
    return False


def domain_in_use(domain_id: int) -> bool:
    """True when a DDS participant of ``domain_id`` runs on this machine (see the module)."""
    return any(_port_taken(port) for port in discovery_ports(domain_id))


def candidate_domains(start: Optional[int] = None) -> Iterator[int]:
    """Every safe domain id once, from ``start`` on (the first safe id >= ``start``, wrapping).

    Parameters
    ----------
    start : int, optional
        Default: a point derived from the process id, so that two processes rarely begin at
        the same id.
    """
    count = len(SAFE_DOMAIN_IDS)
    if start is None:
        first = (os.getpid() * 7919) % count
    else:
        first = next((i for i, d in enumerate(SAFE_DOMAIN_IDS) if d >= start), 0)
    for offset in range(count):
        yield SAFE_DOMAIN_IDS[(first + offset) % count]


def free_domain_id(start: Optional[int] = None, avoid: Iterable[int] = ()) -> int:
    """The first domain id of :func:`candidate_domains` that is not in use nor in ``avoid``.

    Raises
    ------
    RuntimeError
        When every safe domain id is taken.
    """
    avoided = set(avoid)
    for domain_id in candidate_domains(start):
        if domain_id not in avoided and not domain_in_use(domain_id):
            return domain_id
    raise RuntimeError('every safe ROS domain id is in use on this machine')


def choose_domain_id(explicit: Optional[int] = None) -> int:
    """The ROS domain of a tool that starts its own nodes: ``explicit`` if given, else a free
    one (:func:`free_domain_id`) that is not ``$ROS_DOMAIN_ID`` either, so the tool keeps out
    of the user's ROS graph.

    Raises
    ------
    RuntimeError
        When every safe domain id is in use.
    """
    if explicit is not None:
        return explicit
    user_domain = environment_domain_id()
    return free_domain_id(avoid=[] if user_domain is None else [user_domain])


def environment_domain_id() -> Optional[int]:
    """``$ROS_DOMAIN_ID`` as a number, or None when unset or not a number."""
    text = os.environ.get('ROS_DOMAIN_ID', '').strip()
    return int(text) if text.isdigit() else None
