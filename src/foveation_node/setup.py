from glob import glob

from setuptools import find_packages, setup

package_name = 'foveation_node'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    # the default recognition model (trained by train_classifier.py) travels with the package
    package_data={package_name: ['models/*.pt', 'models/*.labels', 'models/*.json',
                                 'models/*.txt']},
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
    description='Foveated vision: space-variant images, foveated CNN detections, saccades.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'foveation = foveation_node.node:main',
            'train_foveation_classifier = foveation_node.training.train_classifier:main',
            'recognize_folder = foveation_node.recognize_folder:main',
            'export_imagenet_classifier = foveation_node.export_imagenet_classifier:main',
        ],
    },
)
