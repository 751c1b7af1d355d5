"""Packaging for the apt ROS 2 path: every package.xml is one that `rosdep install --from-paths src
--ignore-src -y` resolves on Ubuntu 24.04 (ROS 2 Jazzy), and declares what its package's code uses.

Plain pytest, no ROS needed. What the code uses is read from the source: message types named as
'pkg/msg/Type' strings (message(...), get_message(...), type-name constants) or imported with
`from pkg.msg import ...`, and every imported module (ast). Third-party modules either map to a
checked rosdep key that the package must declare, or are pip-only (no key on Ubuntu 24.04) and must
then be in requirements-ros-apt.txt, the README's pip step for that path.
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from vizzy_runtime.testing import scaled

REPO = Path(__file__).resolve().parents[3]
PACKAGE_DIRS = sorted(p.parent for p in REPO.glob('src/*/package.xml')) + [REPO / 'msgs']
APT_PIP_REQUIREMENTS = REPO / 'requirements-ros-apt.txt'

# ROS 2 Jazzy packages the workspace depends on: rosdep resolves them from rosdistro's
# jazzy/distribution.yaml (apt ros-jazzy-*). `ament_python` is not one: it is a build type.
JAZZY_PACKAGES = frozenset({
    'ament_cmake', 'ament_index_python', 'builtin_interfaces', 'geometry_msgs', 'launch',
    'launch_ros', 'rcl_interfaces', 'rclpy', 'rmw_dds_common', 'rosgraph_msgs',
    'rosidl_default_generators', 'rosidl_default_runtime', 'sensor_msgs', 'std_msgs', 'tf2_msgs',
    'visualization_msgs', 'diagnostic_msgs', 'robot_state_publisher', 'rviz2',
    'vision_msgs',  # ros-jazzy-vision-msgs 4.1.1 (ros-perception/vision_msgs, jazzy branch)
})

# System rosdep keys, each checked in ros/rosdistro rosdep/python.yaml (stored copy at commit
# 000730dc5f916eb05b15d3f183bd1c17bf1b4722): every one maps `ubuntu:` to the apt package of the same
# name for all releases (python3-tqdm: '*', xenial null), so it resolves on noble. Not there for
# noble: torch (python3-torch has no noble entry; Ubuntu 24.04 has no python3-torch), mujoco, open3d
# (only the pip key python3-open3d-pip, which rosdep would run as a system pip install), motmetrics,
# rosbags, mcap, cyclonedds, zstandard, lz4: those are PIP_ONLY below.
ROSDEP_KEYS = frozenset({
    'python3-matplotlib', 'python3-numpy', 'python3-opencv', 'python3-pandas', 'python3-pytest',
    'python3-scipy', 'python3-tqdm', 'python3-xmltodict', 'python3-yaml',
})

# Imported module -> the rosdep key that provides it.
MODULE_KEYS = {
    'cv2': 'python3-opencv', 'matplotlib': 'python3-matplotlib', 'numpy': 'python3-numpy',
    'pandas': 'python3-pandas', 'pytest': 'python3-pytest', 'scipy': 'python3-scipy',
    'tqdm': 'python3-tqdm', 'xmltodict': 'python3-xmltodict', 'yaml': 'python3-yaml',
}

# Imported module -> its PyPI distribution, for modules without a rosdep key on Ubuntu 24.04.
PIP_ONLY = {
    'cyclonedds': 'cyclonedds', 'lz4': 'lz4', 'mcap': 'mcap', 'motmetrics': 'motmetrics',
    'mujoco': 'mujoco', 'open3d': 'open3d', 'rosbags': 'rosbags', 'torch': 'torch',
    'zstandard': 'zstandard', 'foxglove': 'foxglove-sdk', 'websockets': 'websockets',
    'efficientnet_lite_pytorch': 'efficientnet-lite-pytorch',
}

# Shared packages any package may use; every other workspace package is a node package, which
# imports no other node package (DESIGN: nodes are thin adapters over shared pieces).
SHARED = frozenset({'vizzy_runtime', 'vizzy_vision', 'active_vision_msgs'})
# What only training and data generation (<pkg>/training/) import: the simulated head (and the gaze
# controller's inverse kinematics, to render the head fixating an object as it would). Declared as
# a test dependency, so a robot that installs a perception node installs no simulator.
TRAINING_ONLY = frozenset({'vizzy_sim_bridge', 'mujoco', 'vizzy_gaze'})

# 'pkg/msg/Type' placeholders in docstrings and messages, not packages.
PLACEHOLDERS = frozenset({'pkg'})

MSG_STRING = re.compile(r'''['"]([a-z][a-z0-9_]*)/(?:msg|srv|action)/[A-Z][A-Za-z0-9_]*['"]''')
MSG_IMPORT = re.compile(r'^\s*from\s+([a-z][a-z0-9_]*)\.(?:msg|srv|action)\s+import\b', re.M)
DEP_TAGS = ('depend', 'build_depend', 'build_export_depend', 'buildtool_depend',
            'buildtool_export_depend', 'exec_depend', 'test_depend', 'doc_depend')


def _manifest(pkg_dir: Path) -> ET.Element:
    return ET.parse(pkg_dir / 'package.xml').getroot()


def _name(pkg_dir: Path) -> str:
    return _manifest(pkg_dir).findtext('name').strip()


WORKSPACE = frozenset(_name(d) for d in PACKAGE_DIRS)


def _deps(pkg_dir: Path, *tags: str) -> set[str]:
    root = _manifest(pkg_dir)
    return {e.text.strip() for tag in tags for e in root.findall(tag)}


def _exec_deps(pkg_dir: Path) -> set[str]:
    return _deps(pkg_dir, 'depend', 'exec_depend')


def _any_deps(pkg_dir: Path) -> set[str]:
    return _deps(pkg_dir, *DEP_TAGS)


def _dependents(name: str) -> set[str]:
    """Workspace packages that depend on `name`, directly or not (any dependency tag)."""
    deps = {_name(d): _any_deps(d) & WORKSPACE for d in PACKAGE_DIRS}
    found: set[str] = set()
    todo = [name]
    while todo:
        cur = todo.pop()
        for pkg, needs in deps.items():
            if cur in needs and pkg not in found:
                found.add(pkg)
                todo.append(pkg)
    return found


def _sources(pkg_dir: Path, tests: bool) -> list[Path]:
    """The package's Python files: its code (module and launch files), or its tests."""
    if tests:
        return sorted((pkg_dir / 'test').rglob('*.py'))
    files = [p for p in pkg_dir.rglob('*.py')
             if p.name != 'setup.py' and 'test' not in p.relative_to(pkg_dir).parts]
    # training/ last, so a module's first importer is run-time code whenever any imports it
    return sorted(files, key=lambda p: ('training' in p.relative_to(pkg_dir).parts, p))


