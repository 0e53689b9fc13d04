"""Photographs as they come in: what a photo file says about its camera."""
