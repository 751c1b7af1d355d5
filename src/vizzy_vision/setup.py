from setuptools import find_packages, setup

package_name = 'vizzy_vision'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Vizzy active vision maintainers',
    maintainer_email='vizzy@example.com',
    description='ROS-free shared core: head kinematics, frames, cameras, log-polar retina, rays.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
)
