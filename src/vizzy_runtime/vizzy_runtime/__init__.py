"""vizzy_runtime: the ROS seam (vizzy_runtime.ros), numpy conversions, rosbag2 tools and the `vizzy`
CLI."""
