"""JSON Schemas of vebuild's files, shipped as package data (read with importlib.resources)."""
