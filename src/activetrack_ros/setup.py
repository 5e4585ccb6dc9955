from setuptools import find_packages, setup

package_name = "activetrack_ros"

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
    maintainer="activetrack developers",
    maintainer_email="dev@activetrack.invalid",
    description="See package.xml.",
    license="Apache-2.0",
)
