"""Python ROS 1 toolkit for robots in VR: the ROS-TCP endpoint (bridge) and the simulated robots (sim)."""

from setuptools import find_packages, setup

setup(
    name="vr_ros_toolkit",
    version="0.1.0",
    description="Drop-in ROS-TCP-Endpoint (protocol v0.7.0, ROS 1) plus simulated robots, controllers and trials",
    # Python 3.8 (ROS Noetic's) and later: the suite runs on 3.8, 3.10 and 3.11 (launch_scripts/test.sh). Every
    # lower bound below is a release that still supports 3.8, and what pip resolves there is what the tests run on.
    # The endpoint alone (bridge) needs none of it: ROS's own packages only, installed the ROS way through the catkin
    # package catkin_ws/src/ros_tcp_endpoint.
    python_requires=">=3.8",
    packages=find_packages(include=["bridge", "bridge.*", "sim", "sim.*"]),
    package_data={
        "bridge": ["py.typed"],
        "sim": ["py.typed"],
        "sim.robots": ["*.yaml", "urdf/*.urdf"],
        "sim.study.design": ["*.yaml"],
        "sim.study.run": ["protocol.json"],
        "sim.wire": ["interfaces/control_msgs/*/*"],  # control_msgs' definitions (sim.wire.control_types)
        "sim.study.questionnaires": ["*.json"],
        # the VR page, and the npm packages setup.sh fetched beside it (node_modules)
        "sim.study.views.vr": ["web/*.html", "web/*.css", "web/*.js", "web/*.json", "web/node_modules/**/*"],
    },
    install_requires=[
        "numpy>=1.24",
        "pybullet>=3.2.5",
        "rosbags>=0.9.20",
        "matplotlib>=3.6",
        "tqdm>=4.60",
        "PyYAML>=5.4",
        "scipy>=1.10",
        "statsmodels>=0.14.1",  # the study's mixed models and equivalence tests
        "viser>=1.0",  # the study's live 3-D view
        "yourdfpy>=0.0.56",  # viser's URDF loader
        "h11>=0.13",  # the VR page's server reads HTTP requests with it
    ],
    # selenium drives Debian's chromium (and chromedriver) for the web view's test
    extras_require={
        "dev": ["pytest>=7", "hypothesis>=6", "pytest-timeout>=2", "mypy>=1.5", "selenium>=4.10", "ruff>=0.6"]
    },
    entry_points={
        "console_scripts": [
            "ros-tcp-endpoint=bridge.__main__:main",
            "sim-engine=sim.engine.stand_in:main",
            "sim-commander=sim.control.commander:main",
            "sim-trials=sim.campaign.trials:main",
            "sim-study=sim.study.__main__:main",
        ]
    },
)
