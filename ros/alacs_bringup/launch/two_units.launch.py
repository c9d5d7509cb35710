"""Two alacs units, left and right arm: `ros2 launch alacs_bringup two_units.launch.py`."""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch_ros.actions import Node


def generate_launch_description():
    params = os.path.join(get_package_share_directory("alacs_bringup"), "config", "two_units.yaml")
    return LaunchDescription([
        Node(
            package="alacs_bringup",
            executable="alacs",
            name=f"alacs_{side}",
            namespace=f"alacs_{side}",
            arguments=["ros"],
            parameters=[params],
            output="screen",
        )
        for side in ("left", "right")
    ])
