"""multiros/sim"""