def _message_packages(files: list[Path]) -> dict[str, str]:
    """Message package -> the first file naming one of its types."""
    used: dict[str, str] = {}
    for f in files:
        text = f.read_text()
        for pkg in MSG_STRING.findall(text) + MSG_IMPORT.findall(text):
            if pkg not in PLACEHOLDERS:
                used.setdefault(pkg, str(f.relative_to(REPO)))
    return used


def _imported_modules(files: list[Path]) -> dict[str, str]:
    """Top-level absolute imports (module -> first file), without the stdlib and test helpers that
    sit beside the importing file."""
    used: dict[str, str] = {}
    for f in files:
        local = {p.stem for p in f.parent.glob('*.py')}
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split('.')[0]
                if top in sys.stdlib_module_names or top == '__future__' or top in local:
                    continue
                used.setdefault(top, str(f.relative_to(REPO)))
    return used


@pytest.fixture(params=PACKAGE_DIRS, ids=lambda d: d.name)
def pkg_dir(request) -> Path:
    return request.param


def test_manifest_is_format_3_with_its_build_type(pkg_dir: Path) -> None:
    root = _manifest(pkg_dir)
    assert root.tag == 'package' and root.get('format') == '3'
    build_type = root.findtext('export/build_type')
    if (pkg_dir / 'setup.py').exists():
        assert _name(pkg_dir) == pkg_dir.name
        assert build_type == 'ament_python'
    else:
        assert build_type == 'ament_cmake' and (pkg_dir / 'CMakeLists.txt').exists()


