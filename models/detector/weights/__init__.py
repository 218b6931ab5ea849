"""Shipped detector weights (package data: found by path relative to this file)."""
