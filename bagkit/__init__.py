"""bagkit: recording, replay and golden-bag regression for ROS 2 MCAP bags."""

__version__ = "0.1.0"
