"""Interbotix ReactorX 200 environments."""
