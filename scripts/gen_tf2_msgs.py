"""Write the source of the tf2_msgs interface package (its messages) for a cmake build.

tf2_msgs has no PyPI wheel. Its message definitions come from rosbags' ROS 2 Jazzy typestore, the
same definitions the bundled runtime uses, so nothing is typed by hand; package.xml and
CMakeLists.txt are the minimal rosidl package around them.

    python scripts/gen_tf2_msgs.py OUT_DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

from rosbags.typesys import Stores, get_typestore

PACKAGE = 'tf2_msgs'
VERSION = '0.36.14'   # the Jazzy release of geometry2 these definitions belong to

PACKAGE_XML = f'''<?xml version="1.0"?>
<package format="3">
  <name>{PACKAGE}</name>
  <version>{VERSION}</version>
  <description>tf2 messages, generated from the ROS 2 Jazzy definitions for the Vizzy
    real-rclpy venv.</description>
  <maintainer email="vizzy@example.com">Vizzy active vision maintainers</maintainer>
  <license>BSD-3-Clause</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <buildtool_depend>rosidl_default_generators</buildtool_depend>
  <depend>builtin_interfaces</depend>
  <depend>geometry_msgs</depend>
  <exec_depend>rosidl_default_runtime</exec_depend>
  <member_of_group>rosidl_interface_packages</member_of_group>
  <export><build_type>ament_cmake</build_type></export>
</package>
'''

CMAKELISTS = '''cmake_minimum_required(VERSION 3.8)
project({package})
find_package(ament_cmake REQUIRED)
find_package(rosidl_default_generators REQUIRED)
find_package(builtin_interfaces REQUIRED)
find_package(geometry_msgs REQUIRED)
rosidl_generate_interfaces(${{PROJECT_NAME}}
  {files}
  DEPENDENCIES builtin_interfaces geometry_msgs
)
ament_export_dependencies(rosidl_default_runtime)
ament_package()
'''


def message_text(typestore: object, typename: str) -> str:
    """The message's own definition: the first section of its full (dependency-joined) msgdef."""
    full, _ = typestore.generate_msgdef(typename, ros_version=2)  # type: ignore[attr-defined]
    return full.split('\n' + '=' * 80 + '\n')[0].rstrip() + '\n'


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print('usage: gen_tf2_msgs.py OUT_DIR', file=sys.stderr)
        return 2
    out = Path(argv[0])
    typestore = get_typestore(Stores.ROS2_JAZZY)
    names = sorted(t for t in typestore.types if t.startswith(f'{PACKAGE}/msg/'))
    if not names:
        print(f'gen_tf2_msgs: no {PACKAGE} messages in the rosbags Jazzy typestore',
              file=sys.stderr)
        return 1
    (out / 'msg').mkdir(parents=True, exist_ok=True)
    files = []
    for name in names:
        short = name.rsplit('/', 1)[1]
        (out / 'msg' / f'{short}.msg').write_text(message_text(typestore, name))
        files.append(f'"msg/{short}.msg"')
    (out / 'package.xml').write_text(PACKAGE_XML)
    cmake = CMAKELISTS.format(package=PACKAGE, files='\n  '.join(files))
    (out / 'CMakeLists.txt').write_text(cmake)
    print(f'gen_tf2_msgs: {", ".join(names)} -> {out}')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
