"""
The thin ROS 2 layer: message conversion and the nodes.

The only place that imports rclpy.
"""