def test_no_ament_python_dependency(pkg_dir: Path) -> None:
    # ament_python is a build type (declared in <export>), not a rosdep key: declaring it as a
    # buildtool_depend makes `rosdep install --from-paths src --ignore-src` fail.
    assert 'ament_python' not in _any_deps(pkg_dir)


def test_no_redundant_dependency(pkg_dir: Path) -> None:
    # catkin_pkg (which rosdep and colcon parse package.xml with) refuses a <depend> repeated as a
    # build/exec dependency.
    root = _manifest(pkg_dir)
    for tag in DEP_TAGS:
        names = [e.text.strip() for e in root.findall(tag)]
        assert len(names) == len(set(names)), f'{pkg_dir.name}: repeated <{tag}>'
    assert not _deps(pkg_dir, 'depend') & _deps(pkg_dir, 'build_depend', 'build_export_depend',
                                                'exec_depend')


def test_every_dependency_resolves(pkg_dir: Path) -> None:
    unknown = _any_deps(pkg_dir) - WORKSPACE - JAZZY_PACKAGES - ROSDEP_KEYS
    assert not unknown, (
        f'{pkg_dir.name}/package.xml: {sorted(unknown)} is neither a workspace package, a ROS 2 '
        'Jazzy package of JAZZY_PACKAGES nor a rosdep key checked for Ubuntu 24.04 (ROSDEP_KEYS)')


def test_used_message_packages_are_declared(pkg_dir: Path) -> None:
    code = _message_packages(_sources(pkg_dir, tests=False))
    unknown = {p: f for p, f in code.items() if p not in WORKSPACE | JAZZY_PACKAGES}
    assert not unknown, f'message packages used but not known to be in ROS 2 Jazzy: {unknown}'
    missing = {p: f for p, f in code.items()
               if p != _name(pkg_dir) and p not in _exec_deps(pkg_dir)}
    assert not missing, f'{pkg_dir.name}/package.xml lacks <exec_depend> on {missing}'
    # Tests also make up message packages (foo_msgs...): only real ones must be declared.
    tests = _message_packages(_sources(pkg_dir, tests=True))
    missing = {p: f for p, f in tests.items()
               if p in WORKSPACE | JAZZY_PACKAGES and p != _name(pkg_dir)
               and p not in _any_deps(pkg_dir) | _dependents(_name(pkg_dir))}
    assert not missing, f'{pkg_dir.name}/package.xml lacks a dependency (test_depend) on {missing}'


def _training(path: Path | str) -> bool:
    return 'training' in Path(path).parts


def _check_imports(pkg_dir: Path, tests: bool) -> list[str]:
    declared = _any_deps(pkg_dir) if tests else _exec_deps(pkg_dir)
    # Whole-graph tests may import packages that depend on this one: declaring those would be a
    # cycle, which colcon refuses (it orders packages by test dependencies too).
    exempt = _dependents(_name(pkg_dir)) if tests else set()
    problems = []
    for module, where in _imported_modules(_sources(pkg_dir, tests)).items():
        if module == _name(pkg_dir) or module in PIP_ONLY or module in exempt:
            continue
        if module in WORKSPACE or module in JAZZY_PACKAGES:
            need = module
        elif module in MODULE_KEYS:
            need = MODULE_KEYS[module]
        else:
            problems.append(f'{module} ({where}): add it to MODULE_KEYS (a checked rosdep key) '
                            'or PIP_ONLY (and requirements-ros-apt.txt)')
            continue
        # training-only imports (first seen in training/ code) are declared at any tag
        training_only = not tests and module in TRAINING_ONLY and _training(where)
        if need not in (_any_deps(pkg_dir) if training_only else declared):
            problems.append(f'{module} ({where}) needs {need} declared')
    return problems


