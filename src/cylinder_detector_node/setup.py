from glob import glob

from setuptools import find_packages, setup

package_name = 'cylinder_detector_node'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['models/*.npz']},   # the pre-attention classifier's weights
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
    description='Cylinder detection and identification in point clouds.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'cylinder_detector = cylinder_detector_node.node:main',
            'detect_file = cylinder_detector_node.detect_file:main',
            'train_cylinder_classifier = cylinder_detector_node.training.train_classifier:main',
        ],
    },
)
