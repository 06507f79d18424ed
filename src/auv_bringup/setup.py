from setuptools import find_packages, setup

package_name = 'auv_bringup'

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
    maintainer='AUV depth-control maintainers',
    maintainer_email='maintainers@auv-depth.dev',
    description='The auv command: launch, record, play, depth, run, design, ident, gap.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'auv = auv_bringup.cli:main',
            'recorder = auv_bringup.record_node:main',
            'player = auv_bringup.play_node:main',
            'foxglove = auv_bringup.foxglove_node:main',
        ],
    },
)
