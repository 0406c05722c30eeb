"""A training job from a config: building its env and runner and restoring a checkpoint's config (``build``),
checking a config (``checks``), ``KEY=VALUE`` overrides (``overrides``), the run folder (``run_folder``) and the
thread defaults (``threads``); after it, exporting a checkpoint (``checkpoint_export``), averaging checkpoints
(``checkpoint_average``), releasing a policy (``release``) and a benchmark study's cells (``study_cells``). Import each
module by its path; this package imports nothing."""
