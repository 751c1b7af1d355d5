import os
from glob import glob

from setuptools import Extension, find_packages, setup

package_name = 'vizzy_runtime'
# colcon (--symlink-install) may run this file from another folder: the C source by its own path
_SHIM = os.path.join('csrc', 'loopback_bind.c')
if not os.path.exists(_SHIM):
    _SHIM = os.path.join(os.path.dirname(os.path.realpath(__file__)), _SHIM)

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    # Jazzy interface definitions rosbags' typestore lacks (vision_msgs), read by msgs.py
    package_data={package_name: ['interfaces/*/msg/*.msg']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        ('share/' + package_name + '/config',
         glob('config/*.yaml') + glob('config/*.xml') + glob('config/*.json')
         + glob('config/*.rviz')),
        ('share/' + package_name + '/config/tasks', glob('config/tasks/*.yaml')),
    ],
    # The loopback-bind LD_PRELOAD shim (csrc/loopback_bind.c; see vizzy_runtime/loopback.py): built
    # like an extension so that pip and colcon compile it, never imported. Optional: without a C
    # compiler the package still installs and the nodes say in one line that their sockets are
    # not confined to loopback.
    ext_modules=[Extension('vizzy_runtime._loopback_bind', sources=[_SHIM],
                           libraries=['dl'], optional=True)],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Vizzy active vision maintainers',
    maintainer_email='vizzy-active-vision@users.noreply.github.com',
    description='ROS seam, numpy conversions, ROS-less CLI and rosbag2 tools for the Vizzy stack',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'vizzy = vizzy_runtime.cli:console_main',
        ],
    },
)
