from setuptools import find_packages, setup

package_name = 'auv_ident'

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
    description=('Hydrodynamic coefficient identification from logs, starting vehicle '
                 'files, and the identification node.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'identifier = auv_ident.node:main',
        ],
    },
)
