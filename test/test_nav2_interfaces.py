"""The nav2_msgs planner actions this environment provides are Nav2 Jazzy's, hash for hash.

In the project's venv they come from ``interfaces/nav2_msgs`` (built by
``scripts/build_interfaces.sh``); on a ROS 2 Jazzy install from the system's nav2_msgs. Either
way a Nav2 client (a behaviour tree, ``nav2_simple_commander``) only talks to the planner when
the RIHS01 type hashes agree, so the compiled C type support is asked for its hashes and they
are compared with those of a real Jazzy build.

Where the reference hashes come from: the generated C sources of nav2_msgs in two public colcon
workspaces built against ``/opt/ros/jazzy`` (their CMakeCache.txt names it) from the Jazzy
sources, whose action definitions have the fields of the navigation2 ``jazzy`` branch
(``PoseStamped[] goals``, ``string error_msg``):

- Rudijs20/tb4_testing_workspace, commit e65df8213955ffc620e2e54ab2c8b8728bf537ac,
  ``build/nav2_msgs/rosidl_generator_c/nav2_msgs/action/detail/
  compute_path_to_pose__description.c`` and ``compute_path_through_poses__description.c``: every
  value below (the ``*_get_type_hash`` byte arrays, and the ``*__EXPECTED_HASH`` arrays of the
  referenced types), transcribed by hand;
- Santos-Enoque/bumperbot, commit 72234bcc66937e885929d68568e99e4a98562775, same path: the same
  ComputePathThroughPoses hashes.

A Kilted/Rolling build (where ComputePathThroughPoses takes ``nav_msgs/Goals``) has the same
ComputePathToPose hashes and different ComputePathThroughPoses ones, as expected.
"""

from pathlib import Path
import shutil
import subprocess
import sys
from typing import Dict

from catkin_pkg.packages import find_packages
from helpers.interface_packages import (assert_build_is_current, compiled_type_hash,
                                        hash_differences, prefix_of)
import pytest

from uav_global_planner.core import status

try:
    import nav2_msgs
    from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose
except ImportError as error:  # pragma: no cover - the message is the point
    raise ImportError(
        f'nav2_msgs is not importable ({error}): in the venv, scripts/venv.sh builds it with '
        'scripts/build_interfaces.sh; on a ROS install, install ros-jazzy-nav2-msgs') from None

