"""The live ROS 2 node around `mcl.localizer.Localizer`, and the tools around it (docs/ros.md).

    robocup-mcl node --ros-args -p field:=kidsize          # the node (needs `make ros`: rclpy and the messages)
    robocup-mcl node bench LOG.mcap --json --save results/ros_bench.json

Nothing here imports rclpy at import time: the modules load (for mypy, the docs, the command line) without
ROS installed, and say what to install when a command needs it.
"""
