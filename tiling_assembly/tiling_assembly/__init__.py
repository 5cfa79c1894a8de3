"""ROS-free core of the tiling assembly system: the structure model (paper section 2)."""