#: RIHS01 hashes of Nav2 Jazzy's planner actions and of the types they reference (see above).
JAZZY_TYPE_HASHES: Dict[str, str] = {
    'nav2_msgs/action/ComputePathToPose':
        'RIHS01_b11d50c914791956069419b8f4ad441e3c66fcfbd9461f8e87110b77dc6febe9',
    'nav2_msgs/action/ComputePathToPose_Goal':
        'RIHS01_9b2a136db06950716ad4a46b9d01bb628703cad155650c0b8233fb6a2f2783fa',
    'nav2_msgs/action/ComputePathToPose_Result':
        'RIHS01_7178b0d4da2f4d4243f3b95db1051384e4fdd2226a14518f04547b13cdfa0253',
    'nav2_msgs/action/ComputePathToPose_Feedback':
        'RIHS01_65f211af92621424a97b9f54224f75c04e748d9b998115a39f6f03a684e01f1b',
    'nav2_msgs/action/ComputePathToPose_SendGoal':
        'RIHS01_e800806a220935f225495784663dfdd78b509335309a5127ed1112f6ce6b9dbc',
    'nav2_msgs/action/ComputePathToPose_SendGoal_Request':
        'RIHS01_7febfe253154b28fa86ff7badebe59ddfb79829c86485903efd19884a73e178e',
    'nav2_msgs/action/ComputePathToPose_SendGoal_Response':
        'RIHS01_5bf8211084a19dc1b677915e75d6752a72c1e0cf0b2beede2f49c578b7865e35',
    'nav2_msgs/action/ComputePathToPose_SendGoal_Event':
        'RIHS01_ba2a385bc719b327e8554d8783ae1d9d7e03fc31fa38984517a9a6d3f2017ae1',
    'nav2_msgs/action/ComputePathToPose_GetResult':
        'RIHS01_386ab12c2f62a441596ef1140b3beca654a957eaac87e769c10de01b0e28208f',
    'nav2_msgs/action/ComputePathToPose_GetResult_Request':
        'RIHS01_4b6daec66100272fa48786b26682982c6de4166bd2b1a061e47ccd9a6bd7bbb1',
    'nav2_msgs/action/ComputePathToPose_GetResult_Response':
        'RIHS01_f278e880ee5e06bc9498152d76991cc90096b0265f1b1e1234baf23f395ce1d5',
    'nav2_msgs/action/ComputePathToPose_GetResult_Event':
        'RIHS01_ce985eeed9162bddc8042de0c87d3d83ece12fb19b45ef45123879e5c0ec0a02',
    'nav2_msgs/action/ComputePathToPose_FeedbackMessage':
        'RIHS01_a086c8f040554ab5883b433bded128a1d1a732d21ca57596b7fdbe7ad2d0b64a',
    'nav2_msgs/action/ComputePathThroughPoses':
        'RIHS01_bb3cde2342f7eadfe65ed4dff5253edc37e44ae14a3fcee77272d7fef552440c',
    'nav2_msgs/action/ComputePathThroughPoses_Goal':
        'RIHS01_ef05acd91e1bfc92608d564d649d666d8bd7ff84fdea0b5a006a1172320d2bae',
    'nav2_msgs/action/ComputePathThroughPoses_Result':
        'RIHS01_9b1b12c2ed2f27b2a8e4a657b944180b3ce4cdb6798f4d0eefd9a5b739f233a6',
    'nav2_msgs/action/ComputePathThroughPoses_Feedback':
        'RIHS01_ee7ba8f81f423e6137f20fcb93da27e9bb7166b7b3c07fedd2bce0ef23b5ff38',
    'nav2_msgs/action/ComputePathThroughPoses_SendGoal':
        'RIHS01_6aac5f4ea44b023b4c4685ee022298a76e8a1671f27ab488adf2ac4efecfca9d',
    'nav2_msgs/action/ComputePathThroughPoses_SendGoal_Request':
        'RIHS01_dbdd127d3da1f01300f279d2484bf5a88d77cba10fceca88710bb0377efd1dc3',
    'nav2_msgs/action/ComputePathThroughPoses_SendGoal_Response':
        'RIHS01_c13064c3215ec29e84c0eda2f52e242423a7b92d713a9aa685746a2c598061ea',
    'nav2_msgs/action/ComputePathThroughPoses_SendGoal_Event':
        'RIHS01_6c3255ec405e845faab70c4e99b4ab843f3edc846003c9cf443ea54c3bee9224',
    'nav2_msgs/action/ComputePathThroughPoses_GetResult':
        'RIHS01_86b86db67d57ff222084ff1ac42e5357fdf8597973b36000e15e01ad43a9fdf7',
    'nav2_msgs/action/ComputePathThroughPoses_GetResult_Request':
        'RIHS01_b44d1f4a9e53c39840aa68d6539c0bd06b63f63c4a60bd554d2edf86aec4de9a',
    'nav2_msgs/action/ComputePathThroughPoses_GetResult_Response':
        'RIHS01_70d89be6b071711328338621fab174401490b8f0e347d359866a3aec8c33a327',
    'nav2_msgs/action/ComputePathThroughPoses_GetResult_Event':
        'RIHS01_9194ffd502c95ddfb64dc3ce39e77006dcb46dd24fb7c59b15e092f649c49dbd',
    'nav2_msgs/action/ComputePathThroughPoses_FeedbackMessage':
        'RIHS01_b04e85195fb2c41edab60868657632fa95d11e9ae69792ca2a1df9de4fbc5521',
}

#: The referenced types as the Jazzy build expected them: when one of these differs here, the
#: action hashes cannot match either, and this says which dependency is to blame.
JAZZY_DEPENDENCY_HASHES: Dict[str, str] = {
    'builtin_interfaces/msg/Duration':
        'RIHS01_e8d009f659816f758b75334ee1a9ca5b5c0b859843261f14c7f937349599d93b',
    'geometry_msgs/msg/PoseStamped':
        'RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8',
    'nav_msgs/msg/Path':
        'RIHS01_1957a5bb3cee5da65c4e52e52b65a93df227efce4c20f8458b36e73066ca334b',
    'std_msgs/msg/Header':
        'RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01',
    'service_msgs/msg/ServiceEventInfo':
        'RIHS01_41bcbbe07a75c9b52bc96bfd5c24d7f0fc0a08c0cb7921b3373c5732345a6f45',
    'unique_identifier_msgs/msg/UUID':
        'RIHS01_1b8e8aca958cbea28fe6ef60bf6c19b683c97a9ef60bb34752067d0f2f7ab437',
}

