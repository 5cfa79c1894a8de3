from setuptools import find_packages, setup

package_name = "tiling_assembly"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        # how the team starts: read by the launch files and the experiment (the repository's config/)
        ("share/" + package_name + "/config", ["../config/team.yaml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="Tiling Assembly Engineering",
    maintainer_email="engineering@tiling-assembly.example.com",
    description="Structure model of the tiling assembly system (ROS-free core).",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "validate = tiling_assembly.executables:validate",
        ],
    },
)
