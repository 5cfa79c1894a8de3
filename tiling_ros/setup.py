from setuptools import find_packages, setup

package_name = "tiling_ros"

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
    description="The ROS side every node shares: QoS profiles, stamps, point clouds, parameters, spinning.",
    license="Apache-2.0",
)
