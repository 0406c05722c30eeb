"""Watching a policy: MuJoCo's window (``native``), the browser (``web``), videos of a checkpoint (``recording``, built
on ``video``), what is shown beside the robot (``overlay``) and steering its command from a viewer (``steering``).
Import each module by its path; this package imports nothing."""
