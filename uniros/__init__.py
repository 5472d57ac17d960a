"""uniros"""
