"""
Replay a recorded trial against the model.

`ros2 launch mmg_tuner replay.launch.py trial:=trials/zigzag_p20_10 [topics:=topics.yaml]
[params_file:=diag/params.yaml] [speed:=10.0] [output_mcap:=replay]`.

Publishes /clock, the recorded commands (rudder, rpm, thrusters when recorded) as the topic
map describes them, /recorded/odom and the model's /model/odom (never /odom, which a
recording's reader takes as the measurement; config/topics.yaml, section replay; see README,
"Simulator node"); output_mcap, when given, must name a path that does not exist yet.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

EXECUTABLE = 'replay_node'
ARGUMENTS = {
    'trial': ('', 'recorded trial: rosbag2 folder, .mcap, .csv or MARIN .dat'),
    'topics': ('', 'topic map YAML of the recording (its command topics, units, signs)'),
    'ship': ('suzaku', 'ship config name or path to a ship YAML'),
    'params_file': ('', 'tuned params.yaml from tune or diagnose'),
    'speed': ('1.0', 'replay speed, multiple of real time'),
    'output_mcap': ('', 'write the replay to this new MCAP path (never overwritten)'),
}


def generate_launch_description():
    """Return the replay node with every argument passed through as a parameter."""
    args = [DeclareLaunchArgument(k, default_value=d, description=h)
            for k, (d, h) in ARGUMENTS.items()]
    node = Node(package='mmg_tuner', executable=EXECUTABLE, name='replay_node', output='screen',
                parameters=[{k: LaunchConfiguration(k) for k in ARGUMENTS}])
    return LaunchDescription(args + [node])
