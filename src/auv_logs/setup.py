from setuptools import find_packages, setup

package_name = 'auv_logs'

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
    description=("Logs in: mapping files, readers of real vehicles' logs, import to the contract "
                 'bag, segments, derived signals, simulated and synthetic logs.'),
    license='Apache-2.0',
)
