#!/usr/bin/env python3
"""The endpoint node as roslaunch/rosrun start it; all logic lives in the `bridge` package."""

import sys

from bridge.__main__ import main

if __name__ == "__main__":
    sys.exit(main())
