"""Robot-agnostic AMP (Adversarial Motion Prior): reference-motion loading, window sampling and the discriminator.

Needs only numpy, torch and rsl-rl, never mujoco.
"""

from pchc_rsl.amp.discriminator import AMPDiscriminator, ReplayBuffer
from pchc_rsl.amp.motion import G1_CSV_JOINTS, MotionWindows, load_motion, load_motions

__all__ = ["AMPDiscriminator", "G1_CSV_JOINTS", "MotionWindows", "ReplayBuffer", "load_motion", "load_motions"]
