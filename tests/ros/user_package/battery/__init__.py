"""A user's battery nodes on their own message types (my_robot_msgs), for bagkit's tests."""
