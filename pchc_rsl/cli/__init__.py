"""Command-line entry points: pchc-train, pchc-export-onnx."""
