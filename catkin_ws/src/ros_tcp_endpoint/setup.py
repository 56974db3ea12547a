"""Makes the `bridge` package importable the ROS way (catkin_python_setup): from devel space through a relay, from
install space as a copy. Run by catkin, not by hand; `bridge` lives at the repository root, three levels up."""

from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["bridge"], package_dir={"bridge": "../../../bridge"}))
