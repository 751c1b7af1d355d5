"""Write the source of an interface package that has no PyPI wheel, for a cmake (rosidl) build.

    python scripts/gen_interfaces.py PACKAGE OUT_DIR

PACKAGE is one of PACKAGES:
- tf2_msgs: the message definitions come from rosbags' ROS 2 Jazzy typestore, the same ones the
  bundled runtime uses, so nothing is typed by hand;
- vision_msgs (4.1.1, the Jazzy release): the .msg files vizzy_runtime ships as package data
  (src/vizzy_runtime/vizzy_runtime/interfaces/vision_msgs/msg), the ones the bundled runtime
  parses; their fields are the released package's, so the type hashes are the released ones
  (src/vizzy_runtime/test/test_vision_msgs.py checks both runtimes).
package.xml and CMakeLists.txt are the minimal rosidl package around them.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from rosbags.typesys import Stores, get_typestore

REPO = Path(__file__).resolve().parents[1]
BUNDLED_INTERFACES = REPO / 'src' / 'vizzy_runtime' / 'vizzy_runtime' / 'interfaces'


@dataclass(frozen=True)
class Spec:
    version: str          # the Jazzy release these definitions belong to
    description: str
    license: str
    depends: tuple[str, ...]
    from_typestore: bool  # rosbags' Jazzy typestore, else vizzy_runtime's bundled .msg files


PACKAGES = {
    'tf2_msgs': Spec('0.36.14', 'tf2 messages, generated from the ROS 2 Jazzy definitions',
                     'BSD-3-Clause', ('builtin_interfaces', 'geometry_msgs'), True),
    'vision_msgs': Spec('4.1.1', 'vision_msgs 4.1.1 messages (the ROS 2 Jazzy release), from '
                        'vizzy_runtime\'s bundled definitions', 'Apache-2.0',
                        ('std_msgs', 'geometry_msgs'), False),
}

PACKAGE_XML = '''<?xml version="1.0"?>
<package format="3">
  <name>{package}</name>
  <version>{version}</version>
  <description>{description} for the Vizzy
    real-rclpy venv.</description>
  <maintainer email="vizzy@example.com">Vizzy active vision maintainers</maintainer>
  <license>{license}</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <buildtool_depend>rosidl_default_generators</buildtool_depend>
{depends}
  <exec_depend>rosidl_default_runtime</exec_depend>
  <member_of_group>rosidl_interface_packages</member_of_group>
  <export><build_type>ament_cmake</build_type></export>
</package>
'''

CMAKELISTS = '''cmake_minimum_required(VERSION 3.8)
project({package})
find_package(ament_cmake REQUIRED)
find_package(rosidl_default_generators REQUIRED)
{find_packages}
rosidl_generate_interfaces(${{PROJECT_NAME}}
  {files}
  DEPENDENCIES {depends}
)
ament_export_dependencies(rosidl_default_runtime)
ament_package()
'''


def message_text(typestore: object, typename: str) -> str:
    """The message's own definition: the first section of its full (dependency-joined) msgdef."""
    full, _ = typestore.generate_msgdef(typename, ros_version=2)  # type: ignore[attr-defined]
    return full.split('\n' + '=' * 80 + '\n')[0].rstrip() + '\n'


def message_texts(package: str, spec: Spec) -> dict[str, str]:
    """Type short name -> .msg text."""
    if spec.from_typestore:
        typestore = get_typestore(Stores.ROS2_JAZZY)
        prefix = f'{package}/msg/'
        return {name[len(prefix):]: message_text(typestore, name)
                for name in sorted(typestore.types) if name.startswith(prefix)}
    folder = BUNDLED_INTERFACES / package / 'msg'
    return {path.stem: path.read_text(encoding='utf-8') for path in sorted(folder.glob('*.msg'))}


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(f'usage: gen_interfaces.py {{{",".join(PACKAGES)}}} OUT_DIR', file=sys.stderr)
        return 2
    if argv[0] not in PACKAGES:
        print(f'gen_interfaces: unknown package {argv[0]!r} (known: {", ".join(PACKAGES)})',
              file=sys.stderr)
        return 2
    package, out = argv[0], Path(argv[1])
    spec = PACKAGES[package]
    texts = message_texts(package, spec)
    if not texts:
        where = ('the rosbags Jazzy typestore' if spec.from_typestore
                 else BUNDLED_INTERFACES / package / 'msg')
        print(f'gen_interfaces: no {package} messages in {where}', file=sys.stderr)
        return 1
    (out / 'msg').mkdir(parents=True, exist_ok=True)
    for short, text in texts.items():
        (out / 'msg' / f'{short}.msg').write_text(text)
    (out / 'package.xml').write_text(PACKAGE_XML.format(
        package=package, version=spec.version, description=spec.description,
        license=spec.license, depends='\n'.join(f'  <depend>{d}</depend>' for d in spec.depends)))
    (out / 'CMakeLists.txt').write_text(CMAKELISTS.format(
        package=package, files='\n  '.join(f'"msg/{short}.msg"' for short in texts),
        find_packages='\n'.join(f'find_package({d} REQUIRED)' for d in spec.depends),
        depends=' '.join(spec.depends)))
    print(f'gen_interfaces: {", ".join(f"{package}/msg/{s}" for s in texts)} -> {out}')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
