"""sensor_msgs/PointCloud2 <-> organized numpy cloud: the reader of `tiling_ros.point_clouds`, under
the name the offline `classify` command imports it by."""

from tiling_ros.point_clouds import CloudError, cloud_from_msg

__all__ = ["CloudError", "cloud_from_msg"]
