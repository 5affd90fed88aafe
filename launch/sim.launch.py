"""
Start one simulated ship.

`ros2 launch mmg_tuner sim.launch.py [ship:=kvlcc2] [namespace:=ship2]
[params_file:=tuned/params.yaml]`.

The node's parameters come from config/sim_node.yaml (installed in share/mmg_tuner/config);
the launch arguments override the ship, the tuned parameter overlay and the namespace, so two
ships run side by side in two namespaces.
"""
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

EXECUTABLE = 'sim_node'
PARAMS_FILE = 'config/sim_node.yaml'


def generate_launch_description():
    """Return the simulator node with its parameter file and the user's overrides."""
    share = Path(get_package_share_directory('mmg_tuner'))
    return LaunchDescription([
        DeclareLaunchArgument('namespace', default_value='',
                              description='ROS namespace of this ship (e.g. ship2)'),
        DeclareLaunchArgument('ship', default_value='suzaku',
                              description='ship config name or path to a ship YAML'),
        DeclareLaunchArgument('params_file', default_value='',
                              description='tuned params.yaml from tune or diagnose'),
        Node(package='mmg_tuner', executable=EXECUTABLE, name='sim_node',
             namespace=LaunchConfiguration('namespace'), output='screen',
             parameters=[str(share / PARAMS_FILE),
                         {'ship': LaunchConfiguration('ship'),
                          'params_file': LaunchConfiguration('params_file')}]),
    ])
