import pathlib

from setuptools import find_packages, setup

package_name = 'auv_contract'
here = pathlib.Path(__file__).resolve().parent


def config_files() -> list[tuple[str, list[str]]]:
    """``config/`` (vehicle files, missions, effects, maps) as share data, folder by folder."""
    out: dict[str, list[str]] = {}
    for path in sorted((here / 'config').rglob('*')):
        if path.is_file():
            rel = path.relative_to(here)
            out.setdefault(str(pathlib.Path('share', package_name, rel.parent)), []).append(
                str(rel))
    return sorted(out.items())


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        *config_files(),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='AUV depth-control maintainers',
    maintainer_email='maintainers@auv-depth.dev',
    description=('The contract written once: topic names, the state layout, the shipped '
                 'configuration and the YAML loader.'),
    license='Apache-2.0',
)
