from setuptools import find_packages, setup

package_name = "tiling_sim"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="Tiling Assembly Engineering",
    maintainer_email="engineering@tiling-assembly.example.com",
    description="Simulated testbed of the tiling assembly system.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "sim_world = tiling_sim.executables:sim_world",
            "sim_robot = tiling_sim.executables:sim_robot",
            "sim_vi = tiling_sim.executables:sim_vi",
            "experiment = tiling_sim.executables:experiment",
            "replay_bag = tiling_sim.executables:replay_bag",
            "vi_accuracy = tiling_sim.executables:vi_accuracy",
            "vi_benchmark = tiling_sim.executables:vi_benchmark",
            "classify_benchmark = tiling_sim.executables:classify_benchmark",
        ],
    },
)
