from glob import glob

from setuptools import find_packages, setup

package_name = "vi_node"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", glob("launch/*.launch.py")),
        # the parameter files live in the repository's config/ (one place for every package)
        ("share/" + package_name + "/config", ["../config/" + package_name + ".yaml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="Tiling Assembly Engineering",
    maintainer_email="engineering@tiling-assembly.example.com",
    description="Visual inspection: aligns depth scans to the expected structure and classifies every tile.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "vi_node = vi_node.executables:vi_node",
            "classify = vi_node.executables:classify",
            "vi_explorer = vi_node.executables:vi_explorer",
        ],
    },
)
