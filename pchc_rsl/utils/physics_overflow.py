"""The error a physics raises when its fixed buffers dropped what did not fit (contacts, constraint rows), so that its
last steps were wrong. Here, beneath both, so that the runner catches what the MuJoCo side raises without importing
that side (or Warp)."""


class PhysicsOverflow(RuntimeError):
    """A physics buffer overflowed: contacts or constraint rows were dropped, so the physics was wrong."""
