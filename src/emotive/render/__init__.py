"""Rendering: static feature plots."""