def test_imported_modules_are_declared(pkg_dir: Path) -> None:
    problems = _check_imports(pkg_dir, tests=False) + _check_imports(pkg_dir, tests=True)
    assert not problems, f'{pkg_dir.name}/package.xml: ' + '; '.join(problems)


def test_no_node_package_imports_another() -> None:
    # Only the shared packages are imported across packages; the simulator only by training code.
    problems = []
    for d in PACKAGE_DIRS:
        name = _name(d)
        if name in SHARED or not (d / 'setup.py').exists():
            continue
        for module, where in _imported_modules(_sources(d, tests=False)).items():
            allowed = module in SHARED | {name} or (module in TRAINING_ONLY and _training(where))
            if module in WORKSPACE and not allowed:
                problems.append(f'{name} imports {module} ({where})')
    assert not problems, '; '.join(problems)


@pytest.mark.slow
def test_nodes_import_without_the_simulator() -> None:
    # A robot without MuJoCo and vizzy_sim_bridge runs every perception node and the gaze
    # controller; a training program there ends with one line naming what to install.
    block = "import sys; sys.modules.update(mujoco=None, vizzy_sim_bridge=None); "
    modules = ['vizzy_gaze.gaze_controller_node', 'foveation_node.node', 'stereo_ses_node.node',
               'cylinder_detector_node.node', 'mot_planner_node.node', 'vizzy_object_map.node']
    code = block + ''.join(f'import {m}; ' for m in modules)
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=scaled(300))
    assert run.returncode == 0, run.stderr[-2000:]
    for program, module in [('train_foveation_classifier', 'foveation_node'),
                            ('train_cylinder_classifier', 'cylinder_detector_node')]:
        code = (block + f'from {module}.training.train_classifier import main; '
                'sys.exit(main(["--epochs", "1"]))')
        run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                             timeout=scaled(300))
        lines = run.stderr.strip().splitlines()
        assert run.returncode == 2 and len(lines) == 1, run.stderr[-2000:]
        assert lines[0].startswith(f'{program}: needs the simulated head') and \
            'vizzy_sim_bridge' in lines[0], lines[0]


def test_no_dependency_cycle() -> None:
    # colcon orders the workspace by every dependency tag and refuses a cycle.
    for d in PACKAGE_DIRS:
        assert _name(d) not in _dependents(_name(d)), f'{_name(d)} depends on itself'


def test_msg_files_depend_on_their_field_packages() -> None:
    msgs = REPO / 'msgs'
    used = set()
    for f in (msgs / 'msg').glob('*.msg'):
        for line in f.read_text().splitlines():
            field_type = line.split('#')[0].split()[:1]
            if field_type and '/' in field_type[0]:
                used.add(field_type[0].split('/')[0])
    assert used and used <= _deps(msgs, 'depend') <= JAZZY_PACKAGES


def test_tables_agree() -> None:
    assert set(MODULE_KEYS.values()) <= ROSDEP_KEYS
    assert not set(MODULE_KEYS) & set(PIP_ONLY)


def test_pip_step_has_the_pip_only_packages_and_keeps_the_system_numpy() -> None:
    pins = {}
    for line in APT_PIP_REQUIREMENTS.read_text().splitlines():
        line = line.split('#')[0].strip()
        if line and not line.startswith('-'):
            name, _, version = line.partition('==')
            pins[name.strip().lower()] = version.strip()
    missing = set(PIP_ONLY.values()) - set(pins)
    assert not missing, f'requirements-ros-apt.txt lacks {sorted(missing)}'
    # Ubuntu 24.04's python3-numpy (1:1.26.4): Jazzy's compiled messages are built against it.
    assert pins.get('numpy') == '1.26.4'
    assert not set(pins) & {'scipy', 'opencv-python', 'opencv-contrib-python-headless',
                            'matplotlib', 'pandas', 'pyyaml'}, 'those come from apt (rosdep)'
