"""The one thing pyproject.toml does not declare: the recorder's C extension.

``bagkit/ros/record/_take.c`` (batched take of serialized messages) builds with the Python
headers only; it calls librcl through the function address that rclpy's librcl gives at run
time.
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "bagkit.ros.record._take",
            sources=["bagkit/ros/record/_take.c"],
            extra_compile_args=["-O2", "-Wall", "-Wextra", "-Werror"],
        )
    ]
)
