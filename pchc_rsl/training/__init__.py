"""A training job from a config: building its env and runner and restoring a checkpoint's config (``build``),
checking a config (``checks``), ``KEY=VALUE`` overrides (``overrides``), the run folder (``run_folder``) and the
thread defaults (``threads``). Import each module by its path; this package imports nothing."""
