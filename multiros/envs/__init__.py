"""multiros/envs"""
