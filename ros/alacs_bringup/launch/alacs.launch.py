"""One alacs unit: `ros2 launch alacs_bringup alacs.launch.py [namespace:=/alacs] [params_file:=...]`."""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    default_params = os.path.join(get_package_share_directory("alacs_bringup"), "config", "alacs.yaml")
    return LaunchDescription([
        DeclareLaunchArgument("namespace", default_value="alacs", description="the node's namespace"),
        DeclareLaunchArgument("params_file", default_value=default_params, description="the parameters YAML"),
        Node(
            package="alacs_bringup",
            executable="alacs",
            name="alacs",
            namespace=LaunchConfiguration("namespace"),
            # `alacs ros`, then launch_ros adds --ros-args -r __node:= -r __ns:= --params-file.
            arguments=["ros"],
            parameters=[LaunchConfiguration("params_file")],
            output="screen",
        ),
    ])
