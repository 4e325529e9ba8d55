"""Interface packages built for this environment: their type hashes and their build.

A ROS 2 client and server only talk when the RIHS01 type hashes of their interfaces agree;
:func:`compiled_type_hash` reads the hash of a message, service or action type from its
generated C type support, as rclpy's own type support sees it.
:func:`assert_build_is_current` runs ``scripts/build_interfaces.sh`` again, which must find
nothing to do.
"""

import ctypes
from pathlib import Path
import subprocess
import sys
from typing import Dict, Mapping, Tuple

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]


class _TypeHash(ctypes.Structure):
    """``rosidl_type_hash_t``: a version byte and 32 bytes of SHA-256."""

    _fields_ = [('version', ctypes.c_uint8), ('value', ctypes.c_uint8 * 32)]


def prefix_of(module) -> Path:
    """Install prefix of a ROS Python package (``<prefix>/lib/pythonX.Y/site-packages/<pkg>``)."""
    return Path(module.__file__).resolve().parents[4]


def compiled_type_hash(type_name: str, prefix: Path) -> str:
    """The RIHS01 hash the compiled C type support of ``type_name`` reports.

    Parameters
    ----------
    type_name : str
        For example ``'nav2_msgs/action/ComputePathToPose_Goal'``.
    prefix : Path
        Install prefix holding ``lib/lib<package>__rosidl_generator_c.so``.
    """
    package, kind, name = type_name.split('/')
    library = ctypes.CDLL(str(prefix / 'lib' / f'lib{package}__rosidl_generator_c.so'))
    function = getattr(library, f'{package}__{kind}__{name}__get_type_hash')
    function.restype = ctypes.POINTER(_TypeHash)
    function.argtypes = [ctypes.c_void_p]
    found = function(None).contents
    return f'RIHS{found.version:02d}_' + bytes(found.value).hex()


def hash_differences(module, expected: Mapping[str, str]) -> Dict[str, Tuple[str, str]]:
    """The types of ``expected`` whose compiled hash differs, as ``{name: (built, expected)}``.

    Parameters
    ----------
    module : module
        The ROS Python package of the types (its install prefix holds their C type support).
    expected : mapping of str to str
        Type name to its expected RIHS01 hash.
    """
    prefix = prefix_of(module)
    found = {name: compiled_type_hash(name, prefix) for name in expected}
    return {name: (found[name], expected[name]) for name in found
            if found[name] != expected[name]}


def assert_build_is_current(package: str) -> None:
    """``scripts/build_interfaces.sh`` returns at once, silent, when ``package`` is built and
    unchanged (skipped where the package does not come from it)."""
    if not (Path(sys.prefix) / f'.{package}.sha256').is_file():
        pytest.skip(f'{package} does not come from scripts/build_interfaces.sh here')
    run = subprocess.run(['bash', str(REPO_ROOT / 'scripts' / 'build_interfaces.sh'),
                          sys.prefix], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    assert run.stdout == '' and run.stderr == '', (run.stdout, run.stderr)
