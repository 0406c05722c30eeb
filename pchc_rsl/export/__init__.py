"""The exported policy file, the one thing a robot needs: writing it from a policy and checking it against torch
(``onnx_export``), running it with its inputs checked (``onnx_policy``), opening it (``onnx_session``) and the names
its metadata uses (``metadata``). Import each module by its path: this package imports nothing, so a deploy reads a
file's metadata without torch."""
