"""Makes the `bridge` package importable the ROS way (catkin_python_setup): from devel space through a relay, from
install space as a copy. Run by catkin, not by hand; `bridge` lives at the repository root, three levels up, and its
packages are found under it (each is named: the copy to install space takes only those)."""

from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

PACKAGES = ["bridge", "bridge.admission", "bridge.client", "bridge.connection", "bridge.protocol", "bridge.ros"]

setup(**generate_distutils_setup(packages=PACKAGES, package_dir={"bridge": "../../../bridge"}))
