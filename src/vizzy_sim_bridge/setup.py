from glob import glob

from setuptools import find_packages, setup

package_name = 'vizzy_sim_bridge'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Vizzy active vision maintainers',
    maintainer_email='vizzy@example.com',
    description='Simulated Vizzy head (MuJoCo): cameras, RGB-D, joints, tf, clock, scenes.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'sim = vizzy_sim_bridge.sim_node:main',
            'gaze_controller = vizzy_gaze.gaze_controller_node:main',
            'vizzy_head_urdf = vizzy_sim_bridge.head_urdf:main',
            'vizzy_camera_calibration = vizzy_sim_bridge.camera_calibration:main',
        ],
    },
)
