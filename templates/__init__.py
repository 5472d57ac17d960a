"""Copyable env templates, installed as ``uniros.templates``; ``uniros new`` copies them."""
