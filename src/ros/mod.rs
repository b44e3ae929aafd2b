//! The ROS 2 node: the only module that names ros2-client types.