REPO_ROOT = Path(__file__).resolve().parents[1]
INTERFACE_PACKAGE = REPO_ROOT / 'interfaces' / 'nav2_msgs'


def test_dependency_hashes_equal_those_of_the_jazzy_build():
    import builtin_interfaces
    prefix = prefix_of(builtin_interfaces)
    found = {name: compiled_type_hash(name, prefix) for name in JAZZY_DEPENDENCY_HASHES}
    assert found == JAZZY_DEPENDENCY_HASHES


def test_built_action_hashes_equal_nav2_jazzy():
    wrong = hash_differences(nav2_msgs, JAZZY_TYPE_HASHES)
    assert not wrong, f'type hashes differ from Nav2 Jazzy (built, expected): {wrong}'


def test_goal_and_result_fields_are_nav2s():
    assert ComputePathToPose.Goal.get_fields_and_field_types() == {
        'goal': 'geometry_msgs/PoseStamped', 'start': 'geometry_msgs/PoseStamped',
        'planner_id': 'string', 'use_start': 'boolean'}
    assert ComputePathThroughPoses.Goal.get_fields_and_field_types() == {
        'goals': 'sequence<geometry_msgs/PoseStamped>', 'start': 'geometry_msgs/PoseStamped',
        'planner_id': 'string', 'use_start': 'boolean'}
    result = {'path': 'nav_msgs/Path', 'planning_time': 'builtin_interfaces/Duration',
              'error_code': 'uint16', 'error_msg': 'string'}
    assert ComputePathToPose.Result.get_fields_and_field_types() == result
    assert ComputePathThroughPoses.Result.get_fields_and_field_types() == result


def test_error_codes_are_nav2s_and_the_cores():
    # Constants are not part of the type hash, so they are checked one by one.
    to_pose = ComputePathToPose.Result
    codes = {'NONE': 0, 'UNKNOWN': 200, 'INVALID_PLANNER': 201, 'TF_ERROR': 202,
             'START_OUTSIDE_MAP': 203, 'GOAL_OUTSIDE_MAP': 204, 'START_OCCUPIED': 205,
             'GOAL_OCCUPIED': 206, 'TIMEOUT': 207, 'NO_VALID_PATH': 208}
    assert {name: getattr(to_pose, name) for name in codes} == codes
    through = ComputePathThroughPoses.Result
    through_codes = {name: (value + 100 if value else 0) for name, value in codes.items()}
    through_codes['NO_VIAPOINTS_GIVEN'] = 309
    assert {name: getattr(through, name) for name in through_codes} == through_codes
    # The core's table (diagnostics, command-line tool) uses the same numbers.
    assert {name: getattr(status, f'NAV2_{name}') for name in codes} == codes


def test_interface_package_is_invisible_to_workspace_tools(tmp_path):
    # rosdep and colcon's ROS identification use catkin_pkg: the repository holds one package.
    assert [package.name for package in find_packages(str(REPO_ROOT)).values()] == [
        'uav_global_planner']
    colcon = shutil.which('colcon', path=str(Path(sys.executable).parent)) or shutil.which(
        'colcon')
    if colcon is None:
        pytest.skip('colcon is not installed')

    def listed(base: Path) -> str:
        run = subprocess.run([colcon, '--log-base', str(tmp_path / 'log'), 'list', '--names-only',
                              '--base-paths', str(base)], capture_output=True, text=True,
                             timeout=120, cwd=tmp_path)
        assert run.returncode == 0, run.stderr
        return run.stdout.split()

    assert listed(REPO_ROOT / 'interfaces') == []
    # The markers are what hides it: a copy without them is found.
    copy = tmp_path / 'unmarked' / 'nav2_msgs'
    shutil.copytree(INTERFACE_PACKAGE, copy,
                    ignore=shutil.ignore_patterns('COLCON_IGNORE', 'AMENT_IGNORE'))
    assert listed(copy.parent) == ['nav2_msgs']


def test_build_script_returns_at_once_when_nothing_changed():
    assert_build_is_current('nav2_msgs')
