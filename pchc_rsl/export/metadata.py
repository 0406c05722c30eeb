"""The names an exported policy's metadata uses, shared by the exporter and the deploy. Imports nothing, so a deploy
reads a file's metadata without torch."""

METADATA_KEY = "pchc"
"""The ONNX metadata_props key under which the deploy metadata is stored, as JSON."""
