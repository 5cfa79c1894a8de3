"""The ROS side every node of the tiling assembly system shares (`tiling_assembly` stays ROS-free)."""
