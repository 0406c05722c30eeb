"""The names an exported policy's metadata uses, shared by the exporter, the deploy and the viewers. Imports nothing,
so a deploy reads a file's metadata without torch."""

METADATA_KEY = "pchc"
"""The ONNX metadata_props key under which the deploy metadata is stored, as JSON."""

COMMAND_COMPONENTS = ("lin_vel_x", "lin_vel_y", "ang_vel_z")
"""The walking command's components, in the order of the observation's command, as the training config's
``command_ranges`` and the metadata's name them."""
