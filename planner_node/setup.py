from setuptools import find_packages, setup

package_name = "planner_node"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        # the parameter files live in the repository's config/ (one place for every package)
        ("share/" + package_name + "/config", ["../config/" + package_name + ".yaml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="Tiling Assembly Engineering",
    maintainer_email="engineering@tiling-assembly.example.com",
    description="Task partitioning and sequencing for the assembly robots (paper section 2.1).",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "plan = planner_node.executables:plan",
            "planner_node = planner_node.executables:planner_node",
            "benchmark = planner_node.executables:benchmark",
        ],
    },
)
