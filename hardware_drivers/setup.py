from glob import glob

from setuptools import find_packages, setup

package_name = "hardware_drivers"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml", "README.md"]),
        ("share/" + package_name + "/launch", glob("launch/*.launch.py")),
        # the parameter files live in the repository's config/ (one place for every package)
        ("share/" + package_name + "/config",
         ["../config/hardware_drivers.yaml", "../config/crustcrawler_arm.yaml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="Tiling Assembly Engineering",
    maintainer_email="engineering@tiling-assembly.example.com",
    description="Drivers of the M3 robot (Create base, CrustCrawler arm, Hokuyo URG), tile localization, "
    "the place-tile action server and device emulators.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "create_base = hardware_drivers.executables:create_base",
            "crustcrawler_arm = hardware_drivers.executables:crustcrawler_arm",
            "hokuyo_urg = hardware_drivers.executables:hokuyo_urg",
            "m3_robot = hardware_drivers.executables:m3_robot",
            "base_navigator = hardware_drivers.executables:base_navigator",
            "create_emulator = hardware_drivers.executables:create_emulator",
            "dynamixel_emulator = hardware_drivers.executables:dynamixel_emulator",
            "urg_emulator = hardware_drivers.executables:urg_emulator",
        ],
    },
)
