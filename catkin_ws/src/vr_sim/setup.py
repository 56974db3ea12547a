"""Makes the `sim` package importable the ROS way (catkin_python_setup): from devel space through a relay, from
install space as a copy. Run by catkin, not by hand; `sim` lives at the repository root, three levels up."""

import os

from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import find_packages, setup

SOURCE = "../../../sim"
subpackages = find_packages(os.path.join(os.path.dirname(os.path.abspath(__file__)), SOURCE))

setup(
    **generate_distutils_setup(
        packages=["sim"] + ["sim." + name for name in subpackages],
        package_dir={"sim": SOURCE},
        # the data files of the repository's setup.py: the bundled robots and the study's defaults
        package_data={
            "sim": ["py.typed"],
            "sim.robots": ["*.yaml", "urdf/*.urdf"],
            "sim.study.design": ["*.yaml"],
            "sim.study.run": ["protocol.json"],
            "sim.wire": ["interfaces/control_msgs/*/*"],
        },
    )
)
