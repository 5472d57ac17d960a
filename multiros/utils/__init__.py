"""multiros/utils"""
