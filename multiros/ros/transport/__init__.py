"""multiros/ros/transport"""
