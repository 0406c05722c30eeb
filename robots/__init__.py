"""Robot models for the MuJoCo environments."""
