"""Makes the `bridge` package importable the ROS way (catkin_python_setup): from devel space through a relay, from
install space as a copy. Run by catkin, not by hand; `bridge` lives at the repository root, three levels up, and
its packages (protocol, admission, connection, ros, client) are found under it for the copy."""

import os

from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import find_packages, setup

SOURCE = "../../../bridge"
subpackages = find_packages(os.path.join(os.path.dirname(os.path.abspath(__file__)), SOURCE))

setup(
    **generate_distutils_setup(
        packages=["bridge"] + ["bridge." + name for name in subpackages], package_dir={"bridge": SOURCE}
    )
)
