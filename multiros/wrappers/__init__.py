"""multiros/wrappers"""
