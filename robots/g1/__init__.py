"""The Unitree G1: constants and model building."""
